// The store's task queue (store.h): leasing the oldest leasable task, renewing and releasing leases,
// and completing or failing a task only while its lease is held.
#include <sqlite3.h>

#include <algorithm>
#include <cstdint>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "store_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/server/store.h"
#include "strokelab/base/json_parse.h"

namespace strokelab::server::internal {

using nlohmann::json;

// The oldest queued task and the oldest expired lease; the older of the two wins (0: none). Tasks
// of finished jobs are never queued or leased (cancel and fail close them), the join is a guard.
int64_t SqliteStore::OldestLeasable(Connection& c, int64_t now_ms) {
  int64_t queued = 0, expired = 0;
  {
    Stmt s = c.Prepare(
        "SELECT t.id FROM tasks t JOIN jobs j ON j.id = t.job_id "
        "WHERE t.status = 'queued' AND j.status IN ('queued', 'running') ORDER BY t.id LIMIT 1");
    if (s.Step()) queued = s.ColInt(0);
  }
  {
    Stmt s = c.Prepare(
        "SELECT t.id FROM tasks t JOIN jobs j ON j.id = t.job_id "
        "WHERE t.status = 'leased' AND t.lease_expires_ms <= ?1 AND j.status IN ('queued', 'running') "
        "ORDER BY t.id LIMIT 1");
    if (s.Int(1, now_ms).Step()) expired = s.ColInt(0);
  }
  return queued == 0 ? expired : expired == 0 ? queued : std::min(queued, expired);
}

std::optional<TaskLease> SqliteStore::LeaseTask(const std::string& worker, int64_t now_ms, int64_t lease_ms) {
  {  // An empty queue is seen on a reader: idle workers' polls take no write lock.
    ReaderPool::Handle reader = readers_.Acquire();
    ReadSnapshot snapshot(*reader);
    if (OldestLeasable(*reader, now_ms) == 0) return std::nullopt;
  }
  TaskLease lease;
  std::string spec_json;  // parsed after the write lock is released
  {
    std::lock_guard lock(write_mu_);
    Transaction tx(*this);
    lease.task_id = OldestLeasable(writer_, now_ms);  // again: another worker may have taken that one
    if (lease.task_id == 0) return std::nullopt;
    lease.lease_token = NewToken();
    lease.expires_ms = now_ms + lease_ms;
    {
      Stmt s = writer_.Prepare(
          "UPDATE tasks SET status = 'leased', lease_token = ?2, lease_owner = ?3, lease_expires_ms = ?4, "
          "attempts = attempts + 1 WHERE id = ?1");
      s.Int(1, lease.task_id).Text(2, lease.lease_token).Text(3, worker).Int(4, lease.expires_ms).Run();
    }
    {
      Stmt s = writer_.Prepare(
          "SELECT t.job_id, t.idx, j.kind, t.spec_json FROM tasks t JOIN jobs j ON j.id = t.job_id WHERE t.id = ?1");
      if (!s.Int(1, lease.task_id).Step()) BrokenInvariant("job store: leased task vanished");
      lease.job_id = s.ColInt(0);
      lease.index = static_cast<int>(s.ColInt(1));
      lease.kind = s.ColText(2);
      spec_json = s.ColText(3);
    }
    {
      Stmt s = writer_.Prepare("UPDATE jobs SET status = 'running', started_ms = ?2 WHERE id = ?1 AND status = 'queued'");
      s.Int(1, lease.job_id).Int(2, now_ms).Run();
    }
    if (writer_.Changes() == 1)
      RecordEvent(lease.job_id, JobStatus::kRunning, now_ms, "first task leased by " + worker);
    tx.Commit();
  }
  lease.spec = ParseJson(spec_json);
  return lease;
}

int SqliteStore::ReleaseLeases(const std::string& owner_prefix) {
  std::lock_guard lock(write_mu_);
  Stmt s = writer_.Prepare(
      "UPDATE tasks SET status = 'queued', lease_token = NULL, lease_owner = NULL, lease_expires_ms = 0 "
      "WHERE status = 'leased' AND substr(lease_owner, 1, length(?1)) = ?1");
  s.Text(1, owner_prefix).Run();
  return writer_.Changes();
}

bool SqliteStore::RenewLease(const TaskLease& lease, int64_t now_ms, int64_t lease_ms) {
  std::lock_guard lock(write_mu_);
  Stmt s = writer_.Prepare(
      "UPDATE tasks SET lease_expires_ms = ?4 "
      "WHERE id = ?1 AND status = 'leased' AND lease_token = ?2 AND lease_expires_ms > ?3");
  s.Int(1, lease.task_id).Text(2, lease.lease_token).Int(3, now_ms).Int(4, now_ms + lease_ms).Run();
  return writer_.Changes() == 1;
}

std::optional<json> SqliteStore::LeasedTaskSpec(const TaskLease& lease, int64_t now_ms) {
  std::string spec_json;
  {
    ReaderPool::Handle reader = readers_.Acquire();
    ReadSnapshot snapshot(*reader);
    if (!CheckLease(*reader, lease, now_ms)) return std::nullopt;
    Stmt s = reader->Prepare("SELECT spec_json FROM tasks WHERE id = ?1");
    if (!s.Int(1, lease.task_id).Step()) return std::nullopt;
    spec_json = s.ColText(0);
  }
  return ParseJson(spec_json);
}

bool SqliteStore::CompleteTask(const TaskLease& lease, const TaskResult& result, int64_t now_ms) {
  const EncodedRows encoded = EncodeRows(result);  // before the write lock: other writers go on meanwhile
  std::lock_guard lock(write_mu_);
  Transaction tx(*this);
  const std::optional<HeldTask> held = CheckLease(writer_, lease, now_ms);
  if (!held) return false;  // rolled back: nothing written
  InsertResultRows(held->job_id, held->index, encoded);
  {
    Stmt s = writer_.Prepare("UPDATE tasks SET status = 'done', lease_token = NULL, finished_ms = ?2 WHERE id = ?1");
    s.Int(1, lease.task_id).Int(2, now_ms).Run();
  }
  bool finished = false;
  int64_t tasks_done = 0;
  {
    Stmt s = writer_.Prepare(
        "UPDATE jobs SET tasks_done = tasks_done + 1, points = points + ?3, "
        "status = CASE WHEN tasks_done + 1 = tasks_total THEN 'succeeded' ELSE status END, "
        "finished_ms = CASE WHEN tasks_done + 1 = tasks_total THEN ?2 ELSE finished_ms END WHERE id = ?1 "
        "RETURNING status = 'succeeded', tasks_done");
    if (s.Int(1, held->job_id).Int(2, now_ms).Int(3, encoded.points).Step()) {
      finished = s.ColInt(0) == 1;
      tasks_done = s.ColInt(1);
    }
    s.Run();
  }
  if (finished)
    RecordEvent(held->job_id, JobStatus::kSucceeded, now_ms, "all " + std::to_string(tasks_done) + " tasks done");
  tx.Commit();
  return true;
}

void SqliteStore::FailTask(const TaskLease& lease, const std::string& error, int64_t now_ms) {
  std::lock_guard lock(write_mu_);
  Transaction tx(*this);
  const std::optional<HeldTask> held = CheckLease(writer_, lease, now_ms);
  if (!held) return;  // lost lease: whoever holds the task now reports its own outcome
  {
    Stmt s = writer_.Prepare("UPDATE tasks SET status = 'failed', lease_token = NULL, finished_ms = ?2 WHERE id = ?1");
    s.Int(1, lease.task_id).Int(2, now_ms).Run();
  }
  {
    Stmt s = writer_.Prepare(
        "UPDATE jobs SET status = 'failed', error = ?2, finished_ms = ?3 "
        "WHERE id = ?1 AND status IN ('queued', 'running')");
    s.Int(1, held->job_id).Text(2, error).Int(3, now_ms).Run();
  }
  if (writer_.Changes() == 1) RecordEvent(held->job_id, JobStatus::kFailed, now_ms, error);
  {
    Stmt s = writer_.Prepare(
        "UPDATE tasks SET status = 'cancelled', lease_token = NULL, finished_ms = ?2 "
        "WHERE job_id = ?1 AND status IN ('queued', 'leased')");
    s.Int(1, held->job_id).Int(2, now_ms).Run();
  }
  tx.Commit();
}

bool SqliteStore::FailTaskOnBudget(const TaskLease& lease, const std::string& error, int64_t now_ms) {
  int64_t failures = 0;
  {
    std::lock_guard lock(write_mu_);
    Transaction tx(*this);
    if (!CheckLease(writer_, lease, now_ms)) return false;
    Stmt s = writer_.Prepare("UPDATE tasks SET budget_failures = budget_failures + 1 WHERE id = ?1 RETURNING budget_failures");
    if (s.Int(1, lease.task_id).Step()) failures = s.ColInt(0);
    s.Run();
    if (failures < kMaxBudgetFailures) {
      Stmt q = writer_.Prepare(
          "UPDATE tasks SET status = 'queued', lease_token = NULL, lease_owner = NULL, lease_expires_ms = 0 WHERE id = ?1");
      q.Int(1, lease.task_id).Run();
      tx.Commit();
      return false;
    }
    tx.Commit();
  }
  FailTask(lease, "work budget spent twice (" + std::to_string(failures) + " leases): " + error, now_ms);
  return true;
}

// The task row behind `lease` if the lease is still held: the task is leased with this token
// (a new lease, a cancel or a completion changes or clears it) and the lease has not expired.
std::optional<SqliteStore::HeldTask> SqliteStore::CheckLease(Connection& c, const TaskLease& lease, int64_t now_ms) {
  Stmt s = c.Prepare("SELECT job_id, idx FROM tasks "
                   "WHERE id = ?1 AND status = 'leased' AND lease_token = ?2 AND lease_expires_ms > ?3");
  if (!s.Int(1, lease.task_id).Text(2, lease.lease_token).Int(3, now_ms).Step()) return std::nullopt;
  HeldTask held{s.ColInt(0), s.ColInt(1)};
  if (held.job_id != lease.job_id) return std::nullopt;
  return held;
}

std::string SqliteStore::NewToken() {
  // 128 bits from the OS entropy source, as 32 hex digits.
  static constexpr char kHex[] = "0123456789abcdef";
  std::string token;
  for (int i = 0; i < 4; ++i) {
    uint32_t v = random_();
    for (int k = 0; k < 8; ++k, v >>= 4) token.push_back(kHex[v & 0xf]);
  }
  return token;
}

}  // namespace strokelab::server::internal
