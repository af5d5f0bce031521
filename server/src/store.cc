// The job store and task queue on SQLite (see store.h; schema in schema/migrations/): the store
// opened, with its integrity checked and its migrations applied. The store's jobs, tasks and results
// are store_jobs.cc, store_tasks.cc, store_results.cc (the class: store_internal.h); its connections,
// their statements and errors, store_connection.cc.
//
// Writes go through one connection under a mutex: SQLite allows one writer at a time anyway, and
// every write here is a short transaction, so HTTP threads and worker threads wait on the mutex
// rather than on SQLite's file locks. Every write that reads before it writes (lease, complete,
// fail, cancel, submit) runs in BEGIN IMMEDIATE, which takes the write lock at the start, so a
// second process on the same file cannot interleave (it waits up to kBusyTimeoutMs). Reads go
// through a pool of read-only connections (store_connection.h): in WAL mode they see the last
// commit and run beside the writer, so a status read never waits behind a completion.
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

// Read-only connections at most: one per HTTP thread (ServiceOptions::http_threads, 8) serving
// reads at once; a ninth read waits for one of them.
constexpr int kMaxReaders = 8;

}  // namespace

SqliteStore::SqliteStore(const std::string& path)
    : writer_(path, Connection::Mode::kReadWrite), readers_(path, kMaxReaders) {
  OpenAndMigrate();
}

int SqliteStore::SchemaVersion() {
  ReaderPool::Handle reader = readers_.Acquire();
  return UserVersion(*reader);
}

void SqliteStore::OpenAndMigrate() {
  if (sqlite3_db_readonly(writer_.db(), "main") == 1) {
    throw std::runtime_error("cannot open database " + writer_.path() + ": the file is read-only");
  }
  // The first statement reads the file header: this is where a non-database file is detected.
  std::string mode;
  if (sqlite3_exec(writer_.db(), "PRAGMA journal_mode = WAL", &ReadFirstColumn, &mode, nullptr) != SQLITE_OK) {
    writer_.OpenFailed(sqlite3_extended_errcode(writer_.db()));
  }
  if (mode != "wal" && mode != "memory") {
    throw std::runtime_error("cannot open database " + writer_.path() + ": WAL mode is not available there (journal mode '" +
                             mode + "'; a network file system?)");
  }
  // The writer's page cache: SQLite's default 2 MiB. Results are stored as blocks (row_block.h), whose
  // pages are written once and not read again by the writer; the B-trees it walks (tasks, jobs, the
  // blocks' keys) are small. (Schema 5's per-row result tables needed 16 MiB to keep their index
  // pages in memory, and a cache that large grows RSS with every sweep stored.)
  for (const char* pragma : {"PRAGMA synchronous = NORMAL", "PRAGMA foreign_keys = ON", "PRAGMA cache_size = -2048"}) {
    if (sqlite3_exec(writer_.db(), pragma, nullptr, nullptr, nullptr) != SQLITE_OK)
      writer_.OpenFailed(sqlite3_extended_errcode(writer_.db()));
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
  if (sqlite3_exec(writer_.db(), "PRAGMA quick_check(1)", &ReadFirstColumn, &result, &error) != SQLITE_OK) {
    sqlite3_free(error);
    writer_.OpenFailed(sqlite3_extended_errcode(writer_.db()));
  }
  if (result != "ok") {
    throw std::runtime_error("cannot open database " + writer_.path() + ": the file is damaged (" + result +
                             "); restore it from a backup");
  }
}

// Applies every migration newer than the file's user_version, each in its own transaction
// together with the new user_version, so a crash leaves the file at one version or the next.
void SqliteStore::Migrate() {
  const std::span<const internal::Migration> migrations = internal::Migrations();
  const int latest = migrations.empty() ? 0 : migrations.back().version;
  const int found = UserVersion(writer_);
  if (found > latest) {
    throw std::runtime_error("cannot open database " + writer_.path() + ": its schema version " + std::to_string(found) +
                             " is newer than this strokelab knows (up to " + std::to_string(latest) +
                             "); use a newer strokelab, or another database file");
  }
  for (const internal::Migration& m : migrations) {
    if (m.version <= found) continue;
    Transaction tx(*this);
    if (UserVersion(writer_) >= m.version) continue;  // another process got there first
    char* error = nullptr;
    if (sqlite3_exec(writer_.db(), m.sql, nullptr, nullptr, &error) != SQLITE_OK) {
      const std::string what = error ? error : sqlite3_errmsg(writer_.db());
      sqlite3_free(error);
      throw std::runtime_error("cannot open database " + writer_.path() + ": migration " + m.name + " failed: " + what);
    }
    if (m.version == 6) MoveResultRowsIntoBlocks();  // the one migration SQL alone cannot do
    writer_.Exec(("PRAGMA user_version = " + std::to_string(m.version)).c_str());
    tx.Commit();
  }
}

int SqliteStore::UserVersion(Connection& c) {
  Stmt s = c.Prepare("PRAGMA user_version");
  s.Step();
  return static_cast<int>(s.ColInt(0));
}

int SqliteStore::ReadFirstColumn(void* out, int columns, char** values, char**) {
  if (columns > 0 && values[0]) *static_cast<std::string*>(out) = values[0];
  return 0;
}

}  // namespace internal

std::unique_ptr<Store> Store::Open(const std::string& path) { return std::make_unique<internal::SqliteStore>(path); }

}  // namespace strokelab::server
