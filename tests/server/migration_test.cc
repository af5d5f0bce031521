// Schema migrations (schema/migrations/, server/src/store.cc Migrate): an empty file reaches the
// latest version; a file at every earlier version, built by applying only the migrations up to it
// and filled with jobs, tasks, results and cache rows, reaches the latest with that data intact
// (and, from version 1, with the job history that 002_job_events.sql backfills; from any, with the
// points counts that 004_job_points.sql backfills); a file of a newer version is refused untouched;
// a migration that fails half-way leaves the file at its old version.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "migrations.h"
#include "raw_db.h"
#include "serve_child.h"
#include "strokelab/server/store.h"

namespace strokelab::server {
namespace {

using nlohmann::json;
using strokelab::testing::RawDb;
using strokelab::testing::ScratchDirectory;

int Latest() { return internal::Migrations().back().version; }

// Jobs and tasks with version 1's columns, as text, for before/after comparisons (later versions
// add columns: jobs.points in 4, tasks.budget_failures in 5).
std::vector<std::string> DumpJobsAndTasks(const std::string& path) {
  RawDb db(path);
  std::vector<std::string> all;
  const std::pair<const char*, const char*> tables[] = {
      {"jobs", "id, kind, status, spec_json, tasks_total, tasks_done, created_ms, started_ms, finished_ms, error"},
      {"tasks", "id, job_id, idx, key, spec_json, status, lease_token, lease_owner, lease_expires_ms, attempts, finished_ms"}};
  for (const auto& [table, columns] : tables) {
    for (std::string& row : db.Rows(std::string("SELECT ") + columns + " FROM " + table + " ORDER BY rowid"))
      all.push_back(std::string(table) + ": " + row);
  }
  return all;
}

// Every row of every table, as text (blobs as hex), for a file a migration must leave alone.
std::vector<std::string> DumpAllTables(const std::string& path) {
  RawDb db(path);
  std::vector<std::string> all;
  for (const std::string& table : db.Rows("SELECT name FROM sqlite_schema WHERE type = 'table' ORDER BY name")) {
    const std::string select = table == "result_blocks" ? "SELECT *, hex(block)" : "SELECT *";
    for (std::string& row : db.Rows(select + " FROM " + table + " ORDER BY rowid")) all.push_back(table + ": " + row);
  }
  return all;
}

// The result rows as "job|table|row" in paging order: of schema 1-5's per-row table, and through the
// store (schema 6 keeps them in blocks).
const char* const kResultTables[] = {"points", "thresholds"};
std::vector<std::string> ResultRowsInSql(const std::string& path) {
  std::vector<std::string> all;
  for (const std::string& row : RawDb(path).Rows(
           "SELECT job_id || '|' || table_name || '|' || json FROM results ORDER BY job_id, table_name, task_idx, row_idx")) {
    const size_t bar = row.rfind('|', row.find('{'));
    all.push_back(row.substr(0, bar + 1) + json::parse(row.substr(bar + 1)).dump());
  }
  return all;
}
std::vector<std::string> ResultRowsInStore(Store& store) {
  std::vector<int64_t> jobs;
  for (const JobRecord& job : store.ListJobs(100, 0)) jobs.push_back(job.id);
  std::sort(jobs.begin(), jobs.end());
  std::vector<std::string> all;
  for (const int64_t job : jobs) {
    for (const char* table : kResultTables) {  // in name order, as the SQL above
      for (const json& row : store.Results(job, table, {}, 0, 1000).rows)
        all.push_back(std::to_string(job) + "|" + table + "|" + row.dump());
    }
  }
  return all;
}

// A database at `version`: migrations 1..version applied as Store would (each with its
// user_version), then jobs in every state written with plain SQL into the version-1 tables (and,
// from version 4, their points counted as the store counts them).
//   1 sweep     succeeded, 2 tasks done, 3 points each      created 1000, started 1100, finished 1500
//   2 simulate  running, task 0 done (1 point), task 1 leased with token "tok-2" until 10^13
//   3 sweep     queued, 1 task queued
//   4 simulate  failed "solver diverged", task 0 failed
//   5 sweep     cancelled before it started
void BuildAtVersion(const std::string& path, int version) {
  RawDb db(path);
  for (const internal::Migration& m : internal::Migrations()) {
    if (m.version > version) break;
    db.Exec(std::string("BEGIN; ") + m.sql + "; PRAGMA user_version = " + std::to_string(m.version) + "; COMMIT;");
  }
  db.Exec(R"sql(
    INSERT INTO jobs (id, kind, status, spec_json, tasks_total, tasks_done, created_ms, started_ms, finished_ms, error)
    VALUES (1, 'sweep', 'succeeded', '{"kind":"sweep"}', 2, 2, 1000, 1100, 1500, NULL),
           (2, 'simulate', 'running', '{"kind":"simulate"}', 2, 1, 2000, 2100, 0, NULL),
           (3, 'sweep', 'queued', '{"kind":"sweep","name":"later"}', 1, 0, 3000, 0, 0, NULL),
           (4, 'simulate', 'failed', '{"kind":"simulate"}', 1, 0, 4000, 4100, 4200, 'solver diverged'),
           (5, 'sweep', 'cancelled', '{"kind":"sweep"}', 1, 0, 5000, 0, 5100, NULL);
    INSERT INTO tasks (id, job_id, idx, key, spec_json, status, lease_token, lease_owner, lease_expires_ms, attempts,
                       finished_ms)
    VALUES (1, 1, 0, 'k1a', '{}', 'done', NULL, NULL, 0, 1, 1300),
           (2, 1, 1, 'k1b', '{}', 'done', NULL, NULL, 0, 1, 1500),
           (3, 2, 0, 'k2a', '{}', 'done', NULL, NULL, 0, 1, 2200),
           (4, 2, 1, 'k2b', '{}', 'leased', 'tok-2', 'remote:w', 10000000000000, 1, 0),
           (5, 3, 0, 'k3a', '{"f":1}', 'queued', NULL, NULL, 0, 0, 0),
           (6, 4, 0, 'k4a', '{}', 'failed', NULL, NULL, 0, 1, 4200),
           (7, 5, 0, 'k5a', '{}', 'cancelled', NULL, NULL, 0, 0, 5100);
    INSERT INTO results (job_id, table_name, task_idx, row_idx, frequency_hz, amplitude_v, branch, json)
    VALUES (1, 'points', 0, 0, 5, 0.1, 'up', '{"frequency_hz":5,"amplitude_v":0.1,"branch":"up"}'),
           (1, 'points', 0, 1, 6, 0.1, 'up', '{"frequency_hz":6,"amplitude_v":0.1,"branch":"up"}'),
           (1, 'points', 0, 2, 7, 0.1, 'down', '{"frequency_hz":7,"amplitude_v":0.1,"branch":"down"}'),
           (1, 'points', 1, 0, 5, 0.2, 'up', '{"frequency_hz":5,"amplitude_v":0.2,"branch":"up"}'),
           (1, 'points', 1, 1, 6, 0.2, 'up', '{"frequency_hz":6,"amplitude_v":0.2,"branch":"up"}'),
           (1, 'points', 1, 2, 7, 0.2, 'unstable', '{"frequency_hz":7,"amplitude_v":0.2,"branch":"unstable"}'),
           (1, 'thresholds', 0, 3, 5, NULL, NULL, '{"frequency_hz":5}'),
           (2, 'points', 0, 0, 9, 0.3, 'up', '{"frequency_hz":9,"amplitude_v":0.3,"branch":"up"}');
    INSERT INTO cache (key, rows_json, created_ms)
    VALUES ('k1a', '[]', 1300), ('k2a', '[{"table":"points","values":{"frequency_hz":9}}]', 2200);
  )sql");
  // From version 4 the store keeps jobs.points as it stores rows (004_job_points.sql): a file at
  // such a version has them counted.
  if (version >= 4)
    db.Exec("UPDATE jobs SET points = (SELECT count(*) FROM results r WHERE r.job_id = jobs.id AND r.table_name = 'points')");
}

TEST(Migration, EmptyFileReachesTheLatestVersion) {
  ScratchDirectory dir("strokelab-migrate");
  const std::string path = (dir.path() / "jobs.db").string();
  auto store = Store::Open(path);
  EXPECT_EQ(store->SchemaVersion(), Latest());
  RawDb db(path);
  EXPECT_EQ(db.Int("PRAGMA user_version"), Latest());
  EXPECT_EQ(db.Text("SELECT group_concat(name, ',') FROM (SELECT name FROM sqlite_schema WHERE type = 'table' "
                    "ORDER BY name)"),
            "job_events,jobs,result_blocks,tasks");
  EXPECT_EQ(db.Int("SELECT count(*) FROM sqlite_schema WHERE type = 'index' AND name = 'job_events_by_job'"), 1);
  EXPECT_EQ(db.Int("SELECT count(*) FROM job_events"), 0) << "nothing to backfill in an empty file";
}

TEST(Migration, EveryEarlierVersionReachesTheLatestWithItsDataIntact) {
  ASSERT_GE(Latest(), 2) << "this test is about upgrades";
  for (int version = 1; version < Latest(); ++version) {
    SCOPED_TRACE("from version " + std::to_string(version));
    ScratchDirectory dir("strokelab-migrate");
    const std::string path = (dir.path() / "jobs.db").string();
    BuildAtVersion(path, version);
    const std::vector<std::string> before = DumpJobsAndTasks(path);
    ASSERT_EQ(before.size(), 5u + 7u);
    const std::vector<std::string> rows_before = ResultRowsInSql(path);
    ASSERT_EQ(rows_before.size(), 8u);

    auto store = Store::Open(path);
    EXPECT_EQ(store->SchemaVersion(), Latest());
    EXPECT_EQ(DumpJobsAndTasks(path), before) << "a migration changed stored jobs or tasks";
    EXPECT_EQ(ResultRowsInStore(*store), rows_before) << "a migration changed stored result rows";
    EXPECT_EQ(RawDb(path).Int("SELECT count(*) FROM sqlite_schema WHERE name IN ('results', 'cache')"), 0);

    // Through the Store's own reads: statuses, counters, result pages and filters.
    ASSERT_TRUE(store->GetJob(4));
    EXPECT_EQ(store->GetJob(4)->status, JobStatus::kFailed);
    EXPECT_EQ(store->GetJob(4)->error, "solver diverged");
    EXPECT_EQ(store->ListJobs(10, 0).size(), 5u);
    EXPECT_EQ(store->CountResults(1, "points"), 6);
    Store::Filter up;
    up.branch = "up";
    EXPECT_EQ(store->Results(1, "points", up, 0, 100).rows.size(), 4u);
    // The result cache of schema 1-5 ('k1a', 'k2a') is gone; a finished task's key still hits.
    const int64_t again = store->SubmitJob("sweep", json::object(), {{"k1b", json::object()}}, 2400);
    EXPECT_EQ(store->GetJob(again)->status, JobStatus::kSucceeded);
    Store::Filter at_0_2_v;  // job 1's task 1, key 'k1b'
    at_0_2_v.amplitude_v = 0.2;
    EXPECT_EQ(store->Results(again, "points", {}, 0, 100).rows, store->Results(1, "points", at_0_2_v, 0, 100).rows);
    EXPECT_EQ(store->CountResults(again, "points"), 3);

    // The history backfilled from the jobs table (version 1 had none).
    if (version < 2) {
      const auto statuses = [&](int64_t job) {
        std::string out;
        for (const JobEvent& e : store->JobEvents(job)) out += std::string(out.empty() ? "" : ",") + ToString(e.status);
        return out;
      };
      EXPECT_EQ(statuses(1), "queued,running,succeeded");
      EXPECT_EQ(statuses(2), "queued,running");
      EXPECT_EQ(statuses(3), "queued");
      EXPECT_EQ(statuses(4), "queued,running,failed");
      EXPECT_EQ(statuses(5), "queued,cancelled");
      const std::vector<JobEvent> done = store->JobEvents(1);
      EXPECT_EQ(done.back().at_ms, 1500);
      EXPECT_EQ(done.back().points, 6);
      EXPECT_EQ(done.back().tasks_done, 2);
      EXPECT_EQ(store->JobEvents(4).back().reason, "solver diverged");
      EXPECT_EQ(store->JobEvents(1).front().at_ms, 1000);
    }

    // The queue goes on where it was: the leased task completes, the queued one is leased.
    std::vector<JobEvent> seen;
    store->SetJobEventSink([&](const JobEvent& e) { seen.push_back(e); });
    TaskLease held;
    held.task_id = 4;
    held.job_id = 2;
    held.lease_token = "tok-2";
    ASSERT_TRUE(store->CompleteTask(held, {{"points", json{{"frequency_hz", 10.0}}}}, 2500));
    EXPECT_EQ(store->GetJob(2)->status, JobStatus::kSucceeded);
    const auto lease = store->LeaseTask("local-0", 2600, 1000);
    ASSERT_TRUE(lease);
    EXPECT_EQ(lease->job_id, 3);
    EXPECT_EQ(lease->spec, json({{"f", 1}}));
    ASSERT_EQ(seen.size(), 2u);
    EXPECT_EQ(seen[0].job_id, 2);
    EXPECT_EQ(seen[0].status, JobStatus::kSucceeded);
    EXPECT_EQ(seen[0].points, 2);
    EXPECT_EQ(seen[0].reason, "all 2 tasks done");
    EXPECT_EQ(seen[1].job_id, 3);
    EXPECT_EQ(seen[1].status, JobStatus::kRunning);
    EXPECT_EQ(seen[1].reason, "first task leased by local-0");
    EXPECT_EQ(store->JobEvents(2).back().id, seen[0].id) << "the sink sees what is stored";

    store.reset();
    EXPECT_EQ(RawDb(path).Text("PRAGMA integrity_check"), "ok");
  }
}

// 003_result_units.sql: sweep points stored with h_re and h_im (version 2) read with the names of
// today's columns, h_re_n_per_v and h_im_n_per_v, values (and a null) kept; other rows untouched.
TEST(Migration, StoredPointsTakeTheFrfColumnsUnitNames) {
  ASSERT_GE(Latest(), 3);
  ScratchDirectory dir("strokelab-migrate");
  const std::string path = (dir.path() / "jobs.db").string();
  BuildAtVersion(path, 2);
  RawDb(path).Exec(R"sql(
    INSERT INTO results (job_id, table_name, task_idx, row_idx, frequency_hz, amplitude_v, branch, json)
    VALUES (1, 'points', 2, 0, 8, 0.3, 'up', '{"frequency_hz":8,"amplitude_v":0.3,"branch":"up","h_re":-0.25,"h_im":null}');
  )sql");
  auto store = Store::Open(path);
  Store::Filter at;
  at.frequency_min_hz = 8;
  const std::vector<json> rows = store->Results(1, "points", at, 0, 10).rows;
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0], json::parse(R"({"frequency_hz":8,"amplitude_v":0.3,"branch":"up","h_re_n_per_v":-0.25,
                                     "h_im_n_per_v":null})"));
  EXPECT_EQ(store->Results(1, "points", {}, 0, 10).rows[0], json::parse(R"({"frequency_hz":5,"amplitude_v":0.1,"branch":"up"})"));
}

// 004_job_points.sql: every job counts its stored points rows (the results of table "points", not
// thresholds), and the store goes on counting from there: job 2's event when its last task
// completes with one more point says 2 (EveryEarlierVersionReachesTheLatestWithItsDataIntact).
TEST(Migration, JobsCountTheirStoredPoints) {
  ASSERT_GE(Latest(), 4);
  ScratchDirectory dir("strokelab-migrate");
  const std::string path = (dir.path() / "jobs.db").string();
  BuildAtVersion(path, 3);
  Store::Open(path);
  EXPECT_EQ(RawDb(path).Rows("SELECT id, points FROM jobs ORDER BY id"),
            (std::vector<std::string>{"1|6", "2|1", "3|0", "4|0", "5|0"}));
}

TEST(Migration, NewerVersionIsRefusedAndLeftUntouched) {
  ScratchDirectory dir("strokelab-migrate");
  const std::string path = (dir.path() / "jobs.db").string();
  BuildAtVersion(path, 5);
  Store::Open(path);  // to the latest version
  const int newer = Latest() + 1;
  RawDb(path).Exec("PRAGMA user_version = " + std::to_string(newer));
  const std::vector<std::string> before = DumpAllTables(path);
  try {
    Store::Open(path);
    FAIL() << "opened a file of schema version " << newer;
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "cannot open database " + path + ": its schema version " +
                                         std::to_string(newer) + " is newer than this strokelab knows (up to " +
                                         std::to_string(Latest()) + "); use a newer strokelab, or another database file");
  }
  EXPECT_EQ(RawDb(path).Int("PRAGMA user_version"), newer);
  EXPECT_EQ(DumpAllTables(path), before);
}

TEST(Migration, AFailingMigrationRollsBackToTheOldVersion) {
  ScratchDirectory dir("strokelab-migrate");
  const std::string path = (dir.path() / "jobs.db").string();
  BuildAtVersion(path, 1);
  // Someone made an index under the name 002 uses: its CREATE TABLE succeeds, its CREATE INDEX fails.
  RawDb(path).Exec("CREATE INDEX job_events_by_job ON jobs (kind)");
  const std::vector<std::string> before = DumpAllTables(path);
  try {
    Store::Open(path);
    FAIL() << "migrated over a clashing index";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "cannot open database " + path +
                                         ": migration 002_job_events.sql failed: index job_events_by_job already exists");
  }
  {
    RawDb db(path);
    EXPECT_EQ(db.Int("PRAGMA user_version"), 1);
    EXPECT_EQ(db.Int("SELECT count(*) FROM sqlite_schema WHERE name = 'job_events'"), 0)
        << "the table 002 created before failing was rolled back";
    EXPECT_EQ(db.Text("PRAGMA integrity_check"), "ok");
    db.Exec("DROP INDEX job_events_by_job");
  }
  EXPECT_EQ(DumpAllTables(path), before);
  // With the clash gone, the same file migrates.
  EXPECT_EQ(Store::Open(path)->SchemaVersion(), Latest());
  EXPECT_EQ(RawDb(path).Int("SELECT count(*) FROM job_events"), 11);
}

}  // namespace
}  // namespace strokelab::server
