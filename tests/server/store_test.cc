// The job store and task queue: the lease protocol (expiry, take-over, renew, cancel, fail), the
// result cache, paging and filters, concurrent workers, persistence across close and SIGKILL, and
// the migrations. Times are synthetic milliseconds passed to every call.
#include "strokelab/server/store.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "migrations.h"

namespace strokelab::server {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

constexpr int64_t kLeaseMs = 1000;

std::vector<TaskSpec> MakeTasks(int n, const std::string& key_prefix) {
  std::vector<TaskSpec> tasks;
  for (int i = 0; i < n; ++i) tasks.push_back({key_prefix + std::to_string(i), json{{"chunk", i}}});
  return tasks;
}

// Rows of task `task`: "points" rows on a grid of frequency (5 + row Hz) at one amplitude per task
// (0.1, 0.2 or 0.3 V), alternating branches.
std::vector<ResultRow> MakeRows(int task, int count) {
  std::vector<ResultRow> rows;
  for (int r = 0; r < count; ++r) {
    rows.push_back({"points", json{{"frequency_hz", 5.0 + r},
                                   {"amplitude_v", 0.1 * (task % 3 + 1)},
                                   {"branch", r % 2 == 0 ? "up" : "down"},
                                   {"task", task},
                                   {"row", r}}});
  }
  return rows;
}

// The first column of the first row of a query on a separate raw connection (what another tool
// would see); "" when there is no row.
std::string QueryText(const std::string& path, const std::string& sql) {
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr) != SQLITE_OK) {
    sqlite3_close(db);
    throw std::runtime_error("raw open failed");
  }
  sqlite3_stmt* stmt = nullptr;
  std::string value;
  if (sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt, nullptr) == SQLITE_OK && sqlite3_step(stmt) == SQLITE_ROW &&
      sqlite3_column_text(stmt, 0) != nullptr) {
    value = reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0));
  }
  sqlite3_finalize(stmt);
  sqlite3_close(db);
  return value;
}
int64_t QueryInt(const std::string& path, const std::string& sql) {
  const std::string text = QueryText(path, sql);
  return text.empty() ? -1 : std::stoll(text);
}

// Per task of `job`: (status, number of result rows), over a raw connection.
std::map<int, std::pair<std::string, int64_t>> TaskRowCounts(const std::string& path, int64_t job) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr), SQLITE_OK);
  const std::string sql =
      "SELECT t.idx, t.status, (SELECT count(*) FROM results r WHERE r.job_id = t.job_id AND r.task_idx = t.idx) "
      "FROM tasks t WHERE t.job_id = " +
      std::to_string(job);
  sqlite3_stmt* stmt = nullptr;
  std::map<int, std::pair<std::string, int64_t>> counts;
  EXPECT_EQ(sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt, nullptr), SQLITE_OK);
  while (sqlite3_step(stmt) == SQLITE_ROW) {
    counts[sqlite3_column_int(stmt, 0)] = {reinterpret_cast<const char*>(sqlite3_column_text(stmt, 1)),
                                           sqlite3_column_int64(stmt, 2)};
  }
  sqlite3_finalize(stmt);
  sqlite3_close(db);
  return counts;
}

std::string IntegrityCheck(const std::string& path) {
  sqlite3* db = nullptr;
  sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr);
  sqlite3_stmt* stmt = nullptr;
  std::string result = "no result";
  if (sqlite3_prepare_v2(db, "PRAGMA integrity_check", -1, &stmt, nullptr) == SQLITE_OK &&
      sqlite3_step(stmt) == SQLITE_ROW) {
    result = reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0));
  }
  sqlite3_finalize(stmt);
  sqlite3_close(db);
  return result;
}

class StoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "strokelab_store_test_XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
    path_ = (dir_ / "jobs.db").string();
    store_ = Store::Open(path_);
  }
  void TearDown() override {
    store_.reset();
    fs::remove_all(dir_);
  }
  void Reopen() {
    store_.reset();
    store_ = Store::Open(path_);
  }
  JobRecord Job(int64_t id) {
    std::optional<JobRecord> job = store_->GetJob(id);
    EXPECT_TRUE(job.has_value()) << "job " << id;
    return job.value_or(JobRecord{});
  }
  // Every row of a table, paging `page_size` at a time.
  std::vector<json> AllRows(int64_t job, const std::string& table, const Store::Filter& filter, int page_size) {
    std::vector<json> rows;
    int64_t cursor = 0;
    for (int pages = 0; pages < 100000; ++pages) {
      Store::Page page = store_->Results(job, table, filter, cursor, page_size);
      EXPECT_LE(static_cast<int>(page.rows.size()), page_size);
      rows.insert(rows.end(), page.rows.begin(), page.rows.end());
      if (page.next_cursor == 0) break;
      EXPECT_GT(page.next_cursor, cursor);
      cursor = page.next_cursor;
    }
    return rows;
  }

  fs::path dir_;
  std::string path_;
  std::unique_ptr<Store> store_;
};

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
  EXPECT_EQ(rows[0]["task"], 9);  // task 0 (computed) first, then task 1 (from the cache of "k1")
  EXPECT_EQ(rows[2]["task"], 1);

  // A job without tasks has nothing to wait for.
  EXPECT_EQ(Job(store_->SubmitJob("sweep", json::object(), {}, 80)).status, JobStatus::kSucceeded);
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

// Four workers share one Store. Leases are short against a shared clock that advances at every
// call, and some workers dawdle, so leases expire and are taken over; still every task is done
// exactly once and the rows are exact.
TEST_F(StoreTest, ConcurrentWorkersCompleteEveryTaskOnce) {
  constexpr int kTasks = 200, kRows = 5, kThreads = 4;
  const int64_t id = store_->SubmitJob("sweep", json::object(), MakeTasks(kTasks, "k"), 0);
  std::atomic<int64_t> clock{1};
  std::atomic<int> lost{0};
  std::vector<std::vector<int>> completed(kThreads);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      std::mt19937 rng(t);
      const std::string name = "w" + std::to_string(t);
      for (int spins = 0; spins < 1000000; ++spins) {
        std::optional<TaskLease> lease = store_->LeaseTask(name, clock++, /*lease_ms=*/40);
        if (!lease) {
          if (store_->GetJob(id)->status == JobStatus::kSucceeded) return;
          std::this_thread::yield();
          continue;
        }
        if (rng() % 8 == 0) std::this_thread::sleep_for(std::chrono::microseconds(500));
        if (store_->CompleteTask(*lease, MakeRows(lease->index, kRows), clock++)) {
          completed[t].push_back(lease->index);
        } else {
          ++lost;
        }
      }
    });
  }
  for (std::thread& t : threads) t.join();

  std::multiset<int> all;
  for (const auto& c : completed) all.insert(c.begin(), c.end());
  EXPECT_EQ(all.size(), static_cast<size_t>(kTasks));
  for (int i = 0; i < kTasks; ++i) EXPECT_EQ(all.count(i), 1u) << "task " << i;
  EXPECT_EQ(store_->CountResults(id, "points"), kTasks * kRows);
  for (const auto& [idx, status_rows] : TaskRowCounts(path_, id)) {
    EXPECT_EQ(status_rows.first, "done");
    EXPECT_EQ(status_rows.second, kRows) << "task " << idx;
  }
  const JobRecord job = Job(id);
  EXPECT_EQ(job.status, JobStatus::kSucceeded);
  EXPECT_EQ(job.tasks_done, kTasks);
  std::printf("[          ] %d completions refused after a lease was taken over\n", lost.load());
}

TEST_F(StoreTest, ReopenedStoreResumesUnfinishedTasks) {
  const int64_t id = store_->SubmitJob("sweep", json{{"grid", "eq1"}}, MakeTasks(3, "k"), 0);
  const TaskLease a = store_->LeaseTask("w", 0, kLeaseMs).value();
  const TaskLease b = store_->LeaseTask("w", 0, kLeaseMs).value();
  ASSERT_TRUE(store_->CompleteTask(a, MakeRows(0, 4), 10));
  Reopen();

  JobRecord job = Job(id);
  EXPECT_EQ(job.status, JobStatus::kRunning);
  EXPECT_EQ(job.tasks_done, 1);
  EXPECT_EQ(job.spec, (json{{"grid", "eq1"}}));
  EXPECT_EQ(store_->CountResults(id, "points"), 4);
  // Before b's lease expires only the never-leased task is available; afterwards b's too.
  const TaskLease c = store_->LeaseTask("w2", 20, kLeaseMs).value();
  EXPECT_EQ(c.index, 2);
  EXPECT_FALSE(store_->LeaseTask("w2", 20, kLeaseMs).has_value());
  const TaskLease b2 = store_->LeaseTask("w2", kLeaseMs, kLeaseMs).value();
  EXPECT_EQ(b2.index, 1);
  EXPECT_FALSE(store_->CompleteTask(b, MakeRows(1, 4), kLeaseMs + 1));
  ASSERT_TRUE(store_->CompleteTask(b2, MakeRows(1, 4), kLeaseMs + 1));
  ASSERT_TRUE(store_->CompleteTask(c, MakeRows(2, 4), kLeaseMs + 1));
  Reopen();
  EXPECT_EQ(Job(id).status, JobStatus::kSucceeded);
  EXPECT_EQ(store_->CountResults(id, "points"), 12);
}

// A worker process killed with SIGKILL while it writes results, several times over: the file opens
// cleanly, passes integrity_check, and every task has all of its rows or none; the job then
// finishes with the exact row count.
TEST_F(StoreTest, SigkilledWriterLeavesNoPartialTask) {
  constexpr int kTasks = 200, kRows = 200, kRounds = 4;
  constexpr int64_t kRoundMs = 1'000'000'000;  // each round's clock starts after all earlier leases expired
  const int64_t id = store_->SubmitJob("sweep", json::object(), MakeTasks(kTasks, "k"), 0);
  store_.reset();  // a connection must not cross fork()

  int killed = 0;
  for (int round = 0; round < kRounds; ++round) {
    int ready[2];
    ASSERT_EQ(pipe(ready), 0);
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      close(ready[0]);
      try {
        std::unique_ptr<Store> store = Store::Open(path_);
        int64_t now = (round + 1) * kRoundMs;
        for (bool first = true;; first = false) {
          std::optional<TaskLease> lease = store->LeaseTask("child", ++now, kRoundMs / 2);
          if (!lease) _exit(0);
          if (!store->CompleteTask(*lease, MakeRows(lease->index, kRows), ++now)) _exit(3);
          if (first && write(ready[1], "x", 1) != 1) _exit(4);
        }
      } catch (...) {
        _exit(5);
      }
    }
    close(ready[1]);
    char byte = 0;
    const bool started = read(ready[0], &byte, 1) == 1;  // the child has committed one task
    close(ready[0]);
    std::this_thread::sleep_for(std::chrono::milliseconds(3 + 7 * round));
    kill(pid, SIGKILL);
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    if (WIFSIGNALED(status)) {
      EXPECT_EQ(WTERMSIG(status), SIGKILL);
      ++killed;
    } else {
      EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "child status " << status;
    }
    EXPECT_TRUE(started || round > 0);

    EXPECT_EQ(IntegrityCheck(path_), "ok") << "round " << round;
    int64_t done = 0;
    for (const auto& [idx, status_rows] : TaskRowCounts(path_, id)) {
      const bool is_done = status_rows.first == "done";
      done += is_done;
      EXPECT_EQ(status_rows.second, is_done ? kRows : 0) << "round " << round << ", task " << idx << " ("
                                                         << status_rows.first << ")";
    }
    EXPECT_EQ(QueryInt(path_, "SELECT tasks_done FROM jobs WHERE id = " + std::to_string(id)), done);
    std::printf("[          ] round %d: %s, %lld of %d tasks done\n", round, WIFSIGNALED(status) ? "killed" : "finished",
                static_cast<long long>(done), kTasks);
  }
  EXPECT_GE(killed, 1) << "the children all finished before they could be killed";

  // Resume: everything left (queued, or leased by a dead child) is leasable once leases expire.
  store_ = Store::Open(path_);
  const int64_t now = (kRounds + 1) * kRoundMs;
  while (std::optional<TaskLease> lease = store_->LeaseTask("parent", now, kLeaseMs)) {
    ASSERT_TRUE(store_->CompleteTask(*lease, MakeRows(lease->index, kRows), now));
  }
  const JobRecord job = Job(id);
  EXPECT_EQ(job.status, JobStatus::kSucceeded);
  EXPECT_EQ(job.tasks_done, kTasks);
  EXPECT_EQ(store_->CountResults(id, "points"), int64_t{kTasks} * kRows);
}

// A full disk (here: a file-size limit in a child process) makes the write that hits it throw,
// naming the file and SQLite's reason; the transaction is rolled back and the file stays sound.
TEST_F(StoreTest, FullDiskThrowsAndLeavesTheFileSound) {
  store_.reset();
  int report[2];
  ASSERT_EQ(pipe(report), 0);
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    close(report[0]);
    signal(SIGXFSZ, SIG_IGN);  // writes past the limit fail with EFBIG instead of killing the process
    int64_t submitted = 0;
    std::string message = "no error";
    try {
      std::unique_ptr<Store> store = Store::Open(path_);
      const rlimit limit{2 << 20, 2 << 20};  // 2 MiB per file [bytes]
      if (setrlimit(RLIMIT_FSIZE, &limit) != 0) _exit(6);
      const json big = {{"padding", std::string(100000, 'x')}};
      for (; submitted < 1000; ++submitted) store->SubmitJob("sweep", big, MakeTasks(10, "t"), 0);
    } catch (const std::runtime_error& e) {
      message = e.what();
    }
    message = std::to_string(submitted) + "\n" + message;
    _exit(write(report[1], message.data(), message.size()) == static_cast<ssize_t>(message.size()) ? 0 : 7);
  }
  close(report[1]);
  std::string message;
  char buffer[512];
  for (ssize_t n; (n = read(report[0], buffer, sizeof buffer)) > 0;) message.append(buffer, static_cast<size_t>(n));
  close(report[0]);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "child status " << status;

  const int64_t submitted = std::stoll(message.substr(0, message.find('\n')));
  message = message.substr(message.find('\n') + 1);
  EXPECT_GT(submitted, 0);
  EXPECT_LT(submitted, 1000) << "the limit was never hit";
  EXPECT_EQ(message.rfind("database " + path_ + ": ", 0), 0u) << message;
  EXPECT_TRUE(message.find("database or disk is full") != std::string::npos ||
              message.find("disk I/O error") != std::string::npos)
      << message;
  std::printf("[          ] after %lld jobs: %s\n", static_cast<long long>(submitted), message.c_str());

  EXPECT_EQ(IntegrityCheck(path_), "ok");
  store_ = Store::Open(path_);
  EXPECT_EQ(store_->ListJobs(2000, 0).size(), static_cast<size_t>(submitted)) << "the failed submission left nothing";
  EXPECT_EQ(QueryInt(path_, "SELECT count(*) FROM tasks"), submitted * 10);
}

TEST_F(StoreTest, FreshDatabaseHasTheLatestSchema) {
  const int latest = internal::Migrations().back().version;
  EXPECT_EQ(store_->SchemaVersion(), latest);
  EXPECT_EQ(QueryInt(path_, "PRAGMA user_version"), latest);
  EXPECT_EQ(QueryInt(path_, "SELECT count(*) FROM sqlite_schema WHERE type = 'table' AND name IN "
                            "('jobs', 'tasks', 'results', 'cache')"),
            4);
  // Migrations are numbered 1, 2, ... without gaps (the CMake embedding checks it too).
  for (size_t i = 0; i < internal::Migrations().size(); ++i) EXPECT_EQ(internal::Migrations()[i].version, int(i) + 1);
  Reopen();  // re-opening an up-to-date file changes nothing
  EXPECT_EQ(store_->SchemaVersion(), latest);
  EXPECT_EQ(QueryText(path_, "PRAGMA journal_mode"), "wal");
}

TEST_F(StoreTest, NewerSchemaIsRefusedWithAClearMessage) {
  store_.reset();
  const int newer = internal::Migrations().back().version + 1;
  QueryInt(path_, "PRAGMA user_version = " + std::to_string(newer));
  try {
    Store::Open(path_);
    FAIL() << "opened a database of a newer schema";
  } catch (const std::runtime_error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(path_), std::string::npos) << message;
    EXPECT_NE(message.find("schema version " + std::to_string(newer) + " is newer than this strokelab knows"),
              std::string::npos)
        << message;
  }
}

TEST_F(StoreTest, NonDatabaseFileIsRefusedNamingTheFile) {
  const std::string garbage = (dir_ / "garbage.db").string();
  {
    std::ofstream out(garbage, std::ios::binary);
    std::mt19937 rng(42);
    for (int i = 0; i < 8192; ++i) out.put(static_cast<char>(rng()));
  }
  try {
    Store::Open(garbage);
    FAIL() << "opened garbage";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "cannot open database " + garbage + ": file is not a database");
  }

  const std::string nowhere = (dir_ / "missing" / "dir" / "jobs.db").string();
  try {
    Store::Open(nowhere);
    FAIL() << "opened a file in a missing directory";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()),
              "cannot open database " + nowhere + ": unable to open database file: No such file or directory");
  }

  if (geteuid() != 0) {  // root writes anyway
    store_.reset();
    ASSERT_EQ(chmod(path_.c_str(), 0444), 0);
    try {
      Store::Open(path_);
      FAIL() << "opened a read-only file for writing";
    } catch (const std::runtime_error& e) {
      EXPECT_EQ(std::string(e.what()), "cannot open database " + path_ + ": the file is read-only");
    }
    chmod(path_.c_str(), 0644);
  }
}

}  // namespace
}  // namespace strokelab::server
