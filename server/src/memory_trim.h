// How much freed heap memory glibc may keep. Internal to the service.
//
// Measured on `strokelab serve` (issue 15; tests/server/hostile_load_test.cc): after 400 bodies of
// deeply nested JSON (400 KB) and 120 chunked bodies cut off at the 1 MiB limit, RSS went from
// 21 to 33 MB and stayed there; malloc_stats showed each of the 12 arenas (one per thread that
// allocated) holding ~2 MB with ~20 KB in use, and malloc_trim(0) gave nothing back. glibc raises its
// mmap threshold to the largest block freed (here ~1 MiB, up to 32 MiB), so later buffers of that
// size come from the arenas, and it raises the trim threshold to twice that, below which an arena
// keeps its free top: ~2 MB per thread, and malloc_trim does not trim the top of a thread's arena.
// Fixed thresholds (which also turn the dynamic adjustment off) hand such buffers back as they are
// freed: the same requests then leave RSS at 21 MB.
#pragma once

#include <malloc.h>

#include <mutex>

namespace strokelab::server::internal {

inline constexpr int kHeapThresholdBytes = 128 * 1024;  // glibc's initial mmap threshold

// Sets the thresholds for the whole process, once.
inline void BoundHeapRetention() {
  static std::once_flag once;
  std::call_once(once, [] {
    mallopt(M_MMAP_THRESHOLD, kHeapThresholdBytes);
    mallopt(M_TRIM_THRESHOLD, kHeapThresholdBytes);
  });
}

}  // namespace strokelab::server::internal
