// The seed of a fault test's random choices (which moment to kill, which connection to break): a
// fixed default so that runs repeat, STROKELAB_FAULT_SEED to try others; printed, so a failing
// run can be repeated with the seed it had.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace strokelab::test_fault {

inline uint64_t FaultSeed(const char* test_name, uint64_t default_seed) {
  uint64_t seed = default_seed;
  if (const char* env = std::getenv("STROKELAB_FAULT_SEED"); env && *env) seed = std::strtoull(env, nullptr, 10);
  std::printf("%s: seed %llu (set STROKELAB_FAULT_SEED to change)\n", test_name, static_cast<unsigned long long>(seed));
  return seed;
}

}  // namespace strokelab::test_fault
