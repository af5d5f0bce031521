// One SQLite connection of the store with its cached prepared statements and its errors, and the
// pool of read-only connections that serves the store's reads (store_connection.cc). Internal to
// the store.
//
// Why a pool: in WAL mode one writer and any number of readers run at once; each reader sees the
// last transaction committed when its statement (or BEGIN) started and never waits for the writer.
// The store writes through one connection under its write mutex and reads through these, so a
// status read does not wait behind a task's completion.
#pragma once

#include <sqlite3.h>

#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace strokelab::server::internal {

inline constexpr int kBusyTimeoutMs = 5000;  // how long a write waits for another process's lock [ms]

class Connection;

// A cached prepared statement in use: binds (1-based, chainable), steps, and resets on scope exit
// (a statement left unreset would hold its read snapshot).
class Stmt {
 public:
  Stmt(Connection& connection, sqlite3_stmt* stmt) : connection_(connection), stmt_(stmt) {}
  ~Stmt() { Reset(); }
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;

  Stmt& Int(int i, int64_t v) { return Bound(sqlite3_bind_int64(stmt_, i, v)); }
  Stmt& Double(int i, double v) { return Bound(sqlite3_bind_double(stmt_, i, v)); }
  Stmt& Text(int i, std::string_view v) {
    return Bound(sqlite3_bind_text64(stmt_, i, v.data(), v.size(), SQLITE_TRANSIENT, SQLITE_UTF8));
  }
  // Text that outlives the statement's next Step (not copied).
  Stmt& StaticText(int i, std::string_view v) {
    return Bound(sqlite3_bind_text64(stmt_, i, v.data(), v.size(), SQLITE_STATIC, SQLITE_UTF8));
  }
  // Bytes that outlive the statement's next Step (not copied).
  Stmt& StaticBlob(int i, std::string_view v) {
    return Bound(sqlite3_bind_blob64(stmt_, i, v.data(), v.size(), SQLITE_STATIC));
  }
  Stmt& Null(int i) { return Bound(sqlite3_bind_null(stmt_, i)); }
  Stmt& OptDouble(int i, const std::optional<double>& v) { return v ? Double(i, *v) : Null(i); }
  Stmt& OptStaticText(int i, const std::optional<std::string>& v) { return v ? StaticText(i, *v) : Null(i); }

  // True when a row is available, false when done; throws StoreError on an error.
  bool Step();
  void Run() {
    while (Step()) {
    }
  }
  // Ready to bind and run again (bindings cleared).
  void Reset() {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  int64_t ColInt(int c) { return sqlite3_column_int64(stmt_, c); }
  std::string ColText(int c) {
    const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(stmt_, c));
    return p ? std::string(p, static_cast<size_t>(sqlite3_column_bytes(stmt_, c))) : std::string();
  }
  // Valid until the next Step or Reset.
  std::string_view ColBlob(int c) {
    const auto* p = static_cast<const char*>(sqlite3_column_blob(stmt_, c));
    return p ? std::string_view(p, static_cast<size_t>(sqlite3_column_bytes(stmt_, c))) : std::string_view();
  }

 private:
  Stmt& Bound(int rc);
  Connection& connection_;
  sqlite3_stmt* stmt_;
};

class Connection {
 public:
  enum class Mode { kReadWrite, kReadOnly };
  // Opens `path` (read-write creates it) with extended result codes and the busy timeout; throws
  // std::runtime_error naming the file when it cannot be opened.
  Connection(std::string path, Mode mode);
  ~Connection();
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  // The statement for `sql`, prepared once per connection.
  Stmt Prepare(const std::string& sql);
  void Exec(const char* sql);
  // Throws StoreError naming the file, SQLite's message with a hint, and the statement.
  [[noreturn]] void Fail(int rc, const char* sql);
  // Throws std::runtime_error "cannot open database FILE: ..." (errors while opening).
  [[noreturn]] void OpenFailed(int rc);
  std::string Describe(int rc);

  sqlite3* db() { return db_; }
  const std::string& path() const { return path_; }
  int Changes() { return sqlite3_changes(db_); }
  int64_t LastInsertRowid() { return sqlite3_last_insert_rowid(db_); }

 private:
  std::string path_;
  sqlite3* db_ = nullptr;
  std::unordered_map<std::string, sqlite3_stmt*> statements_;
};

// BEGIN (a read snapshot for several statements) on a reader; ended on scope exit.
class ReadSnapshot {
 public:
  explicit ReadSnapshot(Connection& c) : connection_(c) { connection_.Exec("BEGIN"); }
  ~ReadSnapshot() {
    if (!sqlite3_get_autocommit(connection_.db())) sqlite3_exec(connection_.db(), "COMMIT", nullptr, nullptr, nullptr);
  }
  ReadSnapshot(const ReadSnapshot&) = delete;
  ReadSnapshot& operator=(const ReadSnapshot&) = delete;

 private:
  Connection& connection_;
};

// Read-only connections, opened when first needed (at most `max_open`) and handed to one thread at
// a time: a thread that finds all of them busy waits for one.
class ReaderPool {
 public:
  ReaderPool(std::string path, int max_open) : path_(std::move(path)), max_open_(max_open) {}
  ReaderPool(const ReaderPool&) = delete;
  ReaderPool& operator=(const ReaderPool&) = delete;

  class Handle {
   public:
    Handle(ReaderPool& pool, std::unique_ptr<Connection> c) : pool_(pool), connection_(std::move(c)) {}
    ~Handle() { pool_.Return(std::move(connection_)); }
    Handle(const Handle&) = delete;
    Handle& operator=(const Handle&) = delete;
    Connection& operator*() { return *connection_; }
    Connection* operator->() { return connection_.get(); }

   private:
    ReaderPool& pool_;
    std::unique_ptr<Connection> connection_;
  };

  // A reader for this thread; throws StoreError when a new one cannot be opened.
  Handle Acquire();

 private:
  void Return(std::unique_ptr<Connection> c);

  const std::string path_;
  const int max_open_;
  std::mutex mu_;
  std::condition_variable returned_;
  std::vector<std::unique_ptr<Connection>> idle_;  // guarded by mu_
  int open_ = 0;                                   // guarded by mu_: idle and handed out
};

}  // namespace strokelab::server::internal
