// What the job store's tests share: tasks and result rows to submit, queries on a raw SQLite
// connection (what another tool would see), and StoreTest, a fixture with a fresh store file per test.
#pragma once

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <stdlib.h>

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "strokelab/server/store.h"

namespace strokelab::server::store_test {

using nlohmann::json;
namespace fs = std::filesystem;

inline constexpr int64_t kLeaseMs = 1000;

inline std::vector<TaskSpec> MakeTasks(int n, const std::string& key_prefix) {
  std::vector<TaskSpec> tasks;
  for (int i = 0; i < n; ++i) tasks.push_back({key_prefix + std::to_string(i), json{{"chunk", i}}});
  return tasks;
}

// Rows of task `task`: "points" rows on a grid of frequency (5 + row Hz) at one amplitude per task
// (0.1, 0.2 or 0.3 V), alternating branches.
inline std::vector<ResultRow> MakeRows(int task, int count) {
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
inline std::string QueryText(const std::string& path, const std::string& sql) {
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
inline int64_t QueryInt(const std::string& path, const std::string& sql) {
  const std::string text = QueryText(path, sql);
  return text.empty() ? -1 : std::stoll(text);
}

// Per task of `job`: (status, number of result rows in its blocks), over a raw connection.
inline std::map<int, std::pair<std::string, int64_t>> TaskRowCounts(const std::string& path, int64_t job) {
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr), SQLITE_OK);
  const std::string sql =
      "SELECT t.idx, t.status, "
      "(SELECT coalesce(sum(rows), 0) FROM result_blocks r WHERE r.job_id = t.job_id AND r.task_idx = t.idx) "
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

inline std::string IntegrityCheck(const std::string& path) {
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


}  // namespace strokelab::server::store_test
