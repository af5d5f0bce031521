// A second SQLite connection on a server's database file, for tests that look at (or lock) it.
#pragma once

#include <sqlite3.h>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace strokelab::test_process {

namespace fs = std::filesystem;

// Read-only looks at the server's database file from the test (another connection; WAL allows it
// while the server writes). Never checkpoints on close, so a crashed server's file stays as it was.
class Db {
 public:
  explicit Db(const fs::path& path) {
    if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE, nullptr) != SQLITE_OK)
      throw std::runtime_error("cannot open " + path.string());
    sqlite3_busy_timeout(db_, 5000);
    sqlite3_db_config(db_, SQLITE_DBCONFIG_NO_CKPT_ON_CLOSE, 1, nullptr);
  }
  ~Db() { sqlite3_close_v2(db_); }
  Db(const Db&) = delete;
  Db& operator=(const Db&) = delete;
  // Rows of a query as text ("" for NULL).
  std::vector<std::vector<std::string>> Query(const std::string& sql) {
    std::vector<std::vector<std::string>> rows;
    char* error = nullptr;
    auto collect = [](void* out, int n, char** values, char**) {
      auto& r = *static_cast<std::vector<std::vector<std::string>>*>(out);
      r.emplace_back();
      for (int i = 0; i < n; ++i) r.back().push_back(values[i] ? values[i] : "");
      return 0;
    };
    if (sqlite3_exec(db_, sql.c_str(), collect, &rows, &error) != SQLITE_OK) {
      const std::string what = error ? error : "?";
      sqlite3_free(error);
      throw std::runtime_error("query failed: " + what + " in " + sql);
    }
    return rows;
  }
  std::string One(const std::string& sql) {
    const auto rows = Query(sql);
    return rows.empty() || rows[0].empty() ? "" : rows[0][0];
  }

 private:
  sqlite3* db_ = nullptr;
};

}  // namespace strokelab::test_process
