// The store on SQLite, whose methods are defined by subject: store.cc (opening: the integrity check,
// migrations, the reader pool), store_jobs.cc (jobs, their events and counts), store_tasks.cc
// (leases) and store_results.cc (result rows). Its connections: store_connection.h. Internal to the
// store.
//
// Writes go through one connection under write_mu_ (SQLite has one writer at a time anyway); reads
// go through the reader pool and never wait for a write. Work that needs no database (encoding a
// completion's rows, parsing a leased task's spec) is done outside write_mu_.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <functional>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "store_connection.h"
#include "strokelab/server/store.h"

namespace strokelab::server::internal {

// A task's rows as they are stored (store_results.cc): one result block (row_block.h) per table,
// with the ranges of the filter columns of its rows, so that a filtered read skips the blocks that
// cannot match without decoding them.
struct EncodedBlock {
  std::string table;
  int64_t rows = 0;
  std::optional<double> frequency_min_hz, frequency_max_hz, amplitude_min_v, amplitude_max_v;
  std::string bytes;
};
struct EncodedRows {
  std::vector<EncodedBlock> blocks;  // tables in the order of their first row
  int64_t points = 0;                // rows of the "points" table
};
EncodedRows EncodeRows(const TaskResult& result);

class SqliteStore final : public Store {
 public:
  explicit SqliteStore(const std::string& path);
  ~SqliteStore() override = default;
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
  bool CompleteTask(const TaskLease& lease, const TaskResult& result, int64_t now_ms) override;
  void FailTask(const TaskLease& lease, const std::string& error, int64_t now_ms) override;
  bool FailTaskOnBudget(const TaskLease& lease, const std::string& error, int64_t now_ms) override;

  Page Results(int64_t job_id, const std::string& table, const Filter& filter, int64_t cursor, int limit) override;
  int64_t CountResults(int64_t job_id, const std::string& table) override;

  Counts GetCounts(int64_t now_ms) override;

 private:
  // BEGIN IMMEDIATE on the writer (held under write_mu_); rolls back unless committed.
  class Transaction {
   public:
    explicit Transaction(SqliteStore& store) : store_(store) { store_.writer_.Exec("BEGIN IMMEDIATE"); }
    ~Transaction() {
      sqlite3* db = store_.writer_.db();
      if (!sqlite3_get_autocommit(db)) sqlite3_exec(db, "ROLLBACK", nullptr, nullptr, nullptr);
      store_.pending_events_.clear();  // rolled back: those changes never happened
    }
    Transaction(const Transaction&) = delete;
    Transaction& operator=(const Transaction&) = delete;
    // Commits, then tells the sink of the job state changes this transaction made (only now are
    // they true for every reader).
    void Commit() {
      store_.writer_.Exec("COMMIT");
      if (store_.sink_)
        for (const JobEvent& e : store_.pending_events_) store_.sink_(e);
      store_.pending_events_.clear();
    }

   private:
    SqliteStore& store_;
  };

  struct HeldTask {
    int64_t job_id = 0, index = 0;
  };

  // store_jobs.cc
  void RecordEvent(int64_t job_id, JobStatus status, int64_t now_ms, const std::string& reason);
  static JobRecord ReadJob(Stmt& s);

  // store_tasks.cc
  int64_t OldestLeasable(Connection& c, int64_t now_ms);
  std::optional<HeldTask> CheckLease(Connection& c, const TaskLease& lease, int64_t now_ms);
  std::string NewToken();

  // store_results.cc, in the open write transaction: the rows of one task; a task's blocks stored
  // again under another job's task (a result cache hit; returns its "points" rows); the rows of
  // schema 5's per-row table moved into blocks (migration 006).
  void InsertResultRows(int64_t job_id, int64_t task_idx, const EncodedRows& rows);
  int64_t CopyResultBlocks(int64_t from_job_id, int64_t from_task_idx, int64_t job_id, int64_t task_idx);
  void MoveResultRowsIntoBlocks();

  // store.cc
  void OpenAndMigrate();
  void CheckIntegrity();
  void Migrate();
  int UserVersion(Connection& c);
  static int ReadFirstColumn(void* out, int columns, char** values, char**);

  std::mutex write_mu_;  // guards the members below up to readers_; held for the whole of every write
  Connection writer_;
  std::random_device random_;
  std::function<void(const JobEvent&)> sink_;
  std::vector<JobEvent> pending_events_;  // of the open transaction, for the sink
  // Declared after writer_, so closed before it: the writer, closing last, checkpoints the WAL
  // into the file and removes it.
  ReaderPool readers_;
};

}  // namespace strokelab::server::internal
