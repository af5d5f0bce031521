// The service's Prometheus metrics (GET /metrics): request latency, tasks done and their rate, rows
// written, and the store's job and task counts. Internal to the service.
#pragma once

#include <cstdint>
#include <iterator>
#include <mutex>
#include <string>

#include "strokelab/server/store.h"

namespace strokelab::server::internal {

class Metrics {
 public:
  static constexpr double kBuckets[] = {0.001, 0.005, 0.01, 0.05, 0.1, 0.5, 1.0, 5.0};
  void ObserveRequest(double seconds);
  void TaskDone(size_t rows);
  // The Prometheus text exposition of these and of the store's counts.
  std::string Text(const Store::Counts& counts) const;

 private:
  mutable std::mutex mutex_;
  uint64_t requests_ = 0, latency_buckets_[std::size(kBuckets)] = {}, tasks_done_ = 0, rows_written_ = 0;
  double latency_sum_ = 0, tasks_per_second_ = 0;
  int64_t last_task_ms_ = 0;
};

}  // namespace strokelab::server::internal
