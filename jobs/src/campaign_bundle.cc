// A campaign directory as one byte string and back (campaign_bundle.h).
#include "strokelab/jobs/campaign_bundle.h"

#include <algorithm>
#include <charconv>
#include <fstream>
#include <set>
#include <stdexcept>
#include <vector>

#include "strokelab/base/errors.h"
#include "strokelab/data/recordings.h"
#include "strokelab/jobs/campaigns.h"
#include "strokelab/jobs/sha256.h"

namespace strokelab::jobs {
namespace {

namespace fs = std::filesystem;

constexpr std::string_view kBundleHeader = "strokelab-campaign 1\n";
constexpr size_t kMaxBundleFiles = 10'000;

// Why `name` cannot be written under a directory, or "" when it can.
std::string BadNameReason(std::string_view name) {
  if (name.empty()) return "an empty name";
  if (name.front() == '/') return "an absolute name";
  if (std::any_of(name.begin(), name.end(), [](char c) { return c == '\\' || static_cast<unsigned char>(c) < 0x20; }))
    return "a backslash or control character in its name";
  size_t start = 0;
  for (;;) {
    const size_t end = std::min(name.find('/', start), name.size());
    const std::string_view part = name.substr(start, end - start);
    if (part.empty() || part == "." || part == "..") return "an empty, '.' or '..' component";
    if (end == name.size()) return "";
    start = end + 1;
  }
}

}  // namespace

std::string CampaignBundle(const fs::path& dir) {
  // manifest.json and the files it lists, no others (issue 15: a directory under the data root may
  // hold large or private files beside a campaign; they are neither read nor sent to a worker).
  std::vector<std::string> names = CampaignFiles(dir);
  if (names.size() > kMaxBundleFiles)
    throw InputError("/campaign", "holds more than " + std::to_string(kMaxBundleFiles) + " files");
  for (std::string& name : names) name = fs::path(name).lexically_normal().generic_string();
  std::sort(names.begin(), names.end());
  std::string bundle(kBundleHeader);
  for (const std::string& name : names) {
    const std::string bytes = ReadFileBytes(dir / name);
    bundle += name;
    bundle += '\0';
    bundle += std::to_string(bytes.size()) + '\n';
    bundle += bytes;
  }
  return bundle;
}

std::string CampaignSha256(const fs::path& dir) { return Sha256Hex(CampaignBundle(dir)); }

void UnpackCampaignBundle(std::string_view bundle, const fs::path& dir) {
  if (!bundle.starts_with(kBundleHeader)) throw std::runtime_error("campaign bundle: no 'strokelab-campaign 1' header");
  fs::create_directories(dir);
  std::set<std::string, std::less<>> seen;
  size_t at = kBundleHeader.size();
  while (at < bundle.size()) {
    const size_t nul = bundle.find('\0', at);
    const size_t newline = nul == std::string_view::npos ? nul : bundle.find('\n', nul);
    if (newline == std::string_view::npos) throw std::runtime_error("campaign bundle: truncated header after byte " + std::to_string(at));
    const std::string_view name = bundle.substr(at, nul - at);
    const std::string shown(name.substr(0, 200));
    if (const std::string reason = BadNameReason(name); !reason.empty())
      throw std::runtime_error("campaign bundle: file '" + shown + "' has " + reason);
    if (!seen.insert(std::string(name)).second) throw std::runtime_error("campaign bundle: file '" + shown + "' given twice");
    if (seen.size() > kMaxBundleFiles)
      throw std::runtime_error("campaign bundle: more than " + std::to_string(kMaxBundleFiles) + " files");
    size_t size = 0;
    const auto [end, ec] = std::from_chars(bundle.data() + nul + 1, bundle.data() + newline, size);
    if (ec != std::errc() || end != bundle.data() + newline || nul + 1 == newline)
      throw std::runtime_error("campaign bundle: file '" + shown + "' has no size");
    if (size > bundle.size() - newline - 1) throw std::runtime_error("campaign bundle: file '" + shown + "' is truncated");
    const fs::path target = dir / fs::path(std::string(name));
    fs::create_directories(target.parent_path());
    std::ofstream out(target, std::ios::binary | std::ios::trunc);
    out.write(bundle.data() + newline + 1, static_cast<std::streamsize>(size));
    if (!out) throw std::runtime_error("campaign bundle: cannot write " + target.string());
    at = newline + 1 + size;
  }
}

}  // namespace strokelab::jobs
