// ParallelFor (parallel_for.h).
#include "strokelab/base/parallel_for.h"

#include <algorithm>
#include <exception>
#include <thread>
#include <vector>

#include "strokelab/base/cancel.h"
#include "strokelab/base/errors.h"

namespace strokelab {

void ParallelFor(size_t n, const std::function<void(size_t)>& f, size_t max_threads,
                 const std::atomic<bool>* cancel) {
  const size_t cores = std::max(1u, std::thread::hardware_concurrency());
  const size_t threads = std::min<size_t>(n, max_threads > 0 ? max_threads : cores);
  std::vector<std::exception_ptr> errors(n);
  std::atomic<size_t> next{0};
  std::atomic<bool> failed{false};
  // Without a flag of its own the loop stops on the caller's (cancel.h), which its threads inherit.
  if (cancel == nullptr) cancel = CurrentCancelFlag();
  auto work = [&] {
    CancelScope scope(cancel);
    for (size_t i; !failed.load() && (i = next++) < n;) {
      try {
        if (cancel && cancel->load()) throw Cancelled();
        f(i);
      } catch (...) {
        errors[i] = std::current_exception();
        failed = true;
      }
    }
  };
  std::vector<std::thread> pool;
  for (size_t t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  for (const std::exception_ptr& e : errors)
    if (e) std::rethrow_exception(e);
}

}  // namespace strokelab
