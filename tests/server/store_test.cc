// The job store and task queue: the lease protocol (expiry, take-over, renew, cancel, fail), the
// result cache, paging and filters. Concurrent workers, persistence across close and SIGKILL, and the
// migrations: store_durability_test.cc. Times are synthetic milliseconds passed to every call.
#include "strokelab/server/store.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "store_test_util.h"

namespace strokelab::server {
namespace {

using nlohmann::json;
using store_test::kLeaseMs;
using store_test::MakeRows;
using store_test::MakeTasks;
using store_test::QueryInt;
using store_test::StoreTest;

TEST_F(StoreTest, SubmitLeaseCompleteSucceeds) {
  const json spec = {{"kind", "sweep"}, {"model", "paper"}};
  const int64_t id = store_->SubmitJob("sweep", spec, MakeTasks(3, "k"), 100);
  JobRecord job = Job(id);
  EXPECT_EQ(job.kind, "sweep");
  EXPECT_EQ(job.status, JobStatus::kQueued);
  EXPECT_EQ(job.spec, spec);
  EXPECT_EQ(job.tasks_total, 3);
  EXPECT_EQ(job.tasks_done, 0);
  EXPECT_EQ(job.created_ms, 100);
  EXPECT_EQ(job.started_ms, 0);

  std::vector<TaskLease> leases;
  for (int i = 0; i < 3; ++i) {
    std::optional<TaskLease> lease = store_->LeaseTask("w1", 200 + i, kLeaseMs);
    ASSERT_TRUE(lease.has_value());
    EXPECT_EQ(lease->job_id, id);
    EXPECT_EQ(lease->index, i);  // oldest first
    EXPECT_EQ(lease->kind, "sweep");
    EXPECT_EQ(lease->spec, (json{{"chunk", i}}));
    EXPECT_EQ(lease->lease_token.size(), 32u);
    EXPECT_EQ(lease->expires_ms, 200 + i + kLeaseMs);
    leases.push_back(*lease);
  }
  EXPECT_NE(leases[0].lease_token, leases[1].lease_token);
  EXPECT_FALSE(store_->LeaseTask("w1", 300, kLeaseMs).has_value());
  job = Job(id);
  EXPECT_EQ(job.status, JobStatus::kRunning);
  EXPECT_EQ(job.started_ms, 200);

  ASSERT_TRUE(store_->CompleteTask(leases[1], MakeRows(1, 4), 400));
  ASSERT_TRUE(store_->CompleteTask(leases[0], MakeRows(0, 4), 401));
  job = Job(id);
  EXPECT_EQ(job.status, JobStatus::kRunning);
  EXPECT_EQ(job.tasks_done, 2);
  EXPECT_EQ(job.finished_ms, 0);
  ASSERT_TRUE(store_->CompleteTask(leases[2], MakeRows(2, 4), 402));
  job = Job(id);
  EXPECT_EQ(job.status, JobStatus::kSucceeded);
  EXPECT_EQ(job.tasks_done, 3);
  EXPECT_EQ(job.finished_ms, 402);
  EXPECT_EQ(store_->CountResults(id, "points"), 12);

  // Completing twice is refused and writes nothing.
  EXPECT_FALSE(store_->CompleteTask(leases[2], MakeRows(2, 4), 403));
  EXPECT_EQ(store_->CountResults(id, "points"), 12);
  EXPECT_FALSE(store_->GetJob(id + 1).has_value());
}

TEST_F(StoreTest, ExpiredLeaseIsTakenOverAndTheOldHolderWritesNothing) {
  const int64_t id = store_->SubmitJob("sweep", json::object(), MakeTasks(1, "k"), 0);
  const TaskLease first = store_->LeaseTask("w1", 0, kLeaseMs).value();
  EXPECT_FALSE(store_->LeaseTask("w2", kLeaseMs - 1, kLeaseMs).has_value()) << "lease still valid";

  // Expired but not yet taken over: still lost (leases are checked against their expiry).
  EXPECT_FALSE(store_->CompleteTask(first, MakeRows(0, 5), kLeaseMs));
  EXPECT_EQ(store_->CountResults(id, "points"), 0);

  const TaskLease second = store_->LeaseTask("w2", kLeaseMs, kLeaseMs).value();
  EXPECT_EQ(second.task_id, first.task_id);
  EXPECT_NE(second.lease_token, first.lease_token);
  EXPECT_FALSE(store_->CompleteTask(first, MakeRows(0, 5), kLeaseMs + 1));
  EXPECT_FALSE(store_->RenewLease(first, kLeaseMs + 1, kLeaseMs));
  store_->FailTask(first, "stale holder", kLeaseMs + 1);  // ignored: not the holder
  EXPECT_EQ(Job(id).status, JobStatus::kRunning);
  EXPECT_EQ(store_->CountResults(id, "points"), 0);

  EXPECT_TRUE(store_->CompleteTask(second, MakeRows(0, 5), kLeaseMs + 2));
  EXPECT_FALSE(store_->CompleteTask(first, MakeRows(0, 5), kLeaseMs + 3));
  EXPECT_EQ(store_->CountResults(id, "points"), 5);
  EXPECT_EQ(Job(id).status, JobStatus::kSucceeded);
  EXPECT_EQ(QueryInt(path_, "SELECT attempts FROM tasks"), 2);
}

TEST_F(StoreTest, RenewExtendsAHeldLeaseOnly) {
  store_->SubmitJob("sweep", json::object(), MakeTasks(1, "k"), 0);
  const TaskLease lease = store_->LeaseTask("w1", 0, kLeaseMs).value();
  ASSERT_TRUE(store_->RenewLease(lease, 900, kLeaseMs));  // now expires at 1900
  EXPECT_FALSE(store_->LeaseTask("w2", 1500, kLeaseMs).has_value());
  TaskLease forged = lease;
  forged.lease_token = std::string(32, '0');
  EXPECT_FALSE(store_->RenewLease(forged, 1600, kLeaseMs));
  EXPECT_FALSE(store_->CompleteTask(forged, MakeRows(0, 1), 1600));
  EXPECT_TRUE(store_->CompleteTask(lease, MakeRows(0, 1), 1800));
  EXPECT_FALSE(store_->RenewLease(lease, 1850, kLeaseMs)) << "done: nothing to renew";

  store_->SubmitJob("sweep", json::object(), MakeTasks(1, "other"), 0);
  const TaskLease late = store_->LeaseTask("w1", 2000, kLeaseMs).value();
  EXPECT_FALSE(store_->RenewLease(late, 3000, kLeaseMs)) << "expired";
}

TEST_F(StoreTest, CancelVoidsLeasesAndRefusesFinishedJobs) {
  const int64_t queued = store_->SubmitJob("sweep", json::object(), MakeTasks(2, "q"), 0);
  const int64_t running = store_->SubmitJob("sweep", json::object(), MakeTasks(2, "r"), 0);
  EXPECT_TRUE(store_->CancelJob(queued, 10));
  EXPECT_EQ(Job(queued).status, JobStatus::kCancelled);
  EXPECT_EQ(Job(queued).finished_ms, 10);

  const TaskLease lease = store_->LeaseTask("w1", 20, kLeaseMs).value();
  EXPECT_EQ(lease.job_id, running) << "a cancelled job's tasks are not leased";
  EXPECT_TRUE(store_->CancelJob(running, 30));
  EXPECT_FALSE(store_->CompleteTask(lease, MakeRows(lease.index, 3), 40));
  EXPECT_FALSE(store_->RenewLease(lease, 40, kLeaseMs));
  EXPECT_EQ(store_->CountResults(running, "points"), 0);
  EXPECT_FALSE(store_->LeaseTask("w1", 50, kLeaseMs).has_value());
  EXPECT_FALSE(store_->LeaseTask("w1", 10 * kLeaseMs, kLeaseMs).has_value()) << "expired leases of cancelled jobs";
  EXPECT_EQ(Job(running).status, JobStatus::kCancelled);
  EXPECT_EQ(Job(running).tasks_done, 0);

  EXPECT_FALSE(store_->CancelJob(running, 60)) << "already cancelled";
  EXPECT_FALSE(store_->CancelJob(999, 60)) << "unknown job";
  const int64_t done = store_->SubmitJob("sweep", json::object(), MakeTasks(1, "d"), 0);
  ASSERT_TRUE(store_->CompleteTask(store_->LeaseTask("w1", 70, kLeaseMs).value(), MakeRows(0, 1), 71));
  EXPECT_EQ(Job(done).status, JobStatus::kSucceeded);
  EXPECT_FALSE(store_->CancelJob(done, 80));
  EXPECT_EQ(Job(done).status, JobStatus::kSucceeded);
}

TEST_F(StoreTest, FailTaskFailsTheJobAndClosesItsTasks) {
  const int64_t id = store_->SubmitJob("sweep", json::object(), MakeTasks(3, "k"), 0);
  const TaskLease a = store_->LeaseTask("w1", 0, kLeaseMs).value();
  const TaskLease b = store_->LeaseTask("w2", 0, kLeaseMs).value();
  ASSERT_TRUE(store_->CompleteTask(a, MakeRows(0, 2), 1));
  store_->FailTask(b, "model: contact_stiffness must be positive", 2);
  const JobRecord job = Job(id);
  EXPECT_EQ(job.status, JobStatus::kFailed);
  EXPECT_EQ(job.error, "model: contact_stiffness must be positive");
  EXPECT_EQ(job.finished_ms, 2);
  EXPECT_FALSE(store_->LeaseTask("w1", 3, kLeaseMs).has_value());
  EXPECT_FALSE(store_->CancelJob(id, 4));
  EXPECT_EQ(store_->CountResults(id, "points"), 2) << "the finished task's rows stay";
}

TEST_F(StoreTest, CachedTasksAreDoneAtSubmission) {
  const int64_t first = store_->SubmitJob("sweep", json::object(), MakeTasks(2, "k"), 0);
  for (int i = 0; i < 2; ++i) {
    const TaskLease lease = store_->LeaseTask("w1", 10, kLeaseMs).value();
    std::vector<ResultRow> rows = MakeRows(lease.index, 3);
    rows.push_back({"thresholds", json{{"frequency_hz", 7.0}, {"grazing_v", 0.2 + lease.index}}});
    ASSERT_TRUE(store_->CompleteTask(lease, rows, 20));
  }
  ASSERT_EQ(Job(first).status, JobStatus::kSucceeded);
  // Each task's rows are stored as one block per table (server/src/row_block.h).
  EXPECT_EQ(store_test::QueryText(path_, "SELECT group_concat(table_name || ':' || rows, ',') FROM result_blocks "
                                         "WHERE job_id = " + std::to_string(first) + " AND task_idx = 0"),
            "points:3,thresholds:1");
  EXPECT_EQ(store_->JobEvents(first).back().points, 6) << "points rows only, thresholds are not points";

  // The same work again: succeeded at once, the same rows, nothing to lease.
  const int64_t repeat = store_->SubmitJob("sweep", json::object(), MakeTasks(2, "k"), 30);
  JobRecord job = Job(repeat);
  EXPECT_EQ(job.status, JobStatus::kSucceeded);
  EXPECT_EQ(job.tasks_done, 2);
  EXPECT_EQ(job.finished_ms, 30);
  EXPECT_FALSE(store_->LeaseTask("w1", 40, kLeaseMs).has_value());
  EXPECT_EQ(AllRows(repeat, "points", {}, 100), AllRows(first, "points", {}, 100));
  EXPECT_EQ(AllRows(repeat, "thresholds", {}, 100), AllRows(first, "thresholds", {}, 100));
  EXPECT_EQ(store_->CountResults(repeat, "thresholds"), 2);
  EXPECT_EQ(store_->JobEvents(repeat).back().points, 6) << "the points served from the finished tasks";

  // Half known: only the new task is leased; its index is its place in the new job.
  std::vector<TaskSpec> mixed = {{"new", json{{"chunk", "new"}}}, {"k1", json{{"chunk", 1}}}};
  const int64_t partial = store_->SubmitJob("sweep", json::object(), mixed, 50);
  job = Job(partial);
  EXPECT_EQ(job.status, JobStatus::kQueued);
  EXPECT_EQ(job.tasks_done, 1);
  const TaskLease lease = store_->LeaseTask("w1", 60, kLeaseMs).value();
  EXPECT_EQ(lease.job_id, partial);
  EXPECT_EQ(lease.index, 0);
  EXPECT_FALSE(store_->LeaseTask("w1", 60, kLeaseMs).has_value());
  ASSERT_TRUE(store_->CompleteTask(lease, MakeRows(9, 2), 70));
  EXPECT_EQ(Job(partial).status, JobStatus::kSucceeded);
  const std::vector<json> rows = AllRows(partial, "points", {}, 100);
  ASSERT_EQ(rows.size(), 5u);
  EXPECT_EQ(rows[0]["task"], 9);  // task 0 (computed) first, then task 1 (from the finished task of key "k1")
  EXPECT_EQ(rows[2]["task"], 1);
  EXPECT_EQ(store_->JobEvents(partial).back().points, 5) << "3 from the cache at submission, 2 computed";

  // A job without tasks has nothing to wait for.
  EXPECT_EQ(Job(store_->SubmitJob("sweep", json::object(), {}, 80)).status, JobStatus::kSucceeded);
}

// Reads while a write holds the store's write lock (the event sink runs under it, just after
// COMMIT): each answers at once from the last commit instead of waiting for the write to end, and an
// empty queue's lease request does not wait either. The reads run on another thread while the sink
// waits up to 5 s for them.
TEST_F(StoreTest, ReadsDoNotWaitBehindAWrite) {
  const int64_t id = store_->SubmitJob("sweep", json::object(), MakeTasks(2, "k"), 0);
  const TaskLease first = store_->LeaseTask("w1", 10, kLeaseMs).value();
  const TaskLease second = store_->LeaseTask("w1", 10, kLeaseMs).value();
  ASSERT_TRUE(store_->CompleteTask(first, MakeRows(0, 3), 20));

  std::atomic<bool> reads_done{false};
  bool answered_under_the_write = false;
  std::optional<JobRecord> job;
  int64_t points = -1;
  size_t page_rows = 0, jobs_listed = 0, events = 0;
  Store::Counts counts;
  bool leased = true;
  std::thread reader;
  store_->SetJobEventSink([&](const JobEvent& e) {
    if (e.status != JobStatus::kSucceeded) return;
    reader = std::thread([&] {
      job = store_->GetJob(id);
      points = store_->CountResults(id, "points");
      page_rows = store_->Results(id, "points", {}, 0, 100).rows.size();
      jobs_listed = store_->ListJobs(10, 0).size();
      events = store_->JobEvents(id).size();
      counts = store_->GetCounts(30);
      leased = store_->LeaseTask("w2", 30, kLeaseMs).has_value();
      reads_done = true;
    });
    const auto start = std::chrono::steady_clock::now();
    while (!reads_done && std::chrono::steady_clock::now() - start < std::chrono::seconds(5))
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    answered_under_the_write = reads_done;
  });
  ASSERT_TRUE(store_->CompleteTask(second, MakeRows(1, 3), 30));
  reader.join();
  EXPECT_TRUE(answered_under_the_write) << "the reads waited for the write lock";
  ASSERT_TRUE(job.has_value());
  EXPECT_EQ(job->status, JobStatus::kSucceeded) << "committed before the sink is told";
  EXPECT_EQ(job->tasks_done, 2);
  EXPECT_EQ(points, 6);
  EXPECT_EQ(page_rows, 6u);
  EXPECT_EQ(jobs_listed, 1u);
  EXPECT_EQ(events, 3u);  // queued, running, succeeded
  EXPECT_EQ(counts.jobs[static_cast<int>(JobStatus::kSucceeded)], 1);
  EXPECT_EQ(counts.tasks_done, 2);
  EXPECT_FALSE(leased);
}

TEST_F(StoreTest, ResultsPageInTaskRowOrderAndFilter) {
  const int kTasks = 6, kRows = 10;
  const int64_t id = store_->SubmitJob("sweep", json::object(), MakeTasks(kTasks, "k"), 0);
  std::vector<TaskLease> leases;
  for (int i = 0; i < kTasks; ++i) leases.push_back(store_->LeaseTask("w", 0, kLeaseMs).value());
  for (int i = kTasks - 1; i >= 0; --i) ASSERT_TRUE(store_->CompleteTask(leases[i], MakeRows(i, kRows), 1));
  EXPECT_FALSE(store_->LeaseTask("w", 0, kLeaseMs).has_value());

  // Pages of 7 (not a divisor of the row count) in (task, row) order although written backwards.
  const std::vector<json> all = AllRows(id, "points", {}, 7);
  ASSERT_EQ(all.size(), static_cast<size_t>(kTasks * kRows));
  for (size_t k = 0; k < all.size(); ++k) {
    EXPECT_EQ(all[k]["task"], static_cast<int>(k) / kRows);
    EXPECT_EQ(all[k]["row"], static_cast<int>(k) % kRows);
  }
  // The last page ends with next_cursor 0 also when it is full.
  Store::Page page = store_->Results(id, "points", {}, 0, kTasks * kRows);
  EXPECT_EQ(page.rows.size(), static_cast<size_t>(kTasks * kRows));
  EXPECT_EQ(page.next_cursor, 0);
  EXPECT_TRUE(store_->Results(id, "thresholds", {}, 0, 10).rows.empty());
  EXPECT_TRUE(store_->Results(id + 1, "points", {}, 0, 10).rows.empty());

  Store::Filter band;
  band.frequency_min_hz = 7.0;
  band.frequency_max_hz = 9.0;  // rows 2, 3, 4 of every task
  std::vector<json> rows = AllRows(id, "points", band, 4);
  ASSERT_EQ(rows.size(), static_cast<size_t>(3 * kTasks));
  for (const json& r : rows) EXPECT_TRUE(r["frequency_hz"] >= 7.0 && r["frequency_hz"] <= 9.0) << r;

  Store::Filter amplitude;
  amplitude.amplitude_v = 0.2 * (1 + 1e-12);  // tasks 1 and 4, matched to 1e-9 relative
  rows = AllRows(id, "points", amplitude, 3);
  ASSERT_EQ(rows.size(), static_cast<size_t>(2 * kRows));
  EXPECT_EQ(rows.front()["task"], 1);
  EXPECT_EQ(rows.back()["task"], 4);
  amplitude.amplitude_v = 0.2 * (1 + 1e-6);
  EXPECT_TRUE(AllRows(id, "points", amplitude, 3).empty());

  Store::Filter all_filters = band;
  all_filters.amplitude_v = 0.3;
  all_filters.branch = "up";  // even rows: 2 and 4 of tasks 2 and 5
  rows = AllRows(id, "points", all_filters, 1);
  ASSERT_EQ(rows.size(), 4u);
  for (const json& r : rows) {
    EXPECT_EQ(r["branch"], "up");
    EXPECT_TRUE(r["task"] == 2 || r["task"] == 5) << r;
  }

  EXPECT_THROW(store_->Results(id, "points", {}, -1, 10), std::invalid_argument);
  EXPECT_THROW(store_->Results(id, "points", {}, 0, 0), std::invalid_argument);
}

TEST_F(StoreTest, ListJobsNewestFirstAndCounts) {
  std::vector<int64_t> ids;
  for (int i = 0; i < 5; ++i) ids.push_back(store_->SubmitJob("sweep", json{{"n", i}}, MakeTasks(2, "j" + std::to_string(i) + "_"), i));
  std::vector<JobRecord> page = store_->ListJobs(2, 0);
  ASSERT_EQ(page.size(), 2u);
  EXPECT_EQ(page[0].id, ids[4]);
  EXPECT_EQ(page[1].id, ids[3]);
  page = store_->ListJobs(10, page.back().id);
  ASSERT_EQ(page.size(), 3u);
  EXPECT_EQ(page[0].id, ids[2]);
  EXPECT_EQ(page[2].id, ids[0]);
  EXPECT_EQ(page[2].spec, (json{{"n", 0}}));
  EXPECT_TRUE(store_->ListJobs(10, ids[0]).empty());

  // jobs 0, 1: running (one task leased, one done); job 2 cancelled; jobs 3, 4 queued.
  const TaskLease a = store_->LeaseTask("w", 100, kLeaseMs).value();
  const TaskLease b = store_->LeaseTask("w", 100, kLeaseMs).value();
  const TaskLease c = store_->LeaseTask("w", 100, 10 * kLeaseMs).value();
  ASSERT_TRUE(store_->CompleteTask(b, MakeRows(1, 1), 101));
  ASSERT_EQ(c.job_id, ids[1]);
  store_->CancelJob(ids[2], 102);
  Store::Counts counts = store_->GetCounts(103);
  EXPECT_EQ(counts.jobs[static_cast<int>(JobStatus::kQueued)], 2);
  EXPECT_EQ(counts.jobs[static_cast<int>(JobStatus::kRunning)], 2);
  EXPECT_EQ(counts.jobs[static_cast<int>(JobStatus::kCancelled)], 1);
  EXPECT_EQ(counts.tasks_leased, 2);
  EXPECT_EQ(counts.tasks_queued, 5);  // job 1's second task, jobs 3 and 4
  EXPECT_EQ(counts.tasks_done, 1);
  counts = store_->GetCounts(100 + kLeaseMs);  // a's lease has expired: leasable again
  EXPECT_EQ(counts.tasks_leased, 1);
  EXPECT_EQ(counts.tasks_queued, 6);
  EXPECT_EQ(a.job_id, ids[0]);
  EXPECT_STREQ(ToString(JobStatus::kSucceeded), "succeeded");
}

}  // namespace
}  // namespace strokelab::server
