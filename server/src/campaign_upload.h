// Campaign uploads for fit and diagnose jobs: a tar or zip archive (POST /v1/campaigns) stored in
// the service's storage directory (jobs/campaigns.h resolves them, and paths under the data root).
//
// Uploads: the archive (zip_reader.h when it starts with a zip signature, else ustar.h) is unpacked
// into UPLOADS/.incoming-ID/, its campaign directory found (manifest.json at the archive's top, or
// in its single top-level directory), read and validated with ReadCampaign (recordings.h), and only
// then renamed to UPLOADS/ID: a campaign id always names a complete, valid, immutable campaign.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "archive.h"
#include "strokelab/identify/campaign.h"
#include "strokelab/jobs/campaigns.h"

namespace strokelab::server {

struct UploadedCampaign {
  std::string id;
  Campaign campaign;
};

// The uploads on disk would pass their total quota (serve --uploads-total-quota-bytes).
class UploadQuotaError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Unpacks, validates and stores an uploaded archive (zip by its first bytes, else tar) under
// `uploads_dir` (created if needed). The members' bytes are limited by `limits` (max_total_bytes:
// the per-upload quota); the files already under `uploads_dir` plus this upload's must stay within
// `total_quota_bytes` (checked and written under one lock, so two uploads cannot both pass).
// Throws ArchiveError (a bad archive), jobs::CampaignError (a bad campaign; nothing is kept),
// UploadQuotaError, or std::runtime_error when the file system refuses.
UploadedCampaign StoreUploadedCampaign(std::string_view archive, const std::filesystem::path& uploads_dir,
                                       const ArchiveLimits& limits = {}, uint64_t total_quota_bytes = UINT64_MAX);

// A short description of a campaign for replies: actuator, response, absolute_scale, records,
// stepped_sine_records.
nlohmann::json CampaignSummary(const Campaign& campaign);

}  // namespace strokelab::server
