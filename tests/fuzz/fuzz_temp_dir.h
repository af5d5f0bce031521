// A scratch directory for one fuzzing process, removed at exit. Harnesses that need files (a campaign
// directory, the service's SQLite file) write them here; it is on /dev/shm when there is one, so
// that the per-input file writes and SQLite's syncs cost no disk I/O.
#pragma once

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace strokelab::fuzz {

inline const std::filesystem::path& ProcessTempDir() {
  static const std::filesystem::path dir = [] {
    namespace fs = std::filesystem;
    const fs::path base = fs::is_directory("/dev/shm") ? fs::path("/dev/shm") : fs::temp_directory_path();
    fs::path made = base / ("strokelab_fuzz_" + std::to_string(::getpid()));
    fs::remove_all(made);
    fs::create_directories(made);
    std::atexit([] { std::filesystem::remove_all(ProcessTempDir()); });
    return made;
  }();
  return dir;
}

}  // namespace strokelab::fuzz
