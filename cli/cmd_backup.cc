// strokelab backup: a consistent copy of a job store while the service writes to it, with SQLite's
// online backup API (https://www.sqlite.org/backup.html).
//
// Why one step: sqlite3_backup_step(-1) copies every page inside one read transaction, so the copy
// is the database as of one commit: a job's result rows, its task states and its counters always
// agree. In WAL mode that read transaction does not block the server's writers (they append to the
// WAL; only checkpoints wait), so a running service slows down by the copy's I/O and no more.
// Stepping in chunks instead would restart from scratch whenever the server commits in between,
// which on a busy server may be never-ending.
//
// The copy goes to TO.partial, is switched to a self-contained file (journal mode DELETE: no -wal
// or -shm beside it), checked (PRAGMA integrity_check), flushed to disk and renamed to TO: TO is
// either a whole, checked backup or absent.
#include <fcntl.h>
#include <sqlite3.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

#include "commands.h"
#include "strokelab/base/errors.h"

namespace strokelab::cli {
namespace {

namespace fs = std::filesystem;

constexpr const char* kBackupHelp = R"(usage: strokelab backup --db FILE --to FILE [--force]

Copies the service's SQLite job store (strokelab serve --db FILE) to one self-contained file, safely
while the service runs: the copy is the database as of one instant (SQLite online backup API),
checked with PRAGMA integrity_check before it is renamed into place. Restore by stopping the
service and copying the backup over its --db file (removing FILE-wal and FILE-shm).

  --db FILE     the job store to copy                                  (required)
  --to FILE     the backup to write (its folder is created); refused if it exists (required)
  --force       overwrite --to if it exists

Exit codes: 0 written, 2 bad input (a flag, no such database, not a job store, --to exists),
1 failure (I/O, disk full, the copy failed its integrity check).
)";

constexpr int kBusyTimeoutMs = 5000;  // waiting for another process's lock [ms]
constexpr int kBusyRetries = 50;      // backup steps retried while the source is locked

using Db = std::unique_ptr<sqlite3, int (*)(sqlite3*)>;

Db Open(const fs::path& path, int flags, const std::string& flag) {
  sqlite3* raw = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &raw, flags, nullptr);
  Db db(raw, &sqlite3_close_v2);
  if (rc != SQLITE_OK)
    throw InputError(flag, "cannot open " + path.string() + ": " + (raw ? sqlite3_errmsg(raw) : sqlite3_errstr(rc)));
  sqlite3_busy_timeout(db.get(), kBusyTimeoutMs);
  return db;
}

// The rows of a one-column query as text; throws naming the database on an error.
std::vector<std::string> Query(sqlite3* db, const std::string& sql, const fs::path& path) {
  sqlite3_stmt* stmt = nullptr;
  std::vector<std::string> rows;
  int rc = sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt, nullptr);
  while (rc == SQLITE_OK && (rc = sqlite3_step(stmt)) == SQLITE_ROW) {
    const auto* text = reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0));
    rows.emplace_back(text ? text : "");
    rc = SQLITE_OK;
  }
  sqlite3_finalize(stmt);
  if (rc != SQLITE_DONE)
    throw std::runtime_error("database " + path.string() + ": " + sqlite3_errmsg(db) + " (in: " + sql + ")");
  return rows;
}

std::string QueryOne(sqlite3* db, const std::string& sql, const fs::path& path) {
  const std::vector<std::string> rows = Query(db, sql, path);
  return rows.empty() ? "" : rows.front();
}

// fsync of a file or directory, so that the rename below cannot survive a power cut without the data.
void Sync(const fs::path& path, bool directory) {
  const int fd = ::open(path.c_str(), directory ? O_RDONLY | O_DIRECTORY : O_RDONLY);
  if (fd < 0) throw std::system_error(errno, std::generic_category(), "cannot open " + path.string());
  const int rc = ::fsync(fd);
  const int error = errno;
  ::close(fd);
  if (rc != 0 && !directory) throw std::system_error(error, std::generic_category(), "fsync " + path.string());
}

// Copies every page of `source` to `dest` in one read transaction (see the top of the file).
void CopyPages(sqlite3* source, sqlite3* dest, const fs::path& source_path) {
  sqlite3_backup* backup = sqlite3_backup_init(dest, "main", source, "main");
  if (!backup) throw std::runtime_error(std::string("cannot start the backup: ") + sqlite3_errmsg(dest));
  int rc = SQLITE_OK;
  for (int attempt = 0; attempt < kBusyRetries; ++attempt) {
    rc = sqlite3_backup_step(backup, -1);
    if (rc != SQLITE_BUSY && rc != SQLITE_LOCKED) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  sqlite3_backup_finish(backup);
  if (rc != SQLITE_DONE)
    throw std::runtime_error("backup of " + source_path.string() + " failed: " + sqlite3_errstr(rc) +
                             (rc == SQLITE_BUSY || rc == SQLITE_LOCKED ? " (still locked after retries)" : ""));
}

}  // namespace

int RunBackup(const std::vector<std::string>& argv) {
  const Args args(argv, {"--db", "--to"}, {"--force", "--help"});
  if (args.Has("--help")) {
    std::cout << kBackupHelp;
    return 0;
  }
  if (!args.Positional().empty()) throw InputError(args.Positional().front(), "unexpected argument (see --help)");
  const auto db_flag = args.Get("--db");
  const auto to_flag = args.Get("--to");
  if (!db_flag) throw InputError("--db", "required: the job store to copy");
  if (!to_flag) throw InputError("--to", "required: the backup file to write");
  const fs::path db_path = *db_flag, to = *to_flag;
  std::error_code ec;
  if (!fs::is_regular_file(db_path, ec)) throw InputError("--db", db_path.string() + ": no such database file");
  if (fs::exists(to, ec) && fs::equivalent(db_path, to, ec)) throw InputError("--to", "is the database itself");
  if (fs::exists(to, ec) && !args.Has("--force"))
    throw InputError("--to", to.string() + " exists (--force overwrites it)");

  // Read-write without create: a WAL reader must be able to use the -shm file; nothing is written.
  Db source = Open(db_path, SQLITE_OPEN_READWRITE, "--db");
  const std::string version = [&] {
    try {
      return QueryOne(source.get(), "PRAGMA user_version", db_path);
    } catch (const std::runtime_error&) {  // "file is not a database", read at the first statement
      throw InputError("--db", db_path.string() + ": " + sqlite3_errmsg(source.get()));
    }
  }();
  if (version == "0" ||
      QueryOne(source.get(), "SELECT count(*) FROM sqlite_schema WHERE type = 'table' AND name = 'jobs'", db_path) == "0")
    throw InputError("--db", db_path.string() + ": not a strokelab job store (schema version " + version +
                                 ", no jobs table)");

  // The README's `--to backups/strokelab-DATE.db` names a folder that need not exist yet.
  if (const fs::path parent = to.parent_path(); !parent.empty()) {
    fs::create_directories(parent, ec);
    if (ec) throw InputError("--to", "cannot create the folder " + parent.string() + ": " + ec.message());
  }
  const fs::path partial = to.string() + ".partial";
  fs::remove(partial, ec);
  std::string jobs, rows, pages;
  {
    Db dest = Open(partial, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, "--to");
    CopyPages(source.get(), dest.get(), db_path);
    if (QueryOne(dest.get(), "PRAGMA journal_mode = DELETE", partial) != "delete")
      throw std::runtime_error("cannot make " + partial.string() + " a self-contained file");
    const std::string check = QueryOne(dest.get(), "PRAGMA integrity_check", partial);
    if (check != "ok") throw std::runtime_error("the copy " + partial.string() + " fails its integrity check: " + check);
    jobs = QueryOne(dest.get(), "SELECT count(*) FROM jobs", partial);
    // Schema 6 stores a task's rows of a table as one block (server/src/row_block.h).
    rows = QueryOne(dest.get(),
                    std::stoi(version) >= 6 ? "SELECT coalesce(sum(rows), 0) FROM result_blocks" : "SELECT count(*) FROM results",
                    partial);
    pages = QueryOne(dest.get(), "PRAGMA page_count", partial);
  }
  Sync(partial, false);
  fs::rename(partial, to);  // throws filesystem_error naming both paths
  Sync(to.has_parent_path() ? to.parent_path() : fs::path("."), true);
  std::cout << "backup of " << db_path.string() << " (schema version " << version << "): " << jobs << " jobs, "
            << rows << " result rows, " << pages << " pages, integrity ok -> " << to.string() << "\n";
  return 0;
}

}  // namespace strokelab::cli
