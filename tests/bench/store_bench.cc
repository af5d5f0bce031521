// Ingest speed of the job store (server/include/strokelab/server/store.h): result rows per second
// through LeaseTask + CompleteTask, each completion one task's rows in one transaction, as the
// service's workers store them. The rows are real: one sweep row of the paper model (1000
// frequencies, 5 .. 50 Hz, at 0.4 V; jobs::RunTask, ~1000-1100 "points" and "jumps" rows), computed
// once and completed again and again under new task keys (never a result cache hit). Not a ctest test (timings are not pass/fail). Run a Release build:
//   store_bench                                      # ~20 s
//   store_bench --benchmark_filter=Ingest/           # the writer alone
// Counters:
//   rows_per_s        result rows stored per second of wall time (the ingest rate)
//   rows_per_cpu_s    result rows stored per second of the benchmark thread's CPU time (on a
//                     shared machine the wall-time rate also counts the waits for a core)
//   rows_per_task     rows in each completion
//   status_p50_us, status_p99_us
//                     (IngestWithStatusReads) latency of GetJob, as GET /v1/jobs/{id} reads it, on two
//                     threads reading in a loop while the benchmark thread completes tasks
// The database is a fresh file in $TMPDIR per benchmark; it grows over the iterations as a server's
// does.
#include <benchmark/benchmark.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "bench_server.h"
#include "strokelab/jobs/jobs.h"
#include "strokelab/server/store.h"

namespace strokelab::server {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr int kTasksPerJob = 200;        // tasks submitted at a time; a new job when they are done
constexpr int64_t kLeaseMs = 3600 * 1000;  // never expires during a run

// The rows of one sweep row of the paper model, as an in-process worker completes them.
const TaskResult& SweepRowRows() {
  static const TaskResult rows = [] {
    const json job = {{"kind", "sweep"},
                      {"model", "paper"},
                      {"thresholds", false},
                      {"grid",
                       {{"frequency_hz", {{"from", 5}, {"to", 50}, {"points", 1000}}},
                        {"amplitude_v", {{"from", 0.4}, {"to", 0.4}, {"points", 1}}}}}};
    return jobs::RunTask(jobs::PlanTasks(job).at(0).spec);
  }();
  return rows;
}

// A store on a fresh file, removed at the end.
class ScratchStore {
 public:
  ScratchStore() {
    dir_ = fs::temp_directory_path() / ("strokelab-store-bench-" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    store_ = Store::Open((dir_ / "bench.db").string());
  }
  ~ScratchStore() {
    store_.reset();
    fs::remove_all(dir_);
  }
  Store& operator*() { return *store_; }
  Store* operator->() { return store_.get(); }

  // A leased task, submitting a new job of kTasksPerJob tasks (unique keys) when none is left.
  TaskLease NextLease(int64_t& job_id) {
    std::optional<TaskLease> lease = store_->LeaseTask("bench", ++now_ms_, kLeaseMs);
    if (!lease) {
      std::vector<TaskSpec> tasks;
      for (int i = 0; i < kTasksPerJob; ++i)
        tasks.push_back({"bench-" + std::to_string(jobs_) + "-" + std::to_string(i), json{{"chunk", i}}});
      job_id = store_->SubmitJob("sweep", json{{"kind", "sweep"}}, tasks, ++now_ms_);
      ++jobs_;
      lease = store_->LeaseTask("bench", ++now_ms_, kLeaseMs);
    }
    if (!lease) throw std::runtime_error("store_bench: no task to lease");
    return *lease;
  }
  int64_t Now() { return ++now_ms_; }

 private:
  fs::path dir_;
  std::unique_ptr<Store> store_;
  int64_t now_ms_ = 1;
  int jobs_ = 0;
};

double ThreadCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

void ReportRows(benchmark::State& state, size_t rows_per_task, double cpu_s) {
  const double rows = static_cast<double>(rows_per_task) * static_cast<double>(state.iterations());
  state.counters["rows_per_s"] = benchmark::Counter(rows, benchmark::Counter::kIsRate);
  state.counters["rows_per_cpu_s"] = rows / cpu_s;
  state.counters["rows_per_task"] = static_cast<double>(rows_per_task);
}

// One completion per iteration: lease a task, store the sweep row's rows.
void BM_Ingest(benchmark::State& state) {
  const TaskResult& rows = SweepRowRows();
  ScratchStore store;
  int64_t job_id = 0;
  const double cpu0 = ThreadCpuSeconds();
  for (auto _ : state) {
    const TaskLease lease = store.NextLease(job_id);
    if (!store->CompleteTask(lease, rows, store.Now())) throw std::runtime_error("store_bench: lease lost");
  }
  ReportRows(state, rows.RowCount(), ThreadCpuSeconds() - cpu0);
}
BENCHMARK(BM_Ingest)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(3.0);

// The same while two threads read the job's status in a loop (as pollers of GET /v1/jobs/{id} do):
// how long a status read waits while completions are stored.
void BM_IngestWithStatusReads(benchmark::State& state) {
  const TaskResult& rows = SweepRowRows();
  ScratchStore store;
  int64_t job_id = 0;
  store.NextLease(job_id);  // the first job exists before the readers start
  std::atomic<int64_t> shared_job{job_id};
  std::atomic<bool> stop{false};
  constexpr int kReaders = 2;
  std::vector<std::vector<double>> latencies_us(kReaders);
  std::vector<std::thread> readers;
  for (int r = 0; r < kReaders; ++r) {
    readers.emplace_back([&, r] {
      while (!stop) {
        const auto t0 = Clock::now();
        benchmark::DoNotOptimize(store->GetJob(shared_job.load()));
        latencies_us[r].push_back(std::chrono::duration<double, std::micro>(Clock::now() - t0).count());
        std::this_thread::sleep_for(std::chrono::microseconds(200));  // a poller, not a spin
      }
    });
  }
  const double cpu0 = ThreadCpuSeconds();
  for (auto _ : state) {
    const TaskLease lease = store.NextLease(job_id);
    shared_job = job_id;
    if (!store->CompleteTask(lease, rows, store.Now())) throw std::runtime_error("store_bench: lease lost");
  }
  const double cpu_s = ThreadCpuSeconds() - cpu0;
  stop = true;
  for (std::thread& t : readers) t.join();
  std::vector<double> all;
  for (const auto& l : latencies_us) all.insert(all.end(), l.begin(), l.end());
  ReportRows(state, rows.RowCount(), cpu_s);
  state.counters["status_reads"] = static_cast<double>(all.size());
  state.counters["status_p50_us"] = bench::Percentile(all, 0.50);
  state.counters["status_p99_us"] = bench::Percentile(all, 0.99);
}
BENCHMARK(BM_IngestWithStatusReads)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(3.0);

}  // namespace
}  // namespace strokelab::server

BENCHMARK_MAIN();
