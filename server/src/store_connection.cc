// The store's SQLite connections (store_connection.h): opening one, its statement cache, its errors
// with a hint for the usual operational causes, and the pool of read-only connections.
#include "store_connection.h"

#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>

#include "strokelab/server/store.h"

namespace strokelab::server::internal {

bool Stmt::Step() {
  const int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  connection_.Fail(rc, sqlite3_sql(stmt_));
}

Stmt& Stmt::Bound(int rc) {
  if (rc != SQLITE_OK) connection_.Fail(rc, sqlite3_sql(stmt_));
  return *this;
}

Connection::Connection(std::string path, Mode mode) : path_(std::move(path)) {
  // SQLITE_OPEN_NOMUTEX: a connection is used by one thread at a time (the store's write mutex, the
  // reader pool's hand-out).
  const int flags = mode == Mode::kReadOnly ? SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX
                                            : SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX;
  const int rc = sqlite3_open_v2(path_.c_str(), &db_, flags, nullptr);
  if (rc != SQLITE_OK) {
    try {
      OpenFailed(rc);
    } catch (...) {
      sqlite3_close_v2(db_);
      db_ = nullptr;
      throw;
    }
  }
  sqlite3_extended_result_codes(db_, 1);
  sqlite3_busy_timeout(db_, kBusyTimeoutMs);
}

Connection::~Connection() {
  for (auto& [sql, stmt] : statements_) sqlite3_finalize(stmt);
  if (db_) sqlite3_close_v2(db_);
}

Stmt Connection::Prepare(const std::string& sql) {
  auto it = statements_.find(sql);
  if (it == statements_.end()) {
    sqlite3_stmt* stmt = nullptr;
    const int rc = sqlite3_prepare_v3(db_, sql.c_str(), static_cast<int>(sql.size() + 1), SQLITE_PREPARE_PERSISTENT,
                                      &stmt, nullptr);
    if (rc != SQLITE_OK) Fail(rc, sql.c_str());
    it = statements_.emplace(sql, stmt).first;
  }
  return Stmt(*this, it->second);
}

void Connection::Exec(const char* sql) {
  const int rc = sqlite3_exec(db_, sql, nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) Fail(rc, sql);
}

void Connection::Fail(int rc, const char* sql) {
  std::string sql_head(sql ? sql : "");
  if (sql_head.size() > 60) sql_head = sql_head.substr(0, 57) + "...";
  throw StoreError("database " + path_ + ": " + Describe(rc) + " (in: " + sql_head + ")");
}

void Connection::OpenFailed(int rc) { throw std::runtime_error("cannot open database " + path_ + ": " + Describe(rc)); }

// The error of the last call on db_, with a hint for the usual operational causes.
std::string Connection::Describe(int rc) {
  std::string msg = db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
  switch (rc & 0xff) {
    case SQLITE_CANTOPEN:
    case SQLITE_PERM:
      if (const int e = db_ ? sqlite3_system_errno(db_) : 0; e != 0) msg += std::string(": ") + std::strerror(e);
      break;
    case SQLITE_IOERR:
      if (const int e = db_ ? sqlite3_system_errno(db_) : 0; e != 0) {
        msg += std::string(": ") + std::strerror(e);
      } else if (rc == SQLITE_IOERR_WRITE || rc == SQLITE_IOERR_FSYNC || rc == SQLITE_IOERR_TRUNCATE) {
        msg += " (writing failed: disk full, file size limit, or a storage fault)";
      }
      break;
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
      msg += " (another process holds a lock on it; waited " + std::to_string(kBusyTimeoutMs) + " ms)";
      break;
    case SQLITE_READONLY: msg += " (the file or its directory is not writable)"; break;
    case SQLITE_CORRUPT: msg += " (the file is damaged; restore it from a backup)"; break;
    default: break;
  }
  return msg;
}

ReaderPool::Handle ReaderPool::Acquire() {
  {
    std::unique_lock lock(mu_);
    returned_.wait(lock, [this] { return !idle_.empty() || open_ < max_open_; });
    if (!idle_.empty()) {
      std::unique_ptr<Connection> c = std::move(idle_.back());
      idle_.pop_back();
      return Handle(*this, std::move(c));
    }
    ++open_;  // opened below, outside the lock
  }
  try {
    return Handle(*this, std::make_unique<Connection>(path_, Connection::Mode::kReadOnly));
  } catch (const std::exception& e) {
    {
      std::lock_guard lock(mu_);
      --open_;
    }
    returned_.notify_one();
    throw StoreError(e.what());
  }
}

void ReaderPool::Return(std::unique_ptr<Connection> c) {
  {
    std::lock_guard lock(mu_);
    idle_.push_back(std::move(c));
  }
  returned_.notify_one();
}

}  // namespace strokelab::server::internal
