// The job store and task queue: one SQLite file in WAL mode (schema/migrations/*.sql).
//
// A job is split into tasks when it is submitted (one transaction). Workers lease a task with an
// expiry; a lease that expires makes the task leasable again. Completing a task writes all of its
// result rows and marks it done in one transaction, and only if the caller still holds the lease,
// so that a task is never stored twice and a crash at any moment loses at most the work of the
// leases in flight. Every task has a key (a hash of its spec, the model, the method and the code
// version); a task whose key equals a finished task's is done at submission with a copy of that
// task's rows (the result cache), without recomputation.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "strokelab/jobs/task.h"

namespace strokelab::server {

using jobs::ResultRow;
using jobs::TaskResult;
using jobs::TaskSpec;

enum class JobStatus { kQueued, kRunning, kSucceeded, kFailed, kCancelled };
const char* ToString(JobStatus status);

struct JobRecord {
  int64_t id = 0;
  std::string kind;                // "sweep", "simulate", ...
  JobStatus status = JobStatus::kQueued;
  nlohmann::json spec;             // as submitted (validated)
  int tasks_total = 0, tasks_done = 0;
  int64_t created_ms = 0, started_ms = 0, finished_ms = 0;  // unix epoch [ms]; 0: not yet
  std::string error;               // when failed
};

// One change of a job's state, as stored in job_events (schema/migrations/002_job_events.sql) and
// passed to the event sink.
struct JobEvent {
  int64_t id = 0;                  // order of the changes (all jobs)
  int64_t job_id = 0;
  std::string kind;                // the job's kind
  JobStatus status = JobStatus::kQueued;  // the state entered
  int64_t at_ms = 0;               // unix epoch [ms]
  int tasks_done = 0, tasks_total = 0;
  int64_t points = 0;              // rows of the "points" table stored at the change
  std::string reason;              // "submitted", "first task leased by local-0", the error, ...
};

struct TaskLease {
  int64_t task_id = 0;
  int64_t job_id = 0;
  int index = 0;                   // position within the job
  std::string kind;                // the job's kind
  nlohmann::json spec;
  std::string lease_token;         // proves the lease when completing
  int64_t expires_ms = 0;
};

// An error of the database itself (disk full, I/O error, damaged file, locked too long), as opposed
// to bad input: the service answers it with 503 and reports it in /v1/health.
class StoreError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Every method is thread-safe: writes go through one SQLite connection behind a mutex, reads
// (GetJob, ListJobs, JobEvents, Results, CountResults, GetCounts, LeasedTaskSpec, SchemaVersion,
// and a LeaseTask that finds the queue empty) through a pool of read-only connections, which in WAL
// mode see the last committed transaction and never wait for a write. Errors of the database (disk
// full, I/O, locked by another process for more than 5 s) throw StoreError naming the file and
// SQLite's message, with the transaction rolled back.
class Store {
 public:
  // Opens (creating if needed) the database, sets WAL mode, checks every page (PRAGMA quick_check),
  // applies pending migrations. Throws std::runtime_error naming the file on failure (damaged,
  // locked, not writable).
  static std::unique_ptr<Store> Open(const std::string& path);
  virtual ~Store() = default;

  virtual int SchemaVersion() = 0;

  // Called with every job state change after its transaction has committed, in commit order, with
  // the store's write lock held: the sink may read the store but must not write to it. Empty: no
  // calls.
  virtual void SetJobEventSink(std::function<void(const JobEvent&)> sink) = 0;
  // A job's state changes, oldest first (empty for an unknown job).
  virtual std::vector<JobEvent> JobEvents(int64_t job_id) = 0;

  // Inserts the job and its tasks in one transaction; tasks whose key has a cached result are done
  // at once with that result (the job is succeeded at once when all are, or when there are no
  // tasks). Returns the job id.
  virtual int64_t SubmitJob(const std::string& kind, const nlohmann::json& spec, const std::vector<TaskSpec>& tasks,
                            int64_t now_ms) = 0;
  virtual std::optional<JobRecord> GetJob(int64_t id) = 0;
  // Newest first; `before_id` pages (0: from the newest).
  virtual std::vector<JobRecord> ListJobs(int limit, int64_t before_id) = 0;
  // Cancels a queued or running job (its leases become void). False if it had already finished
  // (or does not exist).
  virtual bool CancelJob(int64_t id, int64_t now_ms) = 0;

  // Leases the oldest leasable task (queued, or leased with an expired lease) of a running or
  // queued job, for `lease_ms`; nullopt when there is none.
  virtual std::optional<TaskLease> LeaseTask(const std::string& worker, int64_t now_ms, int64_t lease_ms) = 0;
  // Returns the tasks leased by workers whose name starts with `owner_prefix` to the queue: the
  // server does this at start for its own in-process workers, which cannot outlive it, so that a
  // restart after a crash resumes at once instead of waiting for their leases to expire.
  virtual int ReleaseLeases(const std::string& owner_prefix) = 0;
  // Extends a lease still held; false if it was lost.
  virtual bool RenewLease(const TaskLease& lease, int64_t now_ms, int64_t lease_ms) = 0;
  // The spec of the task behind `lease` while the lease is held (as RunTask takes it); nullopt if
  // the lease was lost. A completion is checked against it before its rows are read.
  virtual std::optional<nlohmann::json> LeasedTaskSpec(const TaskLease& lease, int64_t now_ms) = 0;
  // Writes the rows and marks the task done in one transaction, if the lease is still held (same
  // token, not expired, job not cancelled), where later tasks of the same key find them; finishes the job
  // when its last task is done. False if the lease was lost (nothing is written). An expired lease
  // is lost even before another worker takes the task: renew in time.
  virtual bool CompleteTask(const TaskLease& lease, const TaskResult& result, int64_t now_ms) = 0;
  // Fails the task and its job with a message (a deterministic error: retrying would not help);
  // the job's other open tasks are cancelled. Does nothing if the lease was lost.
  virtual void FailTask(const TaskLease& lease, const std::string& error, int64_t now_ms) = 0;
  // A task whose computation spent its work budget (strokelab::WorkBudgetSpent): the first time it
  // goes back to the queue (lease cleared); the second (kMaxBudgetFailures) fails the task and its
  // job as FailTask does, with "work budget spent twice: " + error. Returns true when the job failed.
  // Does nothing (false) if the lease was lost.
  static constexpr int kMaxBudgetFailures = 2;
  virtual bool FailTaskOnBudget(const TaskLease& lease, const std::string& error, int64_t now_ms) = 0;

  // Result rows of a job from one table in (task, row) order, with keyset paging: rows after
  // `cursor` (0: from the start), at most `limit`; `next_cursor` is 0 at the end. Rows whose values
  // hold "frequency_hz", "amplitude_v" and "branch" can be filtered on them (indexed columns).
  // A cursor encodes the position (task, row) of the last row returned, so paging a running job
  // does not see rows of tasks that complete behind the cursor; page a finished job for all rows.
  // Throws std::invalid_argument for a negative cursor or a limit below 1.
  struct Filter {
    std::optional<double> frequency_min_hz, frequency_max_hz;
    std::optional<double> amplitude_v;  // matched to 1e-9 relative
    std::optional<std::string> branch;
  };
  struct Page {
    std::vector<nlohmann::json> rows;
    int64_t next_cursor = 0;
  };
  virtual Page Results(int64_t job_id, const std::string& table, const Filter& filter, int64_t cursor, int limit) = 0;
  virtual int64_t CountResults(int64_t job_id, const std::string& table) = 0;

  // Counts for /metrics: jobs by status, tasks queued (leasable), tasks done in total.
  struct Counts {
    int64_t jobs[5] = {0, 0, 0, 0, 0};
    int64_t tasks_queued = 0, tasks_leased = 0, tasks_done = 0;
  };
  virtual Counts GetCounts(int64_t now_ms) = 0;
};

}  // namespace strokelab::server
