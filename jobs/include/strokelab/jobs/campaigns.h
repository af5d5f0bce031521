// Where fit and diagnose jobs find their campaigns: an upload in the service's storage directory
// ({"id": ...}, stored by the server's upload handler) or a directory under the data root
// ({"path": ...}, serve --data-root).
//
// Paths under the data root: relative, without ".." components; the directory and every file in it
// are canonicalised (symbolic links resolved) and must stay inside the canonical data root. IDs are
// 16 random hex digits.
#pragma once

#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "strokelab/base/errors.h"

namespace strokelab::jobs {

// Where fit and diagnose jobs find their campaigns.
struct CampaignDirs {
  std::filesystem::path data_root;  // {"path": ...} is relative to it; empty: paths are refused
  std::filesystem::path uploads;    // {"id": ...} is a directory in it; empty: ids are refused
  uint64_t max_campaign_bytes = UINT64_MAX;  // the files a manifest lists, in all [bytes]
};

// A campaign whose files were read but are not a valid campaign: the reader's InputError (field
// "manifest.json:LINE", "rec_004.csv:12", ...) passed on as its own type, for its own HTTP code.
class CampaignError : public InputError {
 public:
  using InputError::InputError;
};

// Whether `id` has the form of a campaign id (so that it can be joined to a path safely).
bool IsCampaignId(std::string_view id);

// 16 random hex digits (std::random_device): campaign ids, scratch directory names.
std::string NewCampaignId();

// The canonical directory of a job's "campaign" object ({"path": ...} or {"id": ...}), checked as
// above. Throws InputError naming /campaign, /campaign/path or /campaign/id.
std::filesystem::path ResolveCampaign(const nlohmann::json& campaign, const CampaignDirs& dirs);

// A content digest of the files the campaign's manifest lists (manifest.json and each record's CSV,
// data/recordings.h CampaignFiles; names and bytes, 16 hex digits, as ContentKey): a task carries the
// digest of the campaign it was planned for and checks it when it runs. Nothing else in `dir` is
// read, and the listed files' sizes are added up before any is: more than `max_bytes` in all is an
// InputError at /campaign. When `root` is not empty, every listed file must resolve inside it (else
// InputError at /campaign/path). A manifest that cannot be read, or a listed file that is not a
// regular file, is a CampaignError naming the file.
std::string CampaignDigest(const std::filesystem::path& dir, const std::filesystem::path& root = {},
                           uint64_t max_bytes = UINT64_MAX);

// The whole content of a file; throws std::runtime_error naming it when it cannot be read.
std::string ReadFileBytes(const std::filesystem::path& path);

}  // namespace strokelab::jobs
