// The job store under stress: concurrent workers, persistence across close and SIGKILL, a full disk,
// and the migrations (schema versions, files that are not databases). Times are synthetic
// milliseconds passed to every call.
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
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "migrations.h"
#include "store_test_util.h"

namespace strokelab::server {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;
using store_test::IntegrityCheck;
using store_test::kLeaseMs;
using store_test::MakeRows;
using store_test::MakeTasks;
using store_test::QueryInt;
using store_test::QueryText;
using store_test::StoreTest;
using store_test::TaskRowCounts;

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

// Readers beside two writers: the reader pool's connections, handed from thread to thread, see
// only whole completions (a task's rows all or none, the job's counter no further than its rows),
// and progress never goes back. Under TSan this is also the pool's race check.
TEST_F(StoreTest, ReadersBesideWritersSeeWholeCompletions) {
  constexpr int kTasks = 60, kRows = 20, kWriters = 2, kReaders = 3;
  const int64_t id = store_->SubmitJob("sweep", json::object(), MakeTasks(kTasks, "k"), 0);
  std::atomic<bool> writers_done{false};
  std::atomic<int> reads{0};
  std::vector<std::thread> threads;
  for (int w = 0; w < kWriters; ++w) {
    threads.emplace_back([&, w] {
      while (std::optional<TaskLease> lease = store_->LeaseTask("w" + std::to_string(w), 1, kLeaseMs))
        EXPECT_TRUE(store_->CompleteTask(*lease, MakeRows(lease->index, kRows), 2));
    });
  }
  for (int r = 0; r < kReaders; ++r) {
    threads.emplace_back([&] {
      int64_t last_done = 0;
      for (bool last_round = false; !last_round;) {
        last_round = writers_done;
        const int64_t done_before = store_->GetJob(id)->tasks_done;
        const int64_t rows = store_->CountResults(id, "points");
        const Store::Page page = store_->Results(id, "points", {}, 0, kTasks * kRows);
        const int64_t done_after = store_->GetJob(id)->tasks_done;
        EXPECT_EQ(rows % kRows, 0) << "a task's rows seen in part";
        EXPECT_LE(done_before * kRows, rows);
        EXPECT_LE(rows, static_cast<int64_t>(page.rows.size()));
        EXPECT_LE(static_cast<int64_t>(page.rows.size()), done_after * kRows);
        EXPECT_GE(done_before, last_done) << "progress went back";
        last_done = done_after;
        ++reads;
      }
    });
  }
  for (int w = 0; w < kWriters; ++w) threads[w].join();
  writers_done = true;
  for (size_t t = kWriters; t < threads.size(); ++t) threads[t].join();
  EXPECT_EQ(Job(id).status, JobStatus::kSucceeded);
  EXPECT_EQ(store_->CountResults(id, "points"), kTasks * kRows);
  EXPECT_GE(reads.load(), kReaders);
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
                            "('jobs', 'tasks', 'job_events', 'result_blocks')"),
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
