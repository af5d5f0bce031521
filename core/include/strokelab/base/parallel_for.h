// A loop over independent items on a few threads, for the fit, the diagnosis and the campaign
// reader and synthesiser (the sweep has its own pool with chunking and cancellation, sweep.h).
#pragma once

#include <cstddef>
#include <functional>

namespace strokelab {

// f(i) for i = 0 .. n - 1 on min(n, max_threads) threads (max_threads 0: one per core); f must be
// safe to run side by side. The first exception in index order is re-thrown after every item ran.
void ParallelFor(size_t n, const std::function<void(size_t)>& f, size_t max_threads = 0);

}  // namespace strokelab
