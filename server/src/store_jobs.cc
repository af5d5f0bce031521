// The store's jobs (store.h): submission (tasks with a cached result are done at once), listing,
// cancelling, the job_events history of every state change, and the counts for /metrics.
#include <sqlite3.h>

#include <functional>
#include <limits>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "store_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/server/store.h"
#include "strokelab/base/json_parse.h"

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

namespace internal {
namespace {

using nlohmann::json;

JobStatus ParseJobStatus(std::string_view s) {
  if (s == "queued") return JobStatus::kQueued;
  if (s == "running") return JobStatus::kRunning;
  if (s == "succeeded") return JobStatus::kSucceeded;
  if (s == "failed") return JobStatus::kFailed;
  if (s == "cancelled") return JobStatus::kCancelled;
  throw std::runtime_error("job store: unknown job status '" + std::string(s) + "' in the database");
}

constexpr const char* kJobColumns =
    "SELECT id, kind, status, spec_json, tasks_total, tasks_done, created_ms, started_ms, finished_ms, "
    "coalesce(error, '') FROM jobs";

}  // namespace

void SqliteStore::SetJobEventSink(std::function<void(const JobEvent&)> sink) {
  std::lock_guard lock(write_mu_);
  sink_ = std::move(sink);
}

std::vector<JobEvent> SqliteStore::JobEvents(int64_t job_id) {
  ReaderPool::Handle reader = readers_.Acquire();
  std::vector<JobEvent> events;
  Stmt s = reader->Prepare(
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

int64_t SqliteStore::SubmitJob(const std::string& kind, const json& spec, const std::vector<TaskSpec>& tasks,
                               int64_t now_ms) {
  const std::string spec_json = spec.dump();
  std::vector<std::string> task_specs_json;
  task_specs_json.reserve(tasks.size());
  for (const TaskSpec& t : tasks) task_specs_json.push_back(t.spec.dump());
  std::lock_guard lock(write_mu_);
  Transaction tx(*this);
  int64_t job_id = 0;
  {
    Stmt s = writer_.Prepare(
        "INSERT INTO jobs (kind, status, spec_json, tasks_total, tasks_done, created_ms) "
        "VALUES (?1, 'queued', ?2, ?3, 0, ?4)");
    s.Text(1, kind).Text(2, spec_json).Int(3, static_cast<int64_t>(tasks.size())).Int(4, now_ms).Run();
    job_id = writer_.LastInsertRowid();
  }
  RecordEvent(job_id, JobStatus::kQueued, now_ms, "submitted");
  int64_t cached = 0, points = 0;
  for (size_t i = 0; i < tasks.size(); ++i) {
    const int64_t idx = static_cast<int64_t>(i);
    // A result cache hit: a finished task with the same key (the key hashes the work and the code
    // version) gives its rows.
    std::optional<std::pair<int64_t, int64_t>> done_twin;  // (job_id, idx)
    {
      Stmt s = writer_.Prepare("SELECT job_id, idx FROM tasks WHERE key = ?1 AND status = 'done' ORDER BY id LIMIT 1");
      if (s.Text(1, tasks[i].key).Step()) done_twin = {s.ColInt(0), s.ColInt(1)};
    }
    {
      Stmt s = writer_.Prepare(
          "INSERT INTO tasks (job_id, idx, key, spec_json, status, finished_ms) VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
      s.Int(1, job_id).Int(2, idx).Text(3, tasks[i].key).StaticText(4, task_specs_json[i]);
      s.Text(5, done_twin ? "done" : "queued").Int(6, done_twin ? now_ms : 0).Run();
    }
    if (done_twin) {
      points += CopyResultBlocks(done_twin->first, done_twin->second, job_id, idx);
      ++cached;
    }
  }
  if (cached > 0 || tasks.empty()) {
    const bool all = cached == static_cast<int64_t>(tasks.size());
    Stmt s = writer_.Prepare(
        "UPDATE jobs SET tasks_done = ?2, status = ?3, started_ms = ?4, finished_ms = ?4, points = ?5 WHERE id = ?1");
    s.Int(1, job_id).Int(2, cached).Text(3, all ? "succeeded" : "queued").Int(4, all ? now_ms : 0).Int(5, points);
    s.Run();
    if (all)
      RecordEvent(job_id, JobStatus::kSucceeded, now_ms,
                  tasks.empty() ? "no tasks" : "all " + std::to_string(cached) + " tasks from the result cache");
  }
  tx.Commit();
  return job_id;
}

std::optional<JobRecord> SqliteStore::GetJob(int64_t id) {
  ReaderPool::Handle reader = readers_.Acquire();
  Stmt s = reader->Prepare(std::string(kJobColumns) + " WHERE id = ?1");
  if (!s.Int(1, id).Step()) return std::nullopt;
  return ReadJob(s);
}

std::vector<JobRecord> SqliteStore::ListJobs(int limit, int64_t before_id) {
  std::vector<JobRecord> jobs;
  if (limit <= 0) return jobs;
  ReaderPool::Handle reader = readers_.Acquire();
  Stmt s = reader->Prepare(std::string(kJobColumns) + " WHERE id < ?1 ORDER BY id DESC LIMIT ?2");
  s.Int(1, before_id > 0 ? before_id : std::numeric_limits<int64_t>::max()).Int(2, limit);
  while (s.Step()) jobs.push_back(ReadJob(s));
  return jobs;
}

bool SqliteStore::CancelJob(int64_t id, int64_t now_ms) {
  std::lock_guard lock(write_mu_);
  Transaction tx(*this);
  {
    Stmt s = writer_.Prepare(
        "UPDATE jobs SET status = 'cancelled', finished_ms = ?2 WHERE id = ?1 AND status IN ('queued', 'running')");
    s.Int(1, id).Int(2, now_ms).Run();
  }
  if (writer_.Changes() == 0) return false;
  RecordEvent(id, JobStatus::kCancelled, now_ms, "cancelled by request");
  {
    Stmt s = writer_.Prepare(
        "UPDATE tasks SET status = 'cancelled', lease_token = NULL, finished_ms = ?2 "
        "WHERE job_id = ?1 AND status IN ('queued', 'leased')");
    s.Int(1, id).Int(2, now_ms).Run();
  }
  tx.Commit();
  return true;
}

Store::Counts SqliteStore::GetCounts(int64_t now_ms) {
  ReaderPool::Handle reader = readers_.Acquire();
  ReadSnapshot snapshot(*reader);  // one consistent snapshot
  Counts c;
  {
    Stmt s = reader->Prepare("SELECT status, count(*) FROM jobs GROUP BY status");
    while (s.Step()) c.jobs[static_cast<int>(ParseJobStatus(s.ColText(0)))] = s.ColInt(1);
  }
  {
    Stmt s = reader->Prepare(
        "SELECT count(*) FILTER (WHERE status = 'queued' OR lease_expires_ms <= ?1), "
        "       count(*) FILTER (WHERE status = 'leased' AND lease_expires_ms > ?1) "
        "FROM tasks WHERE status IN ('queued', 'leased')");
    s.Int(1, now_ms).Step();
    c.tasks_queued = s.ColInt(0);
    c.tasks_leased = s.ColInt(1);
  }
  {
    Stmt s = reader->Prepare("SELECT count(*) FROM tasks WHERE status = 'done'");
    s.Step();
    c.tasks_done = s.ColInt(0);
  }
  return c;
}

// Stores a state change of a job in job_events, inside the caller's transaction, and queues it for
// the sink (Transaction::Commit).
void SqliteStore::RecordEvent(int64_t job_id, JobStatus status, int64_t now_ms, const std::string& reason) {
  JobEvent e;
  e.job_id = job_id;
  e.status = status;
  e.at_ms = now_ms;
  e.reason = reason;
  {  // the points counter, not the results table: a finishing job's event costs no scan of its rows
    Stmt s = writer_.Prepare("SELECT kind, tasks_done, tasks_total, points FROM jobs WHERE id = ?1");
    if (!s.Int(1, job_id).Step()) BrokenInvariant("job store: event of a job that does not exist");
    e.kind = s.ColText(0);
    e.tasks_done = static_cast<int>(s.ColInt(1));
    e.tasks_total = static_cast<int>(s.ColInt(2));
    e.points = s.ColInt(3);
  }
  Stmt s = writer_.Prepare(
      "INSERT INTO job_events (job_id, at_ms, status, tasks_done, points, reason) VALUES (?1, ?2, ?3, ?4, ?5, ?6)");
  s.Int(1, job_id).Int(2, now_ms).Text(3, ToString(status)).Int(4, e.tasks_done).Int(5, e.points).Text(6, reason);
  s.Run();
  e.id = writer_.LastInsertRowid();
  pending_events_.push_back(std::move(e));
}

JobRecord SqliteStore::ReadJob(Stmt& s) {
  JobRecord j;
  j.id = s.ColInt(0);
  j.kind = s.ColText(1);
  j.status = ParseJobStatus(s.ColText(2));
  j.spec = ParseJson(s.ColText(3));
  j.tasks_total = static_cast<int>(s.ColInt(4));
  j.tasks_done = static_cast<int>(s.ColInt(5));
  j.created_ms = s.ColInt(6);
  j.started_ms = s.ColInt(7);
  j.finished_ms = s.ColInt(8);
  j.error = s.ColText(9);
  return j;
}

}  // namespace internal
}  // namespace strokelab::server
