// A plain SQLite connection for tests that look at a job store from outside the Store class (as
// another tool would): to build old schema versions by hand, and to check backups and migrations.
#pragma once

#include <sqlite3.h>

#include <stdexcept>
#include <string>
#include <vector>

namespace strokelab::testing {

class RawDb {
 public:
  explicit RawDb(const std::string& path, int flags = SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE) : path_(path) {
    if (sqlite3_open_v2(path.c_str(), &db_, flags, nullptr) != SQLITE_OK) {
      const std::string error = db_ ? sqlite3_errmsg(db_) : "out of memory";
      sqlite3_close(db_);
      throw std::runtime_error("cannot open " + path + ": " + error);
    }
    sqlite3_busy_timeout(db_, 5000);
  }
  ~RawDb() { sqlite3_close_v2(db_); }
  RawDb(const RawDb&) = delete;
  RawDb& operator=(const RawDb&) = delete;

  // Runs one or more statements; throws with SQLite's message.
  void Exec(const std::string& sql) {
    char* error = nullptr;
    if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error) != SQLITE_OK) {
      const std::string what = error ? error : "?";
      sqlite3_free(error);
      throw std::runtime_error(path_ + ": " + what + " (in: " + sql.substr(0, 80) + ")");
    }
  }

  // Every row, its columns joined by '|' (NULL as "NULL").
  std::vector<std::string> Rows(const std::string& sql) {
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &stmt, nullptr) != SQLITE_OK)
      throw std::runtime_error(path_ + ": " + sqlite3_errmsg(db_) + " (in: " + sql + ")");
    std::vector<std::string> rows;
    int rc;
    while ((rc = sqlite3_step(stmt)) == SQLITE_ROW) {
      std::string row;
      for (int c = 0; c < sqlite3_column_count(stmt); ++c) {
        const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(stmt, c));
        row += (c ? "|" : "") + std::string(text ? text : "NULL");
      }
      rows.push_back(std::move(row));
    }
    sqlite3_finalize(stmt);
    if (rc != SQLITE_DONE) throw std::runtime_error(path_ + ": " + sqlite3_errmsg(db_) + " (in: " + sql + ")");
    return rows;
  }
  // The first row ("" when there is none).
  std::string Text(const std::string& sql) {
    const std::vector<std::string> rows = Rows(sql);
    return rows.empty() ? "" : rows.front();
  }
  int64_t Int(const std::string& sql) { return std::stoll(Text(sql)); }

 private:
  std::string path_;
  sqlite3* db_ = nullptr;
};

}  // namespace strokelab::testing
