// The one pool of threads for independent items: the sweep, the fit and the diagnosis, the campaign
// reader and synthesiser, the paper's figures.
#pragma once

#include <atomic>
#include <cstddef>
#include <functional>

namespace strokelab {

// f(i) for i = 0 .. n - 1 on min(n, max_threads) threads (max_threads 0: one per core, the calling
// thread among them); f must be safe to run side by side. After the first exception no further item
// starts, and once the items already running end, the exception of the lowest index is rethrown:
// the same one whatever the thread count, since every lower item had started. `cancel`, when set,
// is checked before each item and ends the loop with Cancelled; without one, the calling thread's
// CancelScope flag is (cancel.h), and every item runs under it.
void ParallelFor(size_t n, const std::function<void(size_t)>& f, size_t max_threads = 0,
                 const std::atomic<bool>* cancel = nullptr);

}  // namespace strokelab
