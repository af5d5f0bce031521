#include "campaign_upload.h"

#include <algorithm>
#include <fstream>
#include <mutex>
#include <system_error>
#include <vector>

#include "strokelab/data/mapping.h"
#include "strokelab/data/recordings.h"
#include "ustar.h"
#include "zip_reader.h"

namespace strokelab::server {
namespace {

using jobs::CampaignError;

namespace fs = std::filesystem;
using nlohmann::json;

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

// The bytes of the regular files under `dir` (the uploads' storage, for its quota).
uint64_t BytesUnder(const fs::path& dir) {
  uint64_t bytes = 0;
  std::error_code error;
  for (fs::recursive_directory_iterator it(dir, error), end; !error && it != end; it.increment(error)) {
    std::error_code size_error;
    if (it->is_regular_file(size_error)) {
      const uint64_t size = it->file_size(size_error);
      if (!size_error) bytes += size;
    }
  }
  return bytes;
}

// The campaign directory of an unpacked archive: its top, or its single top-level directory; one
// that holds manifest.json (CSV records) or mapping.json (UFF 58 or WAV files, data/mapping.h).
bool HoldsCampaignDescription(const fs::path& dir) {
  return fs::is_regular_file(fs::symlink_status(dir / kManifestName)) ||
         fs::is_regular_file(fs::symlink_status(dir / kMappingName));
}

fs::path CampaignRoot(const fs::path& unpacked) {
  if (HoldsCampaignDescription(unpacked)) return unpacked;
  std::vector<fs::path> entries;
  for (const fs::directory_entry& e : fs::directory_iterator(unpacked)) entries.push_back(e.path());
  if (entries.size() == 1 && fs::is_directory(fs::symlink_status(entries[0])) && HoldsCampaignDescription(entries[0]))
    return entries[0];
  throw ArchiveError(std::string("no ") + kManifestName + " or " + kMappingName +
                     " at the archive's top or in its single top-level directory (not a campaign)");
}

}  // namespace

UploadedCampaign StoreUploadedCampaign(std::string_view archive, const fs::path& uploads_dir,
                                       const ArchiveLimits& limits, uint64_t total_quota_bytes) {
  // The archive is read whole before anything is written: a bad one leaves no trace.
  std::vector<TarMember> tar;
  std::vector<ZipMember> zip;
  if (LooksLikeZip(archive)) zip = ReadZip(archive, limits);
  else tar = ReadUstar(archive, limits);
  uint64_t upload_bytes = 0;
  for (const TarMember& m : tar) upload_bytes += m.data.size();
  for (const ZipMember& m : zip) upload_bytes += m.data.size();
  static std::mutex quota_mutex;  // one upload at a time from the quota check to its rename
  const std::lock_guard<std::mutex> quota_lock(quota_mutex);
  fs::create_directories(uploads_dir);
  if (const uint64_t stored = BytesUnder(uploads_dir); stored + upload_bytes > total_quota_bytes)
    throw UploadQuotaError("the server's uploads hold " + std::to_string(stored) + " bytes; this upload's " +
                           std::to_string(upload_bytes) + " would pass their quota of " +
                           std::to_string(total_quota_bytes) + " bytes (serve --uploads-total-quota-bytes)");
  UploadedCampaign result;
  result.id = jobs::NewCampaignId();
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
