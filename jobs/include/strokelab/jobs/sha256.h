// SHA-256 (FIPS 180-4), for the campaign a remote worker downloads: the hash in its task names the
// bytes, so a download changed on the way (or a cache changed on disk) is detected. ContentKey
// (jobs.h) stays the task cache's key; it is no defence against a deliberate change.
#pragma once

#include <string>
#include <string_view>

namespace strokelab::jobs {

// The digest of `bytes` as 64 lower-case hex digits.
std::string Sha256Hex(std::string_view bytes);

// Whether `text` has that form (64 lower-case hex digits).
bool IsSha256Hex(std::string_view text);

}  // namespace strokelab::jobs
