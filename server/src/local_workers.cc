// The service's in-process workers: each leases tasks from the store (or takes one handed over by a
// remote lease), runs it, and stores its rows; every task runs on a thread of its own (RunHeldTask).
#include "service_impl.h"

#include <algorithm>
#include <cstdio>

#include "now.h"
#include "strokelab/jobs/jobs.h"

namespace strokelab::server {

using nlohmann::json;
using namespace internal;

// A task handed over by LeaseForRemote whose lease is still held (renewed now), if any; for a remote
// worker (with_campaign_hash) only one whose campaign it can fetch.
std::optional<TaskLease> Service::Impl::TakeHandoff(bool with_campaign_hash) {
  for (;;) {
    TaskLease lease;
    {
      std::lock_guard<std::mutex> lock(handoff_mutex);
      const auto it = std::find_if(handoff.begin(), handoff.end(), [&](const TaskLease& held) {
        return !with_campaign_hash || held.spec.contains("campaign_sha256");
      });
      if (it == handoff.end()) return std::nullopt;
      lease = *it;
      handoff.erase(it);
    }
    if (store->RenewLease(lease, NowMs(), options.lease_ms)) return lease;
  }
}

// Runs a task on a thread of its own under the task's cancel flag (jobs::RunTask polls it in every
// loop), renewing the lease every lease_ms / 4 (a simulate of an extreme model or a diagnosis takes
// minutes). Gives up, returning nullopt, when the service stops (Stop returns the task to the queue),
// the job is cancelled or the lease is lost; the flag is then raised, so the computation ends within
// a few ms (a Ceres iteration at most) and its result is dropped.
std::optional<TaskResult> Service::Impl::RunHeldTask(const TaskLease& lease,
                                                     const std::shared_ptr<std::atomic<bool>>& cancel) {
  auto computation = std::make_shared<Computation>();
  computation->job_id = lease.job_id;
  {
    std::lock_guard<std::mutex> lock(computations_mutex);
    std::erase_if(computations, [](auto& c) {
      std::lock_guard<std::mutex> done_lock(c.second->mutex);
      if (!c.second->done) return false;
      c.first.join();
      return true;
    });
    computations.emplace_back(std::thread([computation, cancel, spec = lease.spec] {
                                TaskResult result;
                                std::exception_ptr error;
                                try {
                                  result = jobs::RunTask(spec, cancel.get(), [&computation](const ProgressReport& r) {
                                    json progress = StageProgressJson(r);
                                    std::lock_guard<std::mutex> progress_lock(computation->mutex);
                                    computation->progress = std::move(progress);
                                  });
                                } catch (...) {
                                  error = std::current_exception();
                                }
                                std::lock_guard<std::mutex> done_lock(computation->mutex);
                                computation->result = std::move(result);
                                computation->error = error;
                                computation->done = true;
                                computation->done_cv.notify_all();
                              }),
                              computation);
  }
  int64_t renewed_ms = NowMs();
  std::unique_lock<std::mutex> lock(computation->mutex);
  // Raises the flag and waits (a second at most) for the computation to end, so that a worker
  // never has two running.
  const auto give_up = [&]() -> std::optional<TaskResult> {
    *cancel = true;
    computation->done_cv.wait_for(lock, std::chrono::seconds(1), [&] { return computation->done; });
    return std::nullopt;
  };
  while (!computation->done) {
    computation->done_cv.wait_for(lock, std::chrono::milliseconds(100));
    if (computation->done) break;
    if (stopping || *cancel) return give_up();
    if (NowMs() - renewed_ms >= options.lease_ms / 4) {
      lock.unlock();
      const bool held = store->RenewLease(lease, NowMs(), options.lease_ms);
      lock.lock();
      if (!held) return give_up();  // another worker has the task now (or the job is over)
      renewed_ms = NowMs();
    }
  }
  if (computation->error) std::rethrow_exception(computation->error);
  return std::move(computation->result);
}

bool Service::Impl::StoreCompletion(const TaskLease& lease, const TaskResult& result, const std::string& worker) {
  for (;;) {
    try {
      const bool stored = store->CompleteTask(lease, result, NowMs());
      storage.WriteSucceeded();
      return stored;
    } catch (const StoreError& e) {
      storage.WriteFailed(e.what(), NowMs());
      std::fprintf(stderr, "%s\n", json({{"worker", worker}, {"error", e.what()}, {"retry_s", 1}}).dump().c_str());
    }
    std::unique_lock<std::mutex> lock(wake_mutex);
    if (wake.wait_for(lock, std::chrono::seconds(1), [this] { return stopping.load(); })) return false;
  }
}

void Service::Impl::WorkLoop(int index) {
  const std::string name = "local-" + std::to_string(index);
  while (!stopping) {
    std::optional<TaskLease> lease;
    try {
      lease = TakeHandoff(/*with_campaign_hash=*/false);
      if (!lease) lease = store->LeaseTask(name, NowMs(), options.lease_ms);
    } catch (const std::exception& e) {
      if (dynamic_cast<const StoreError*>(&e)) storage.WriteFailed(e.what(), NowMs());
      std::fprintf(stderr, "%s\n", json({{"worker", name}, {"error", e.what()}}).dump().c_str());
    }
    if (!lease) {
      std::unique_lock<std::mutex> lock(wake_mutex);
      wake.wait_for(lock, std::chrono::milliseconds(200));
      continue;
    }
    auto cancel = std::make_shared<std::atomic<bool>>(false);
    {
      std::lock_guard<std::mutex> lock(cancel_mutex);
      running.emplace(lease->job_id, cancel);
    }
    if (stopping) *cancel = true;  // Stop raised the flags it found before this one was listed
    try {
      const std::optional<TaskResult> result = RunHeldTask(*lease, cancel);
      if (result && StoreCompletion(*lease, *result, name)) metrics.TaskDone(result->RowCount());
    } catch (const Cancelled&) {
      // The job was cancelled (its lease is void and nothing is written) or the service stops (Stop
      // returns the task to the queue).
    } catch (const WorkBudgetSpent& e) {
      // Back to the queue the first time, the job failed the second (Store::FailTaskOnBudget).
      try {
        store->FailTaskOnBudget(*lease, WithoutServerPaths(e.what()), NowMs());
      } catch (const std::exception& inner) {
        std::fprintf(stderr, "%s\n", json({{"worker", name}, {"error", inner.what()}}).dump().c_str());
      }
    } catch (const std::exception& e) {
      try {
        store->FailTask(*lease, WithoutServerPaths(e.what()), NowMs());  // shown to clients
      } catch (const std::exception& inner) {
        std::fprintf(stderr, "%s\n", json({{"worker", name}, {"error", inner.what()}}).dump().c_str());
      }
    }
    std::lock_guard<std::mutex> lock(cancel_mutex);
    for (auto it = running.begin(); it != running.end(); ++it) {
      if (it->second == cancel) {
        running.erase(it);
        break;
      }
    }
  }
}

}  // namespace strokelab::server
