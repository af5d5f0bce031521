// The bearer tokens the in-process service tests write to their token file (one per role).
#pragma once

namespace strokelab::testing {

inline constexpr const char* kSubmitToken = "submit-token-0123456789";
inline constexpr const char* kReadToken = "read-token-0123456789ab";
inline constexpr const char* kWorkerToken = "worker-token-0123456789";

}  // namespace strokelab::testing
