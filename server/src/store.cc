// The job store and task queue on SQLite (see store.h; schema in schema/migrations/).
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

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <random>
#include <stdexcept>
#include <string_view>
#include <unordered_map>
#include <utility>

#include "migrations.h"
#include "strokelab/base/errors.h"

namespace strokelab::server {

const char* ToString(JobStatus status) {
  switch (status) {
    case JobStatus::kQueued: return "queued";
    case JobStatus::kRunning: return "running";
    case JobStatus::kSucceeded: return "succeeded";
    case JobStatus::kFailed: return "failed";
    case JobStatus::kCancelled: return "cancelled";
  }
  return "unknown";
}

namespace {

using nlohmann::json;

constexpr int kBusyTimeoutMs = 5000;  // how long a write waits for another process's lock [ms]
// Amplitude filter: stored and requested amplitudes match when they differ by at most this
// fraction of the requested one (dimensionless).
constexpr double kAmplitudeMatchRel = 1e-9;

JobStatus ParseJobStatus(std::string_view s) {
  if (s == "queued") return JobStatus::kQueued;
  if (s == "running") return JobStatus::kRunning;
  if (s == "succeeded") return JobStatus::kSucceeded;
  if (s == "failed") return JobStatus::kFailed;
  if (s == "cancelled") return JobStatus::kCancelled;
  throw std::runtime_error("job store: unknown job status '" + std::string(s) + "' in the database");
}

// Results cursors encode the position (task_idx, row_idx) of the last row returned as
// task_idx * 2^32 + row_idx + 1, so that 0 stays "from the start" and the order of cursors is the
// order of rows.
constexpr int64_t kRowsPerTaskLimit = (int64_t{1} << 32) - 1;
int64_t EncodeCursor(int64_t task_idx, int64_t row_idx) { return (task_idx << 32) | (row_idx + 1); }

// The values copied out of a row's JSON into indexed columns.
struct FilterColumns {
  std::optional<double> frequency_hz, amplitude_v;
  std::optional<std::string> branch;
};
FilterColumns ExtractFilterColumns(const json& values) {
  FilterColumns c;
  if (!values.is_object()) return c;
  auto number = [&](const char* name) -> std::optional<double> {
    auto it = values.find(name);
    if (it == values.end() || !it->is_number()) return std::nullopt;
    const double v = it->get<double>();
    return std::isfinite(v) ? std::optional<double>(v) : std::nullopt;
  };
  c.frequency_hz = number("frequency_hz");
  c.amplitude_v = number("amplitude_v");
  if (auto it = values.find("branch"); it != values.end() && it->is_string()) c.branch = it->get<std::string>();
  return c;
}

class SqliteStore final : public Store {
 public:
  explicit SqliteStore(const std::string& path) : path_(path) {
    try {
      OpenAndMigrate();
    } catch (...) {
      Close();
      throw;
    }
  }
  ~SqliteStore() override { Close(); }
  SqliteStore(const SqliteStore&) = delete;
  SqliteStore& operator=(const SqliteStore&) = delete;

  int SchemaVersion() override {
    std::lock_guard lock(mu_);
    return UserVersion();
  }

  void SetJobEventSink(std::function<void(const JobEvent&)> sink) override {
    std::lock_guard lock(mu_);
    sink_ = std::move(sink);
  }

  std::vector<JobEvent> JobEvents(int64_t job_id) override {
    std::lock_guard lock(mu_);
    std::vector<JobEvent> events;
    Stmt s = Prepare(
        "SELECT e.id, e.job_id, j.kind, e.status, e.at_ms, e.tasks_done, j.tasks_total, e.points, e.reason "
        "FROM job_events e JOIN jobs j ON j.id = e.job_id WHERE e.job_id = ?1 ORDER BY e.id");
    s.Int(1, job_id);
    while (s.Step()) {
      JobEvent e;
      e.id = s.ColInt(0);
      e.job_id = s.ColInt(1);
      e.kind = s.ColText(2);
      e.status = ParseJobStatus(s.ColText(3));
      e.at_ms = s.ColInt(4);
      e.tasks_done = static_cast<int>(s.ColInt(5));
      e.tasks_total = static_cast<int>(s.ColInt(6));
      e.points = s.ColInt(7);
      e.reason = s.ColText(8);
      events.push_back(std::move(e));
    }
    return events;
  }

  int64_t SubmitJob(const std::string& kind, const json& spec, const std::vector<TaskSpec>& tasks,
                    int64_t now_ms) override {
    std::lock_guard lock(mu_);
    Transaction tx(*this);
    int64_t job_id = 0;
    {
      Stmt s = Prepare(
          "INSERT INTO jobs (kind, status, spec_json, tasks_total, tasks_done, created_ms) "
          "VALUES (?1, 'queued', ?2, ?3, 0, ?4)");
      s.Text(1, kind).Text(2, spec.dump()).Int(3, static_cast<int64_t>(tasks.size())).Int(4, now_ms).Run();
      job_id = sqlite3_last_insert_rowid(db_);
    }
    RecordEvent(job_id, JobStatus::kQueued, now_ms, "submitted");
    int64_t cached = 0;
    for (size_t i = 0; i < tasks.size(); ++i) {
      const int64_t idx = static_cast<int64_t>(i);
      std::optional<std::string> rows_json;
      {
        Stmt s = Prepare("SELECT rows_json FROM cache WHERE key = ?1");
        if (s.Text(1, tasks[i].key).Step()) rows_json = s.ColText(0);
      }
      {
        Stmt s = Prepare(
            "INSERT INTO tasks (job_id, idx, key, spec_json, status, finished_ms) VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
        s.Int(1, job_id).Int(2, idx).Text(3, tasks[i].key).Text(4, tasks[i].spec.dump());
        s.Text(5, rows_json ? "done" : "queued").Int(6, rows_json ? now_ms : 0).Run();
      }
      if (rows_json) {
        std::vector<ResultRow> rows;
        for (const json& r : json::parse(*rows_json)) rows.push_back({r.at("table").get<std::string>(), r.at("values")});
        InsertResultRows(job_id, idx, rows);
        ++cached;
      }
    }
    if (cached > 0 || tasks.empty()) {
      const bool all = cached == static_cast<int64_t>(tasks.size());
      Stmt s = Prepare(
          "UPDATE jobs SET tasks_done = ?2, status = ?3, started_ms = ?4, finished_ms = ?4 WHERE id = ?1");
      s.Int(1, job_id).Int(2, cached).Text(3, all ? "succeeded" : "queued").Int(4, all ? now_ms : 0).Run();
      if (all)
        RecordEvent(job_id, JobStatus::kSucceeded, now_ms,
                    tasks.empty() ? "no tasks" : "all " + std::to_string(cached) + " tasks from the result cache");
    }
    tx.Commit();
    return job_id;
  }

  std::optional<JobRecord> GetJob(int64_t id) override {
    std::lock_guard lock(mu_);
    Stmt s = Prepare(std::string(kJobColumns) + " WHERE id = ?1");
    if (!s.Int(1, id).Step()) return std::nullopt;
    return ReadJob(s);
  }

  std::vector<JobRecord> ListJobs(int limit, int64_t before_id) override {
    std::lock_guard lock(mu_);
    std::vector<JobRecord> jobs;
    if (limit <= 0) return jobs;
    Stmt s = Prepare(std::string(kJobColumns) + " WHERE id < ?1 ORDER BY id DESC LIMIT ?2");
    s.Int(1, before_id > 0 ? before_id : std::numeric_limits<int64_t>::max()).Int(2, limit);
    while (s.Step()) jobs.push_back(ReadJob(s));
    return jobs;
  }

  bool CancelJob(int64_t id, int64_t now_ms) override {
    std::lock_guard lock(mu_);
    Transaction tx(*this);
    {
      Stmt s = Prepare(
          "UPDATE jobs SET status = 'cancelled', finished_ms = ?2 WHERE id = ?1 AND status IN ('queued', 'running')");
      s.Int(1, id).Int(2, now_ms).Run();
    }
    if (sqlite3_changes(db_) == 0) return false;
    RecordEvent(id, JobStatus::kCancelled, now_ms, "cancelled by request");
    {
      Stmt s = Prepare(
          "UPDATE tasks SET status = 'cancelled', lease_token = NULL, finished_ms = ?2 "
          "WHERE job_id = ?1 AND status IN ('queued', 'leased')");
      s.Int(1, id).Int(2, now_ms).Run();
    }
    tx.Commit();
    return true;
  }

  std::optional<TaskLease> LeaseTask(const std::string& worker, int64_t now_ms, int64_t lease_ms) override {
    std::lock_guard lock(mu_);
    Transaction tx(*this);
    // The oldest queued task and the oldest expired lease; the older of the two wins. Tasks of
    // finished jobs are never queued or leased (cancel and fail close them), the join is a guard.
    int64_t queued = 0, expired = 0;
    {
      Stmt s = Prepare(
          "SELECT t.id FROM tasks t JOIN jobs j ON j.id = t.job_id "
          "WHERE t.status = 'queued' AND j.status IN ('queued', 'running') ORDER BY t.id LIMIT 1");
      if (s.Step()) queued = s.ColInt(0);
    }
    {
      Stmt s = Prepare(
          "SELECT t.id FROM tasks t JOIN jobs j ON j.id = t.job_id "
          "WHERE t.status = 'leased' AND t.lease_expires_ms <= ?1 AND j.status IN ('queued', 'running') "
          "ORDER BY t.id LIMIT 1");
      if (s.Int(1, now_ms).Step()) expired = s.ColInt(0);
    }
    const int64_t task_id = queued == 0 ? expired : expired == 0 ? queued : std::min(queued, expired);
    if (task_id == 0) return std::nullopt;

    TaskLease lease;
    lease.task_id = task_id;
    lease.lease_token = NewToken();
    lease.expires_ms = now_ms + lease_ms;
    {
      Stmt s = Prepare(
          "UPDATE tasks SET status = 'leased', lease_token = ?2, lease_owner = ?3, lease_expires_ms = ?4, "
          "attempts = attempts + 1 WHERE id = ?1");
      s.Int(1, task_id).Text(2, lease.lease_token).Text(3, worker).Int(4, lease.expires_ms).Run();
    }
    {
      Stmt s = Prepare(
          "SELECT t.job_id, t.idx, j.kind, t.spec_json FROM tasks t JOIN jobs j ON j.id = t.job_id WHERE t.id = ?1");
      if (!s.Int(1, task_id).Step()) BrokenInvariant("job store: leased task vanished");
      lease.job_id = s.ColInt(0);
      lease.index = static_cast<int>(s.ColInt(1));
      lease.kind = s.ColText(2);
      lease.spec = json::parse(s.ColText(3));
    }
    {
      Stmt s = Prepare("UPDATE jobs SET status = 'running', started_ms = ?2 WHERE id = ?1 AND status = 'queued'");
      s.Int(1, lease.job_id).Int(2, now_ms).Run();
    }
    if (sqlite3_changes(db_) == 1)
      RecordEvent(lease.job_id, JobStatus::kRunning, now_ms, "first task leased by " + worker);
    tx.Commit();
    return lease;
  }

  int ReleaseLeases(const std::string& owner_prefix) override {
    std::lock_guard lock(mu_);
    Stmt s = Prepare(
        "UPDATE tasks SET status = 'queued', lease_token = NULL, lease_owner = NULL, lease_expires_ms = 0 "
        "WHERE status = 'leased' AND substr(lease_owner, 1, length(?1)) = ?1");
    s.Text(1, owner_prefix).Run();
    return sqlite3_changes(db_);
  }

  bool RenewLease(const TaskLease& lease, int64_t now_ms, int64_t lease_ms) override {
    std::lock_guard lock(mu_);
    Stmt s = Prepare(
        "UPDATE tasks SET lease_expires_ms = ?4 "
        "WHERE id = ?1 AND status = 'leased' AND lease_token = ?2 AND lease_expires_ms > ?3");
    s.Int(1, lease.task_id).Text(2, lease.lease_token).Int(3, now_ms).Int(4, now_ms + lease_ms).Run();
    return sqlite3_changes(db_) == 1;
  }

  bool CompleteTask(const TaskLease& lease, const std::vector<ResultRow>& rows, int64_t now_ms) override {
    std::lock_guard lock(mu_);
    Transaction tx(*this);
    const std::optional<HeldTask> held = CheckLease(lease, now_ms);
    if (!held) return false;  // rolled back: nothing written
    InsertResultRows(held->job_id, held->index, rows);
    {
      Stmt s = Prepare("UPDATE tasks SET status = 'done', lease_token = NULL, finished_ms = ?2 WHERE id = ?1");
      s.Int(1, lease.task_id).Int(2, now_ms).Run();
    }
    bool finished = false;
    int64_t tasks_done = 0;
    {
      Stmt s = Prepare(
          "UPDATE jobs SET tasks_done = tasks_done + 1, "
          "status = CASE WHEN tasks_done + 1 = tasks_total THEN 'succeeded' ELSE status END, "
          "finished_ms = CASE WHEN tasks_done + 1 = tasks_total THEN ?2 ELSE finished_ms END WHERE id = ?1 "
          "RETURNING status = 'succeeded', tasks_done");
      if (s.Int(1, held->job_id).Int(2, now_ms).Step()) {
        finished = s.ColInt(0) == 1;
        tasks_done = s.ColInt(1);
      }
      s.Run();
    }
    if (finished)
      RecordEvent(held->job_id, JobStatus::kSucceeded, now_ms, "all " + std::to_string(tasks_done) + " tasks done");
    {
      json cached = json::array();
      for (const ResultRow& r : rows) cached.push_back({{"table", r.table}, {"values", r.values}});
      Stmt s = Prepare(
          "INSERT INTO cache (key, rows_json, created_ms) VALUES (?1, ?2, ?3) ON CONFLICT (key) DO NOTHING");
      s.Text(1, held->key).Text(2, cached.dump()).Int(3, now_ms).Run();
    }
    tx.Commit();
    return true;
  }

  void FailTask(const TaskLease& lease, const std::string& error, int64_t now_ms) override {
    std::lock_guard lock(mu_);
    Transaction tx(*this);
    const std::optional<HeldTask> held = CheckLease(lease, now_ms);
    if (!held) return;  // lost lease: whoever holds the task now reports its own outcome
    {
      Stmt s = Prepare("UPDATE tasks SET status = 'failed', lease_token = NULL, finished_ms = ?2 WHERE id = ?1");
      s.Int(1, lease.task_id).Int(2, now_ms).Run();
    }
    {
      Stmt s = Prepare(
          "UPDATE jobs SET status = 'failed', error = ?2, finished_ms = ?3 "
          "WHERE id = ?1 AND status IN ('queued', 'running')");
      s.Int(1, held->job_id).Text(2, error).Int(3, now_ms).Run();
    }
    if (sqlite3_changes(db_) == 1) RecordEvent(held->job_id, JobStatus::kFailed, now_ms, error);
    {
      Stmt s = Prepare(
          "UPDATE tasks SET status = 'cancelled', lease_token = NULL, finished_ms = ?2 "
          "WHERE job_id = ?1 AND status IN ('queued', 'leased')");
      s.Int(1, held->job_id).Int(2, now_ms).Run();
    }
    tx.Commit();
  }

  Page Results(int64_t job_id, const std::string& table, const Filter& filter, int64_t cursor, int limit) override {
    if (cursor < 0) throw std::invalid_argument("cursor: not a cursor returned by this service");
    if (limit <= 0) throw std::invalid_argument("limit: must be at least 1");
    // One statement per combination of filters (at most 32), so that each can use its best index.
    std::string sql = "SELECT task_idx, row_idx, json FROM results WHERE job_id = ?1 AND table_name = ?2";
    if (cursor > 0) sql += " AND (task_idx, row_idx) > (?3, ?4)";
    if (filter.frequency_min_hz) sql += " AND frequency_hz >= ?5";
    if (filter.frequency_max_hz) sql += " AND frequency_hz <= ?6";
    if (filter.amplitude_v) sql += " AND amplitude_v BETWEEN ?7 AND ?8";
    if (filter.branch) sql += " AND branch = ?9";
    sql += " ORDER BY task_idx, row_idx LIMIT ?10";

    std::lock_guard lock(mu_);
    Stmt s = Prepare(sql);
    s.Int(1, job_id).Text(2, table);
    if (cursor > 0) s.Int(3, cursor >> 32).Int(4, (cursor & kRowsPerTaskLimit) - 1);
    if (filter.frequency_min_hz) s.Double(5, *filter.frequency_min_hz);
    if (filter.frequency_max_hz) s.Double(6, *filter.frequency_max_hz);
    if (filter.amplitude_v) {
      const double a = *filter.amplitude_v, tol = kAmplitudeMatchRel * std::abs(a);
      s.Double(7, a - tol).Double(8, a + tol);
    }
    if (filter.branch) s.Text(9, *filter.branch);
    s.Int(10, static_cast<int64_t>(limit) + 1);  // one more tells whether there is a next page

    Page page;
    int64_t last = 0;
    while (s.Step()) {
      if (static_cast<int>(page.rows.size()) == limit) {
        page.next_cursor = last;
        break;
      }
      last = EncodeCursor(s.ColInt(0), s.ColInt(1));
      page.rows.push_back(json::parse(s.ColText(2)));
    }
    return page;
  }

  int64_t CountResults(int64_t job_id, const std::string& table) override {
    std::lock_guard lock(mu_);
    Stmt s = Prepare("SELECT count(*) FROM results WHERE job_id = ?1 AND table_name = ?2");
    s.Int(1, job_id).Text(2, table).Step();
    return s.ColInt(0);
  }

  Counts GetCounts(int64_t now_ms) override {
    std::lock_guard lock(mu_);
    Transaction tx(*this, /*write=*/false);  // one consistent snapshot
    Counts c;
    {
      Stmt s = Prepare("SELECT status, count(*) FROM jobs GROUP BY status");
      while (s.Step()) c.jobs[static_cast<int>(ParseJobStatus(s.ColText(0)))] = s.ColInt(1);
    }
    {
      Stmt s = Prepare(
          "SELECT count(*) FILTER (WHERE status = 'queued' OR lease_expires_ms <= ?1), "
          "       count(*) FILTER (WHERE status = 'leased' AND lease_expires_ms > ?1) "
          "FROM tasks WHERE status IN ('queued', 'leased')");
      s.Int(1, now_ms).Step();
      c.tasks_queued = s.ColInt(0);
      c.tasks_leased = s.ColInt(1);
    }
    {
      Stmt s = Prepare("SELECT count(*) FROM tasks WHERE status = 'done'");
      s.Step();
      c.tasks_done = s.ColInt(0);
    }
    tx.Commit();
    return c;
  }

 private:
  static constexpr const char* kJobColumns =
      "SELECT id, kind, status, spec_json, tasks_total, tasks_done, created_ms, started_ms, finished_ms, "
      "coalesce(error, '') FROM jobs";

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

  // The task row behind `lease` if the lease is still held: the task is leased with this token
  // (a new lease, a cancel or a completion changes or clears it) and the lease has not expired.
  std::optional<HeldTask> CheckLease(const TaskLease& lease, int64_t now_ms) {
    Stmt s = Prepare("SELECT job_id, idx, key FROM tasks "
                     "WHERE id = ?1 AND status = 'leased' AND lease_token = ?2 AND lease_expires_ms > ?3");
    if (!s.Int(1, lease.task_id).Text(2, lease.lease_token).Int(3, now_ms).Step()) return std::nullopt;
    HeldTask held{s.ColInt(0), s.ColInt(1), s.ColText(2)};
    if (held.job_id != lease.job_id) return std::nullopt;
    return held;
  }

  void InsertResultRows(int64_t job_id, int64_t task_idx, const std::vector<ResultRow>& rows) {
    if (static_cast<int64_t>(rows.size()) >= kRowsPerTaskLimit) throw std::length_error("job store: too many rows");
    for (size_t r = 0; r < rows.size(); ++r) {
      const FilterColumns c = ExtractFilterColumns(rows[r].values);
      Stmt s = Prepare(
          "INSERT INTO results (job_id, table_name, task_idx, row_idx, frequency_hz, amplitude_v, branch, json) "
          "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)");
      s.Int(1, job_id).Text(2, rows[r].table).Int(3, task_idx).Int(4, static_cast<int64_t>(r));
      s.OptDouble(5, c.frequency_hz).OptDouble(6, c.amplitude_v).OptText(7, c.branch);
      s.Text(8, rows[r].values.dump(-1, ' ', false, json::error_handler_t::replace)).Run();
    }
  }

  // Stores a state change of a job in job_events, inside the caller's transaction, and queues it for
  // the sink (Transaction::Commit).
  void RecordEvent(int64_t job_id, JobStatus status, int64_t now_ms, const std::string& reason) {
    JobEvent e;
    e.job_id = job_id;
    e.status = status;
    e.at_ms = now_ms;
    e.reason = reason;
    {
      Stmt s = Prepare(
          "SELECT kind, tasks_done, tasks_total, "
          "(SELECT count(*) FROM results WHERE job_id = ?1 AND table_name = 'points') FROM jobs WHERE id = ?1");
      if (!s.Int(1, job_id).Step()) BrokenInvariant("job store: event of a job that does not exist");
      e.kind = s.ColText(0);
      e.tasks_done = static_cast<int>(s.ColInt(1));
      e.tasks_total = static_cast<int>(s.ColInt(2));
      e.points = s.ColInt(3);
    }
    Stmt s = Prepare(
        "INSERT INTO job_events (job_id, at_ms, status, tasks_done, points, reason) VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
    s.Int(1, job_id).Int(2, now_ms).Text(3, ToString(status)).Int(4, e.tasks_done).Int(5, e.points).Text(6, reason);
    s.Run();
    e.id = sqlite3_last_insert_rowid(db_);
    pending_events_.push_back(std::move(e));
  }

  static JobRecord ReadJob(Stmt& s) {
    JobRecord j;
    j.id = s.ColInt(0);
    j.kind = s.ColText(1);
    j.status = ParseJobStatus(s.ColText(2));
    j.spec = json::parse(s.ColText(3));
    j.tasks_total = static_cast<int>(s.ColInt(4));
    j.tasks_done = static_cast<int>(s.ColInt(5));
    j.created_ms = s.ColInt(6);
    j.started_ms = s.ColInt(7);
    j.finished_ms = s.ColInt(8);
    j.error = s.ColText(9);
    return j;
  }

  std::string NewToken() {
    // 128 bits from the OS entropy source, as 32 hex digits.
    static constexpr char kHex[] = "0123456789abcdef";
    std::string token;
    for (int i = 0; i < 4; ++i) {
      uint32_t v = random_();
      for (int k = 0; k < 8; ++k, v >>= 4) token.push_back(kHex[v & 0xf]);
    }
    return token;
  }

  Stmt Prepare(const std::string& sql) {
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

  void Exec(const char* sql) {
    const int rc = sqlite3_exec(db_, sql, nullptr, nullptr, nullptr);
    if (rc != SQLITE_OK) Fail(rc, sql);
  }

  [[noreturn]] void Fail(int rc, const char* sql) {
    std::string sql_head(sql ? sql : "");
    if (sql_head.size() > 60) sql_head = sql_head.substr(0, 57) + "...";
    throw StoreError("database " + path_ + ": " + Describe(rc) + " (in: " + sql_head + ")");
  }

  // The error of the last call on db_, with a hint for the usual operational causes.
  std::string Describe(int rc) {
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

  void OpenAndMigrate() {
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
  void CheckIntegrity() {
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
  void Migrate() {
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

  int UserVersion() {
    Stmt s = Prepare("PRAGMA user_version");
    s.Step();
    return static_cast<int>(s.ColInt(0));
  }

  [[noreturn]] void OpenFailed(int rc) {
    throw std::runtime_error("cannot open database " + path_ + ": " + Describe(rc));
  }

  static int ReadFirstColumn(void* out, int columns, char** values, char**) {
    if (columns > 0 && values[0]) *static_cast<std::string*>(out) = values[0];
    return 0;
  }

  void Close() {
    for (auto& [sql, stmt] : statements_) sqlite3_finalize(stmt);
    statements_.clear();
    if (db_) sqlite3_close_v2(db_);
    db_ = nullptr;
  }

  std::mutex mu_;  // guards everything below; held for the whole of every public method
  std::string path_;
  sqlite3* db_ = nullptr;
  std::unordered_map<std::string, sqlite3_stmt*> statements_;
  std::random_device random_;
  std::function<void(const JobEvent&)> sink_;
  std::vector<JobEvent> pending_events_;  // of the open transaction, for the sink
};

}  // namespace

std::unique_ptr<Store> Store::Open(const std::string& path) { return std::make_unique<SqliteStore>(path); }

}  // namespace strokelab::server
