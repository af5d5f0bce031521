// `strokelab backup` (clients/cli/cmd_backup.cc) against a running `strokelab serve`: a sweep runs on
// one in-process worker while backups are taken one after another (30 ms apart). Each backup must
// be a self-contained file (no -wal beside it) that passes PRAGMA integrity_check, at the latest
// schema version, and a consistent snapshot: per job, tasks_done is the number of done tasks and the
// status follows from it; a done task's result rows are exactly the rows the store holds for it when
// the service has stopped, a task not done has none; the job's last recorded event is its status. And
// its refusals, one line each.
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "raw_db.h"
#include "serve_child.h"

namespace strokelab::testing {
namespace {

using nlohmann::json;

constexpr int kLatestSchema = 6;  // schema/migrations/006_result_blocks.sql
constexpr int kAmplitudes = 40;   // the sweep's amplitude points: one task each (thresholds off)

struct CliRun {
  int exit_code;
  std::string output;  // stdout and stderr
};

CliRun RunCli(const std::string& args) {
  const std::string command = std::string(STROKELAB_BINARY) + " " + args + " 2>&1";
  FILE* pipe = ::popen(command.c_str(), "r");
  if (!pipe) throw std::runtime_error("popen failed");
  std::string output;
  char buffer[4096];
  for (size_t n; (n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0;) output.append(buffer, n);
  const int status = ::pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128, output};
}

// The result blocks of each task of `job`, as "task_idx -> blocks (table|rows|bytes in hex, by table)".
std::map<int64_t, std::vector<std::string>> RowsByTask(RawDb& db, int64_t job) {
  std::map<int64_t, std::vector<std::string>> out;
  for (const std::string& row :
       db.Rows("SELECT task_idx, table_name || '|' || rows || '|' || hex(block) FROM result_blocks WHERE job_id = " +
               std::to_string(job) + " ORDER BY task_idx, table_name")) {
    const size_t bar = row.find('|');
    out[std::stoll(row.substr(0, bar))].push_back(row.substr(bar + 1));
  }
  return out;
}

// Checks one backup against the database the service left (the job finished or not: a task done in
// the backup is done there too); returns the job's tasks_done in the backup.
int64_t CheckBackup(const fs::path& backup, const fs::path& final_db, int64_t job) {
  EXPECT_FALSE(fs::exists(backup.string() + "-wal")) << "not self-contained";
  RawDb db(backup.string(), SQLITE_OPEN_READONLY);
  EXPECT_EQ(db.Text("PRAGMA integrity_check"), "ok");
  EXPECT_EQ(db.Text("PRAGMA journal_mode"), "delete");
  EXPECT_EQ(db.Int("PRAGMA user_version"), kLatestSchema);
  const std::string id = std::to_string(job);
  const int64_t total = db.Int("SELECT tasks_total FROM jobs WHERE id = " + id);
  const int64_t done = db.Int("SELECT tasks_done FROM jobs WHERE id = " + id);
  const std::string status = db.Text("SELECT status FROM jobs WHERE id = " + id);
  EXPECT_EQ(done, db.Int("SELECT count(*) FROM tasks WHERE status = 'done' AND job_id = " + id));
  EXPECT_EQ(status, done == total ? "succeeded" : (done == 0 ? status : "running"));
  EXPECT_EQ(db.Text("SELECT status FROM job_events WHERE job_id = " + id + " ORDER BY id DESC LIMIT 1"), status);

  RawDb final(final_db.string(), SQLITE_OPEN_READONLY);
  const auto expected = RowsByTask(final, job);
  const auto rows = RowsByTask(db, job);
  for (const std::string& task : db.Rows("SELECT idx, status FROM tasks WHERE job_id = " + id)) {
    const int64_t idx = std::stoll(task.substr(0, task.find('|')));
    const bool is_done = task.substr(task.find('|') + 1) == "done";
    if (is_done) EXPECT_EQ(rows.count(idx) ? rows.at(idx) : std::vector<std::string>{}, expected.at(idx)) << task;
    else EXPECT_EQ(rows.count(idx), 0u) << "rows of a task not done: " << task;
  }
  return done;
}

TEST(Backup, SnapshotsOfARunningServiceAreWholeAndConsistent) {
  ScratchDirectory dir("strokelab-backup");
  const fs::path db = dir.path() / "jobs.db";
  // One worker and 2,000 frequencies: the sweep would run ~10 s, far longer than the backups need on
  // any machine (240 frequencies took 2 s, then 1 s once the service reached the CLI's speed, and
  // under load the job finished before three backups). The backups stop once three fell mid-run;
  // the server's stop leaves the job unfinished, which the checks allow for.
  ServeChild server(db, dir.path() / "serve.log", {"--workers", "1", "--quiet"});
  auto client = server.Client();
  const json sweep = {{"kind", "sweep"},
                      {"model", "paper"},
                      {"thresholds", false},
                      {"grid", {{"frequency_hz", {{"from", 5}, {"to", 50}, {"points", 2000}}},
                                {"amplitude_v", {{"from", 0.1}, {"to", 0.6}, {"points", kAmplitudes}}}}}};
  auto submitted = client->Post("/v1/jobs", sweep.dump(), "application/json");
  ASSERT_TRUE(submitted && submitted->status == 201);
  const int64_t job = json::parse(submitted->body).at("id");

  std::vector<fs::path> backups;
  int mid_run_taken = 0;
  for (int i = 0; i < 600 && mid_run_taken < 3; ++i) {
    const fs::path to = dir.path() / ("backup_" + std::to_string(i) + ".db");
    const CliRun run = RunCli("backup --db " + db.string() + " --to " + to.string());
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("integrity ok -> " + to.string()), std::string::npos) << run.output;
    backups.push_back(to);
    const int64_t done = RawDb(to.string(), SQLITE_OPEN_READONLY).Int("SELECT tasks_done FROM jobs WHERE id = " +
                                                                      std::to_string(job));
    if (done > 0 && done < kAmplitudes) ++mid_run_taken;
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
  }
  ASSERT_EQ(server.Stop(), 0);

  int mid_run = 0;
  int64_t previous = 0;
  for (const fs::path& backup : backups) {
    SCOPED_TRACE(backup.filename().string());
    const int64_t done = CheckBackup(backup, db, job);
    EXPECT_GE(done, previous) << "backups go back in time";
    previous = done;
    if (done > 0 && done < kAmplitudes) ++mid_run;
  }
  std::printf("[          ] %zu backups, %d of them mid-run\n", backups.size(), mid_run);
  EXPECT_GE(mid_run, 3) << "the sweep finished too fast to back it up while it ran";
}

TEST(Backup, RefusesWhatItCannotCopyInOneLine) {
  ScratchDirectory dir("strokelab-backup");
  const std::string missing = (dir.path() / "missing.db").string();
  const std::string other = (dir.path() / "other.db").string();
  RawDb(other).Exec("CREATE TABLE t (x)");
  const std::string store = (dir.path() / "store.db").string();
  {
    ServeChild server(store, dir.path() / "serve.log", {"--workers", "0", "--quiet"});
  }
  const std::string taken = (dir.path() / "taken.db").string();
  std::ofstream(taken) << "x";
  const struct {
    std::string args, message;
  } refusals[] = {
      {"backup --to " + taken, "strokelab: error: --db: required: the job store to copy\n"},
      {"backup --db " + store, "strokelab: error: --to: required: the backup file to write\n"},
      {"backup --db " + missing + " --to x.db", "strokelab: error: --db: " + missing + ": no such database file\n"},
      {"backup --db " + other + " --to " + taken + ".2",
       "strokelab: error: --db: " + other + ": not a strokelab job store (schema version 0, no jobs table)\n"},
      {"backup --db " + store + " --to " + taken,
       "strokelab: error: --to: " + taken + " exists (--force overwrites it)\n"},
      {"backup --db " + store + " --to " + store, "strokelab: error: --to: is the database itself\n"},
  };
  for (const auto& r : refusals) {
    const CliRun run = RunCli(r.args);
    EXPECT_EQ(run.exit_code, 2) << r.args;
    EXPECT_EQ(run.output, r.message) << r.args;
  }
  EXPECT_FALSE(fs::exists(taken + ".2")) << "nothing written for a refused copy";
  const CliRun forced = RunCli("backup --db " + store + " --to " + taken + " --force");
  EXPECT_EQ(forced.exit_code, 0) << forced.output;
  EXPECT_EQ(RawDb(taken).Int("PRAGMA user_version"), kLatestSchema);
}

// The README's `--to backups/strokelab-DATE.db`: a folder that does not exist yet is created.
TEST(Backup, CreatesTheFolderOfTo) {
  ScratchDirectory dir("strokelab-backup");
  const std::string store = (dir.path() / "store.db").string();
  {
    ServeChild server(store, dir.path() / "serve.log", {"--workers", "0", "--quiet"});
  }
  const fs::path to = dir.path() / "backups" / "daily" / "store.db";
  const CliRun run = RunCli("backup --db " + store + " --to " + to.string());
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_EQ(RawDb(to.string()).Int("PRAGMA user_version"), kLatestSchema);
}

}  // namespace
}  // namespace strokelab::testing
