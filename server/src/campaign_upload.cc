#include "campaign_upload.h"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <system_error>
#include <vector>

#include "strokelab/recordings.h"
#include "ustar.h"
#include "zip_reader.h"

namespace strokelab::server {
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

void WriteMember(const fs::path& target, std::string_view data, const std::string& name) {
  std::error_code error;
  fs::create_directories(target.parent_path(), error);
  if (error) throw ArchiveError("member '" + name + "': cannot create its directory (" + error.message() + ")");
  if (fs::exists(fs::symlink_status(target))) throw ArchiveError("member '" + name + "': clashes with a directory of the same name");
  std::ofstream out(target, std::ios::binary);
  out.write(data.data(), static_cast<std::streamsize>(data.size()));
  if (!out.flush()) throw std::runtime_error("cannot write " + target.string());
}

// Writes the members (TarMember or ZipMember: path, directory, data) under `dir`.
template <class Member>
void Unpack(const std::vector<Member>& members, const fs::path& dir) {
  for (const Member& m : members) {
    const fs::path target = dir / fs::path(m.path);
    if (m.directory) {
      std::error_code error;
      fs::create_directories(target, error);
      if (error) throw ArchiveError("member '" + m.path + "': cannot create the directory (" + error.message() + ")");
    } else {
      WriteMember(target, m.data, m.path);
    }
  }
}

// The campaign directory of an unpacked archive: its top, or its single top-level directory.
fs::path CampaignRoot(const fs::path& unpacked) {
  if (fs::is_regular_file(fs::symlink_status(unpacked / kManifestName))) return unpacked;
  std::vector<fs::path> entries;
  for (const fs::directory_entry& e : fs::directory_iterator(unpacked)) entries.push_back(e.path());
  if (entries.size() == 1 && fs::is_directory(fs::symlink_status(entries[0])) &&
      fs::is_regular_file(fs::symlink_status(entries[0] / kManifestName)))
    return entries[0];
  throw ArchiveError(std::string("no ") + kManifestName +
                     " at the archive's top or in its single top-level directory (not a campaign)");
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

UploadedCampaign StoreUploadedCampaign(std::string_view archive, const fs::path& uploads_dir,
                                       const ArchiveLimits& limits) {
  // The archive is read whole before anything is written: a bad one leaves no trace.
  std::vector<TarMember> tar;
  std::vector<ZipMember> zip;
  if (LooksLikeZip(archive)) zip = ReadZip(archive, limits);
  else tar = ReadUstar(archive, limits);
  fs::create_directories(uploads_dir);
  UploadedCampaign result;
  result.id = NewCampaignId();
  const fs::path incoming = uploads_dir / (".incoming-" + result.id);
  fs::remove_all(incoming);
  fs::create_directory(incoming);
  try {
    Unpack(tar, incoming);
    Unpack(zip, incoming);
    const fs::path root = CampaignRoot(incoming);
    try {
      result.campaign = ReadCampaign(root);
    } catch (const InputError& e) {
      throw CampaignError(e.field(), e.bare_message());
    }
    fs::rename(root, uploads_dir / result.id);
    fs::remove_all(incoming);  // what is left when the campaign was a top-level directory
  } catch (...) {
    std::error_code ignored;
    fs::remove_all(incoming, ignored);
    throw;
  }
  return result;
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

std::string CampaignDigest(const fs::path& dir, const fs::path& root) {
  std::vector<fs::path> files;
  for (const fs::directory_entry& e : fs::recursive_directory_iterator(dir)) {
    if (!root.empty()) {
      std::error_code error;
      const fs::path target = fs::canonical(e.path(), error);
      if (error || !Inside(target, root))
        throw InputError("/campaign/path", "'" + e.path().lexically_relative(dir).string() +
                                               "' is a symbolic link leading outside the data root (or nowhere)");
    }
    if (!fs::is_regular_file(e.status())) continue;
    files.push_back(e.path());
    if (files.size() > kMaxCampaignFiles)
      throw InputError("/campaign", "holds more than " + std::to_string(kMaxCampaignFiles) + " files");
  }
  std::sort(files.begin(), files.end());
  std::string listing;
  for (const fs::path& file : files) {
    const std::string bytes = ReadFileBytes(file);
    listing += file.lexically_relative(dir).generic_string() + '\0' + std::to_string(bytes.size()) + '\0' +
               ContentKey(bytes) + '\n';
  }
  return ContentKey(listing);
}

json CampaignSummary(const Campaign& campaign) {
  const size_t stepped =
      std::count_if(campaign.records.begin(), campaign.records.end(), [](const Recording& r) { return !r.broadband; });
  return {{"actuator", campaign.actuator},
          {"response", ToString(campaign.response)},
          {"absolute_scale", campaign.absolute_scale},
          {"records", campaign.records.size()},
          {"stepped_sine_records", stepped}};
}

}  // namespace strokelab::server
