// BrokenInvariant: abort in debug builds, throw in release builds (errors.h).
#include "strokelab/base/errors.h"

#include <cstdio>
#include <cstdlib>

namespace strokelab {

void BrokenInvariant(const std::string& what) {
#ifndef NDEBUG
  std::fprintf(stderr, "strokelab: broken invariant: %s\n", what.c_str());
  std::abort();
#else
  throw InvariantError(what);
#endif
}

}  // namespace strokelab
