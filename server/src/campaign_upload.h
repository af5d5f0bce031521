// Campaigns for fit and diagnose jobs: uploaded as a tar or zip archive (POST /v1/campaigns) into
// the service's storage directory, or named by a path under the data root (serve --data-root).
//
// Uploads: the archive (zip_reader.h when it starts with a zip signature, else ustar.h) is unpacked
// into UPLOADS/.incoming-ID/, its campaign directory found (manifest.json at the archive's top, or
// in its single top-level directory), read and validated with ReadCampaign (recordings.h), and only
// then renamed to UPLOADS/ID: a campaign id always names a complete, valid, immutable campaign. IDs
// are 16 random hex digits.
//
// Paths under the data root: relative, without ".." components; the directory and every file in it
// are canonicalised (symbolic links resolved) and must stay inside the canonical data root.
#pragma once

#include <cstddef>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "archive.h"
#include "strokelab/campaign.h"
#include "strokelab/server/jobs.h"

namespace strokelab::server {

// A campaign whose files were read but are not a valid campaign: the reader's InputError (field
// "manifest.json:LINE", "rec_004.csv:12", ...) passed on as its own type, for its own HTTP code.
class CampaignError : public InputError {
 public:
  using InputError::InputError;
};

struct UploadedCampaign {
  std::string id;
  Campaign campaign;
};

// Unpacks, validates and stores an uploaded archive (zip by its first bytes, else tar) under
// `uploads_dir` (created if needed).
// Throws ArchiveError (a bad archive), CampaignError (a bad campaign; nothing is kept), or
// std::runtime_error when the file system refuses.
UploadedCampaign StoreUploadedCampaign(std::string_view archive, const std::filesystem::path& uploads_dir,
                                       const ArchiveLimits& limits = {});

// Whether `id` has the form of a campaign id (so that it can be joined to a path safely).
bool IsCampaignId(std::string_view id);

// The canonical directory of a job's "campaign" object ({"path": ...} or {"id": ...}), checked as
// above. Throws InputError naming /campaign, /campaign/path or /campaign/id.
std::filesystem::path ResolveCampaign(const nlohmann::json& campaign, const CampaignDirs& dirs);

// A content digest of the regular files under `dir` (names and bytes, in name order; 16 hex digits,
// as ContentKey): a task carries the digest of the campaign it was planned for and checks it when
// it runs. When `root` is not empty, every file must resolve inside it (else InputError at
// /campaign/path). Throws InputError("/campaign", ...) for more than 10,000 files.
std::string CampaignDigest(const std::filesystem::path& dir, const std::filesystem::path& root = {});

// 16 random hex digits (std::random_device): campaign ids, scratch directory names.
std::string NewCampaignId();

// The whole content of a file; throws std::runtime_error naming it when it cannot be read.
std::string ReadFileBytes(const std::filesystem::path& path);

// A short description of a campaign for replies: actuator, response, absolute_scale, records,
// stepped_sine_records.
nlohmann::json CampaignSummary(const Campaign& campaign);

}  // namespace strokelab::server
