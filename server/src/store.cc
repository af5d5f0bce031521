// The job store and task queue on SQLite (see store.h; schema in schema/migrations/): the connection,
// opened with its integrity checked and its migrations applied, its prepared statements and its
// errors. The store's jobs, tasks and results are store_jobs.cc, store_tasks.cc, store_results.cc
// (the class: store_internal.h).
//
// One connection per Store, serialised by a mutex: SQLite allows one writer at a time anyway, and
// every write here is a short transaction, so HTTP threads and worker threads sharing the Store
// wait on the mutex rather than on SQLite's file locks. Every write that reads before it writes
// (lease, complete, fail, cancel, submit) runs in BEGIN IMMEDIATE, which takes the write lock at the
// start, so a second process on the same file cannot interleave (it waits up to kBusyTimeoutMs).
//
// Durability: WAL with synchronous=NORMAL. A committed transaction is in the WAL file before
// COMMIT returns, so a process killed at any moment (SIGKILL, crash) loses nothing committed and
// leaves no partial transaction: the next Open ignores uncommitted WAL frames. The WAL is fsynced
// only at checkpoints, so a power cut or OS crash can lose the last few transactions (those leases
// and results are then redone), but it never corrupts the database.
#include "strokelab/server/store.h"

#include <sqlite3.h>

#include <cstring>
#include <memory>
#include <mutex>
#include <span>
#include <stdexcept>
#include <string>

#include "migrations.h"
#include "store_internal.h"

namespace strokelab::server {
namespace internal {
namespace {

constexpr int kBusyTimeoutMs = 5000;  // how long a write waits for another process's lock [ms]

}  // namespace

SqliteStore::SqliteStore(const std::string& path) : path_(path) {
  try {
    OpenAndMigrate();
  } catch (...) {
    Close();
    throw;
  }
}

SqliteStore::~SqliteStore() { Close(); }

int SqliteStore::SchemaVersion() {
  std::lock_guard lock(mu_);
  return UserVersion();
}

SqliteStore::Stmt SqliteStore::Prepare(const std::string& sql) {
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

void SqliteStore::Exec(const char* sql) {
  const int rc = sqlite3_exec(db_, sql, nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) Fail(rc, sql);
}

void SqliteStore::Fail(int rc, const char* sql) {
  std::string sql_head(sql ? sql : "");
  if (sql_head.size() > 60) sql_head = sql_head.substr(0, 57) + "...";
  throw StoreError("database " + path_ + ": " + Describe(rc) + " (in: " + sql_head + ")");
}

// The error of the last call on db_, with a hint for the usual operational causes.
std::string SqliteStore::Describe(int rc) {
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

void SqliteStore::OpenAndMigrate() {
  const int flags = SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX;  // mu_ serialises
  const int rc = sqlite3_open_v2(path_.c_str(), &db_, flags, nullptr);
  if (rc != SQLITE_OK) OpenFailed(rc);
  sqlite3_extended_result_codes(db_, 1);
  sqlite3_busy_timeout(db_, kBusyTimeoutMs);
  if (sqlite3_db_readonly(db_, "main") == 1) {
    throw std::runtime_error("cannot open database " + path_ + ": the file is read-only");
  }
  // The first statement reads the file header: this is where a non-database file is detected.
  std::string mode;
  if (sqlite3_exec(db_, "PRAGMA journal_mode = WAL", &ReadFirstColumn, &mode, nullptr) != SQLITE_OK) {
    OpenFailed(sqlite3_extended_errcode(db_));
  }
  if (mode != "wal" && mode != "memory") {
    throw std::runtime_error("cannot open database " + path_ + ": WAL mode is not available there (journal mode '" +
                             mode + "'; a network file system?)");
  }
  for (const char* pragma : {"PRAGMA synchronous = NORMAL", "PRAGMA foreign_keys = ON"}) {
    if (sqlite3_exec(db_, pragma, nullptr, nullptr, nullptr) != SQLITE_OK) OpenFailed(sqlite3_extended_errcode(db_));
  }
  CheckIntegrity();
  Migrate();
}

// A file damaged inside its pages (not in the header) opens without complaint and fails later, on
// whichever query reads the bad page, possibly after the service has taken work: check every page
// once at open (PRAGMA quick_check: every page's structure, not the row contents) and refuse to
// start. It reads the whole file: 7 s (warm cache) to 21 s (cold) for a 1 GB file on a busy machine.
void SqliteStore::CheckIntegrity() {
  std::string result;
  char* error = nullptr;
  if (sqlite3_exec(db_, "PRAGMA quick_check(1)", &ReadFirstColumn, &result, &error) != SQLITE_OK) {
    sqlite3_free(error);
    OpenFailed(sqlite3_extended_errcode(db_));
  }
  if (result != "ok") {
    throw std::runtime_error("cannot open database " + path_ + ": the file is damaged (" + result +
                             "); restore it from a backup");
  }
}

// Applies every migration newer than the file's user_version, each in its own transaction
// together with the new user_version, so a crash leaves the file at one version or the next.
void SqliteStore::Migrate() {
  const std::span<const internal::Migration> migrations = internal::Migrations();
  const int latest = migrations.empty() ? 0 : migrations.back().version;
  const int found = UserVersion();
  if (found > latest) {
    throw std::runtime_error("cannot open database " + path_ + ": its schema version " + std::to_string(found) +
                             " is newer than this strokelab knows (up to " + std::to_string(latest) +
                             "); use a newer strokelab, or another database file");
  }
  for (const internal::Migration& m : migrations) {
    if (m.version <= found) continue;
    Transaction tx(*this);
    if (UserVersion() >= m.version) continue;  // another process got there first
    char* error = nullptr;
    if (sqlite3_exec(db_, m.sql, nullptr, nullptr, &error) != SQLITE_OK) {
      const std::string what = error ? error : sqlite3_errmsg(db_);
      sqlite3_free(error);
      throw std::runtime_error("cannot open database " + path_ + ": migration " + m.name + " failed: " + what);
    }
    Exec(("PRAGMA user_version = " + std::to_string(m.version)).c_str());
    tx.Commit();
  }
}

int SqliteStore::UserVersion() {
  Stmt s = Prepare("PRAGMA user_version");
  s.Step();
  return static_cast<int>(s.ColInt(0));
}

void SqliteStore::OpenFailed(int rc) {
  throw std::runtime_error("cannot open database " + path_ + ": " + Describe(rc));
}

int SqliteStore::ReadFirstColumn(void* out, int columns, char** values, char**) {
  if (columns > 0 && values[0]) *static_cast<std::string*>(out) = values[0];
  return 0;
}

void SqliteStore::Close() {
  for (auto& [sql, stmt] : statements_) sqlite3_finalize(stmt);
  statements_.clear();
  if (db_) sqlite3_close_v2(db_);
  db_ = nullptr;
}

}  // namespace internal

std::unique_ptr<Store> Store::Open(const std::string& path) { return std::make_unique<internal::SqliteStore>(path); }

}  // namespace strokelab::server
