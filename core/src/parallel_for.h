// A loop over independent items on one thread per core, for the fit and the diagnosis (the sweep
// has its own pool with chunking and cancellation, sweep.h).
#pragma once

#include <cstddef>
#include <functional>

namespace strokelab::internal {

// f(i) for i = 0 .. n - 1 on min(n, cores) threads; f must be safe to run side by side. The first
// exception (in index order) is re-thrown after every item has run.
void ParallelFor(size_t n, const std::function<void(size_t)>& f);

}  // namespace strokelab::internal
