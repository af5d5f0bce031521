// Campaign uploads for fit and diagnose jobs: a tar or zip archive (POST /v1/campaigns) stored in
// the service's storage directory (jobs/campaigns.h resolves them, and paths under the data root).
//
// Uploads: the archive (zip_reader.h when it starts with a zip signature, else ustar.h) is unpacked
// into UPLOADS/.incoming-ID/, its campaign directory found (manifest.json at the archive's top, or
// in its single top-level directory), read and validated with ReadCampaign (recordings.h), and only
// then renamed to UPLOADS/ID: a campaign id always names a complete, valid, immutable campaign.
#pragma once

#include <cstddef>
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

// Unpacks, validates and stores an uploaded archive (zip by its first bytes, else tar) under
// `uploads_dir` (created if needed).
// Throws ArchiveError (a bad archive), jobs::CampaignError (a bad campaign; nothing is kept), or
// std::runtime_error when the file system refuses.
UploadedCampaign StoreUploadedCampaign(std::string_view archive, const std::filesystem::path& uploads_dir,
                                       const ArchiveLimits& limits = {});

// A short description of a campaign for replies: actuator, response, absolute_scale, records,
// stepped_sine_records.
nlohmann::json CampaignSummary(const Campaign& campaign);

}  // namespace strokelab::server
