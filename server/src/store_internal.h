// The store on SQLite, whose methods are defined by subject: store.cc (the connection: opening, the
// integrity check, migrations, prepared statements, errors), store_jobs.cc (jobs, their events and
// counts), store_tasks.cc (leases) and store_results.cc (result rows). Internal to the store.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <functional>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "strokelab/server/store.h"

namespace strokelab::server::internal {

class SqliteStore final : public Store {
 public:
  explicit SqliteStore(const std::string& path);
  ~SqliteStore() override;
  SqliteStore(const SqliteStore&) = delete;
  SqliteStore& operator=(const SqliteStore&) = delete;

  int SchemaVersion() override;

  void SetJobEventSink(std::function<void(const JobEvent&)> sink) override;
  std::vector<JobEvent> JobEvents(int64_t job_id) override;
  int64_t SubmitJob(const std::string& kind, const nlohmann::json& spec, const std::vector<TaskSpec>& tasks,
                    int64_t now_ms) override;
  std::optional<JobRecord> GetJob(int64_t id) override;
  std::vector<JobRecord> ListJobs(int limit, int64_t before_id) override;
  bool CancelJob(int64_t id, int64_t now_ms) override;

  std::optional<TaskLease> LeaseTask(const std::string& worker, int64_t now_ms, int64_t lease_ms) override;
  int ReleaseLeases(const std::string& owner_prefix) override;
  bool RenewLease(const TaskLease& lease, int64_t now_ms, int64_t lease_ms) override;
  std::optional<nlohmann::json> LeasedTaskSpec(const TaskLease& lease, int64_t now_ms) override;
  bool CompleteTask(const TaskLease& lease, const std::vector<ResultRow>& rows, int64_t now_ms) override;
  void FailTask(const TaskLease& lease, const std::string& error, int64_t now_ms) override;
  bool FailTaskOnBudget(const TaskLease& lease, const std::string& error, int64_t now_ms) override;

  Page Results(int64_t job_id, const std::string& table, const Filter& filter, int64_t cursor, int limit) override;
  int64_t CountResults(int64_t job_id, const std::string& table) override;

  Counts GetCounts(int64_t now_ms) override;

 private:
  // A cached prepared statement in use: binds (1-based, chainable), steps, and resets on scope exit.
  class Stmt {
   public:
    Stmt(SqliteStore& store, sqlite3_stmt* stmt) : store_(store), stmt_(stmt) {}
    ~Stmt() {
      sqlite3_reset(stmt_);
      sqlite3_clear_bindings(stmt_);
    }
    Stmt(const Stmt&) = delete;
    Stmt& operator=(const Stmt&) = delete;

    Stmt& Int(int i, int64_t v) { return Bound(sqlite3_bind_int64(stmt_, i, v)); }
    Stmt& Double(int i, double v) { return Bound(sqlite3_bind_double(stmt_, i, v)); }
    Stmt& Text(int i, std::string_view v) {
      return Bound(sqlite3_bind_text64(stmt_, i, v.data(), v.size(), SQLITE_TRANSIENT, SQLITE_UTF8));
    }
    Stmt& Null(int i) { return Bound(sqlite3_bind_null(stmt_, i)); }
    Stmt& OptDouble(int i, const std::optional<double>& v) { return v ? Double(i, *v) : Null(i); }
    Stmt& OptText(int i, const std::optional<std::string>& v) { return v ? Text(i, *v) : Null(i); }

    // True when a row is available, false when done; throws on an error.
    bool Step() {
      const int rc = sqlite3_step(stmt_);
      if (rc == SQLITE_ROW) return true;
      if (rc == SQLITE_DONE) return false;
      store_.Fail(rc, sqlite3_sql(stmt_));
    }
    void Run() {
      while (Step()) {
      }
    }
    int64_t ColInt(int c) { return sqlite3_column_int64(stmt_, c); }
    std::string ColText(int c) {
      const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(stmt_, c));
      return p ? std::string(p, static_cast<size_t>(sqlite3_column_bytes(stmt_, c))) : std::string();
    }

   private:
    Stmt& Bound(int rc) {
      if (rc != SQLITE_OK) store_.Fail(rc, sqlite3_sql(stmt_));
      return *this;
    }
    SqliteStore& store_;
    sqlite3_stmt* stmt_;
  };

  // BEGIN IMMEDIATE (write) or BEGIN (read snapshot); rolls back unless committed.
  class Transaction {
   public:
    explicit Transaction(SqliteStore& store, bool write = true) : store_(store) {
      store_.Exec(write ? "BEGIN IMMEDIATE" : "BEGIN");
    }
    ~Transaction() {
      if (!sqlite3_get_autocommit(store_.db_)) sqlite3_exec(store_.db_, "ROLLBACK", nullptr, nullptr, nullptr);
      store_.pending_events_.clear();  // rolled back: those changes never happened
    }
    Transaction(const Transaction&) = delete;
    Transaction& operator=(const Transaction&) = delete;
    // Commits, then tells the sink of the job state changes this transaction made (only now are
    // they true for every reader).
    void Commit() {
      store_.Exec("COMMIT");
      if (store_.sink_)
        for (const JobEvent& e : store_.pending_events_) store_.sink_(e);
      store_.pending_events_.clear();
    }

   private:
    SqliteStore& store_;
  };

  struct HeldTask {
    int64_t job_id = 0, index = 0;
    std::string key;
  };

  // store_jobs.cc
  void RecordEvent(int64_t job_id, JobStatus status, int64_t now_ms, const std::string& reason);
  static JobRecord ReadJob(Stmt& s);

  // store_tasks.cc
  std::optional<HeldTask> CheckLease(const TaskLease& lease, int64_t now_ms);
  std::string NewToken();

  // store_results.cc
  void InsertResultRows(int64_t job_id, int64_t task_idx, const std::vector<ResultRow>& rows);

  // store.cc
  Stmt Prepare(const std::string& sql);
  void Exec(const char* sql);
  [[noreturn]] void Fail(int rc, const char* sql);
  std::string Describe(int rc);
  void OpenAndMigrate();
  void CheckIntegrity();
  void Migrate();
  int UserVersion();
  [[noreturn]] void OpenFailed(int rc);
  static int ReadFirstColumn(void* out, int columns, char** values, char**);
  void Close();

  std::mutex mu_;  // guards everything below; held for the whole of every public method
  std::string path_;
  sqlite3* db_ = nullptr;
  std::unordered_map<std::string, sqlite3_stmt*> statements_;
  std::random_device random_;
  std::function<void(const JobEvent&)> sink_;
  std::vector<JobEvent> pending_events_;  // of the open transaction, for the sink
};

}  // namespace strokelab::server::internal
