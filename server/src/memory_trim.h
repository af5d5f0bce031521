// How much freed heap memory glibc may keep. Internal to the service.
//
// Two measurements pull opposite ways:
// - RSS after hostile requests (issue 15; tests/server/hostile_load_test.cc): after 400 bodies of
//   deeply nested JSON (400 KB) and 120 chunked bodies cut off at the 1 MiB limit, RSS went from 21
//   to 33 MB and stayed there with glibc's defaults: each of the 12 arenas (one per thread that
//   allocated) kept ~2 MB with ~20 KB in use. glibc raises its mmap threshold to the largest block
//   freed (up to 32 MiB) and its trim threshold to twice that, and malloc_trim does not trim the top
//   of a thread's arena.
// - CPU per task (issue 17; tests/bench/service_vs_cli.py): a sweep task allocates and frees a few
//   hundred KB at a time (its points, their cells, the encoded block). With both thresholds fixed at
//   128 KiB every task mapped fresh pages again, and a page fault costs ~5-10 us on this virtual
//   machine: the 1000 x 40 sweep job took 0.45-0.48 s against 0.31 s for the CLI.
// Fixed thresholds (which also turn the dynamic adjustment off) that hold a task's buffers in the
// heap, and at most one arena per core, bound both: measured here on 2 cores, the job 0.28-0.32 s
// and RSS 20.2 -> 22.6 MB after the 10 s attack (4 arenas: 0.32-0.36 s, 21.1 -> 24.1 MB).
#pragma once

#include <malloc.h>

#include <algorithm>
#include <mutex>
#include <thread>

namespace strokelab::server::internal {

inline constexpr int kMmapThresholdBytes = 512 * 1024;     // larger blocks are mapped and unmapped
inline constexpr int kTrimThresholdBytes = 2 * 1024 * 1024;  // free top an arena may keep

// Sets the thresholds and the arena count for the whole process, once, before its threads start.
inline void BoundHeapRetention() {
  static std::once_flag once;
  std::call_once(once, [] {
    mallopt(M_MMAP_THRESHOLD, kMmapThresholdBytes);
    mallopt(M_TRIM_THRESHOLD, kTrimThresholdBytes);
    mallopt(M_ARENA_MAX, static_cast<int>(std::max(2u, std::thread::hardware_concurrency())));
  });
}

}  // namespace strokelab::server::internal
