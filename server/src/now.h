// Wall-clock time as the store keeps it: unix epoch milliseconds. Internal to the service.
#pragma once

#include <chrono>
#include <cstdint>

namespace strokelab::server::internal {

inline int64_t NowMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace strokelab::server::internal
