// A campaign directory as one byte string, so that a remote worker can fetch the campaign of a fit or
// diagnose task from the server (GET /v1/campaigns/{sha256}) and check it against the SHA-256 its
// task carries (campaign_sha256, set when the job was planned).
//
// Format: the line "strokelab-campaign 1\n", then per file the manifest names (manifest.json and the
// records' CSVs, data/recordings.h CampaignFiles; no other file in the directory is read), in name
// order: its relative name ('/' between components), a NUL, its size in decimal digits, a newline,
// its bytes.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace strokelab::jobs {

// The bundle of `dir` (throws InputError for a bad manifest or beyond 10,000 files, std::runtime_error
// when a file cannot be read).
std::string CampaignBundle(const std::filesystem::path& dir);

// Sha256Hex(CampaignBundle(dir)): the campaign's content hash.
std::string CampaignSha256(const std::filesystem::path& dir);

// Writes the files of `bundle` under `dir` (created; it should be new and empty). Strict: a bad
// header, a truncated file, a name that is empty, absolute, has an empty, "." or ".." component, a
// backslash or a control character, a name given twice, or more than 10,000 files throw
// std::runtime_error naming the file, and nothing is written past the first error.
void UnpackCampaignBundle(std::string_view bundle, const std::filesystem::path& dir);

}  // namespace strokelab::jobs
