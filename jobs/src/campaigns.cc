#include "strokelab/jobs/campaigns.h"

#include <algorithm>
#include <fstream>
#include <random>
#include <sstream>
#include <system_error>
#include <vector>

#include "strokelab/data/recordings.h"
#include "strokelab/jobs/jobs.h"

namespace strokelab::jobs {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr size_t kMaxCampaignFiles = 10'000;
constexpr size_t kCampaignIdDigits = 16;

// Whether `path` lies inside `root` (both canonical), by whole components.
bool Inside(const fs::path& path, const fs::path& root) {
  const fs::path relative = path.lexically_relative(root);
  return !relative.empty() && *relative.begin() != "..";
}

}  // namespace

std::string NewCampaignId() {
  std::random_device random;
  std::uniform_int_distribution<int> digit(0, 15);
  std::string id;
  for (size_t i = 0; i < kCampaignIdDigits; ++i) id += "0123456789abcdef"[digit(random)];
  return id;
}

std::string ReadFileBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path.string());
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

bool IsCampaignId(std::string_view id) {
  return id.size() == kCampaignIdDigits &&
         std::all_of(id.begin(), id.end(), [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); });
}

fs::path ResolveCampaign(const json& campaign, const CampaignDirs& dirs) {
  const bool has_path = campaign.contains("path"), has_id = campaign.contains("id");
  if (has_path == has_id)
    throw InputError("/campaign", "must give exactly one of path (under the server's data root) and id (an upload)");
  if (has_id) {
    const std::string id = campaign.at("id");
    if (!IsCampaignId(id))
      throw InputError("/campaign/id", "is not a campaign id (16 hex digits, as POST /v1/campaigns returns)");
    const fs::path dir = dirs.uploads.empty() ? fs::path() : dirs.uploads / id;
    if (dir.empty() || !fs::is_directory(dir))
      throw InputError("/campaign/id", "no uploaded campaign " + id + " on this server");
    return fs::canonical(dir);
  }
  const std::string text = campaign.at("path");
  if (dirs.data_root.empty())
    throw InputError("/campaign/path", "this server has no data root (serve --data-root DIR); upload the campaign instead");
  const fs::path relative(text);
  if (relative.is_absolute() || relative.has_root_name() || relative.has_root_directory())
    throw InputError("/campaign/path", "must be relative to the server's data root, not absolute");
  for (const fs::path& part : relative)
    if (part == "..") throw InputError("/campaign/path", "must not contain '..' (it must stay inside the data root)");
  std::error_code error;
  const fs::path root = fs::canonical(dirs.data_root, error);
  if (error) throw std::runtime_error("data root " + dirs.data_root.string() + ": " + error.message());
  const fs::path dir = fs::canonical(root / relative, error);
  if (error || !fs::is_directory(dir))
    throw InputError("/campaign/path", "no campaign directory '" + text + "' under the data root");
  if (!Inside(dir, root) && dir != root)
    throw InputError("/campaign/path", "leads outside the data root (through a symbolic link)");
  return dir;
}

std::string CampaignDigest(const fs::path& dir, const fs::path& root, uint64_t max_bytes) {
  // The manifest first: only the files it lists are looked at (a directory holding other large
  // files is never read), and their sizes are checked before any is.
  std::vector<std::string> names;
  try {
    names = CampaignFiles(dir);
  } catch (const InputError& e) {
    throw CampaignError(e.field(), e.bare_message());
  }
  if (names.size() > kMaxCampaignFiles)
    throw InputError("/campaign", "lists more than " + std::to_string(kMaxCampaignFiles) + " files");
  uint64_t total_bytes = 0;
  for (const std::string& name : names) {
    const fs::path file = dir / name;
    std::error_code error;
    if (!root.empty()) {
      const fs::path target = fs::canonical(file, error);
      if (error || !Inside(target, root))
        throw InputError("/campaign/path", "'" + name + "' is a symbolic link leading outside the data root (or nowhere)");
    }
    if (!fs::is_regular_file(file, error))
      throw CampaignError(name, "not a regular file (the manifest lists it)");
    total_bytes += fs::file_size(file, error);
    if (error) throw CampaignError(name, "cannot be read: " + error.message());
    if (total_bytes > max_bytes)
      throw InputError("/campaign", "the files its manifest lists hold more than the server's limit of " +
                                        std::to_string(max_bytes) + " bytes (serve --max-campaign-bytes)");
  }
  std::string listing;
  for (const std::string& name : names) {
    const std::string bytes = ReadFileBytes(dir / name);
    listing += fs::path(name).lexically_normal().generic_string() + '\0' + std::to_string(bytes.size()) + '\0' +
               ContentKey(bytes) + '\n';
  }
  return ContentKey(listing);
}

}  // namespace strokelab::jobs
