// The service's Prometheus metrics (metrics.h).
#include "metrics.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "now.h"

namespace strokelab::server::internal {

void Metrics::ObserveRequest(double seconds) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++requests_;
  latency_sum_ += seconds;
  for (size_t i = 0; i < std::size(kBuckets); ++i)
    if (seconds <= kBuckets[i]) ++latency_buckets_[i];
}

void Metrics::TaskDone(size_t rows) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++tasks_done_;
  rows_written_ += rows;
  const int64_t now = NowMs();
  // Tasks per second, an exponentially weighted average over ~10 s.
  if (last_task_ms_ > 0) {
    const double dt = std::max(1e-3, (now - last_task_ms_) / 1000.0);
    const double w = std::exp(-dt / 10.0);
    tasks_per_second_ = w * tasks_per_second_ + (1 - w) / dt;
  }
  last_task_ms_ = now;
}

std::string Metrics::Text(const Store::Counts& counts) const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::string out;
  char line[1024];
  out += "# HELP strokelab_jobs Jobs by state.\n# TYPE strokelab_jobs gauge\n";
  const char* states[] = {"queued", "running", "succeeded", "failed", "cancelled"};
  for (int i = 0; i < 5; ++i) {
    std::snprintf(line, sizeof line, "strokelab_jobs{state=\"%s\"} %lld\n", states[i],
                  static_cast<long long>(counts.jobs[i]));
    out += line;
  }
  std::snprintf(line, sizeof line,
                "# HELP strokelab_queue_depth Tasks waiting for a worker.\n# TYPE strokelab_queue_depth gauge\n"
                "strokelab_queue_depth %lld\n"
                "# HELP strokelab_tasks_leased Tasks being worked on.\n# TYPE strokelab_tasks_leased gauge\n"
                "strokelab_tasks_leased %lld\n",
                static_cast<long long>(counts.tasks_queued), static_cast<long long>(counts.tasks_leased));
  out += line;
  std::snprintf(line, sizeof line,
                "# HELP strokelab_tasks_completed_total Tasks completed by this process.\n"
                "# TYPE strokelab_tasks_completed_total counter\nstrokelab_tasks_completed_total %llu\n"
                "# HELP strokelab_tasks_per_second Recent task completion rate.\n"
                "# TYPE strokelab_tasks_per_second gauge\nstrokelab_tasks_per_second %.6g\n"
                "# HELP strokelab_result_rows_written_total Result rows written to SQLite.\n"
                "# TYPE strokelab_result_rows_written_total counter\nstrokelab_result_rows_written_total %llu\n",
                static_cast<unsigned long long>(tasks_done_), tasks_per_second_,
                static_cast<unsigned long long>(rows_written_));
  out += line;
  out += "# HELP strokelab_request_duration_seconds Request latency.\n"
         "# TYPE strokelab_request_duration_seconds histogram\n";
  for (size_t i = 0; i < std::size(kBuckets); ++i) {
    std::snprintf(line, sizeof line, "strokelab_request_duration_seconds_bucket{le=\"%g\"} %llu\n", kBuckets[i],
                  static_cast<unsigned long long>(latency_buckets_[i]));
    out += line;
  }
  std::snprintf(line, sizeof line,
                "strokelab_request_duration_seconds_bucket{le=\"+Inf\"} %llu\n"
                "strokelab_request_duration_seconds_sum %.6f\nstrokelab_request_duration_seconds_count %llu\n",
                static_cast<unsigned long long>(requests_), latency_sum_,
                static_cast<unsigned long long>(requests_));
  out += line;
  return out;
}

}  // namespace strokelab::server::internal
