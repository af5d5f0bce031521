// The service as separate processes on loopback: the real `strokelab serve` and `strokelab worker`
// binaries started as children, talked to over HTTP on 127.0.0.1, killed with SIGKILL mid-run.
//
//   CrashAndResume: a 4,000-point sweep on one in-process worker; the server is SIGKILLed three
//     times at different progress levels and restarted on the same file; the job finishes with
//     every point exactly once and bitwise equal to a single-process CLI sweep.
//   RemoteWorkerKilledMidLease: a server with no workers of its own and 2 s leases, three remote
//     worker processes, one SIGKILLed while it holds a lease; its task is leased again after expiry
//     and every task's rows are stored exactly once.
//   WorkerTokens: a worker with a read token is refused (exits non-zero saying so); with a worker
//     token it completes the job.
//
// Every child is SIGKILLed and reaped when its guard goes out of scope, so a failing test leaves no
// process behind; ports are chosen by the server (--port 0) and read from its "serving" line
// (helpers in tests/process/, shared with tests/fault/).
#include <gtest/gtest.h>
#include <signal.h>

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "process/child.h"
#include "process/service.h"
#include "process/store_file.h"
#include "process/sweep_checks.h"
#include "strokelab/model/model.h"
#include "strokelab/report/sweep_tables.h"
#include "strokelab/sweep/sweep.h"

namespace {

using namespace strokelab::test_process;

// ---------------------------------------------------------------------------------------------

TEST(ServiceProcess, CrashAndResume) {
  const auto test_start = Clock::now();
  ScratchDir dir;
  const std::string db = (dir.path() / "jobs.db").string();
  const std::vector<std::string> serve_args = {"--workers", "1", "--db", db};
  constexpr int kFrequencies = 400, kAmplitudes = 10;  // ~40 ms a task here: the kills come mid-job

  Server server = StartServer(dir.path(), "serve-0", serve_args);
  const int64_t id = Submit(*Client(server), SweepJob(kFrequencies, kAmplitudes, true));
  const json first = GetJson(*Client(server), "/v1/jobs/" + std::to_string(id));
  const int total = first.at("progress").at("total");
  ASSERT_EQ(total, kAmplitudes + (kFrequencies + 15) / 16);  // rows + threshold column chunks

  // Kill at about 1/10, 2/5 and 3/4 of the tasks.
  const std::vector<int> targets = {2, total * 2 / 5, total * 3 / 4};
  int kills_with_lease = 0;
  for (size_t k = 0; k < targets.size(); ++k) {
    auto client = Client(server);
    int seen = 0;
    const auto wait_start = Clock::now();
    for (;;) {
      const json job = GetJson(*client, "/v1/jobs/" + std::to_string(id));
      seen = job.at("progress").at("done");
      ASSERT_TRUE(job.at("status") == "running" || job.at("status") == "queued")
          << "the job finished before kill " << k + 1 << " (make the grid heavier): " << job.dump();
      if (seen >= targets[k]) break;
      ASSERT_LT(SecondsSince(wait_start), 30) << job.dump();
      SleepMs(20);
    }
    // Kill with a task in flight: just after a completion the worker is between two tasks, and in a
    // slow build (ThreadSanitizer) for longer than the poll above (3 kills of 3 found no lease there).
    for (const auto wait_lease = Clock::now(); SecondsSince(wait_lease) < 5; SleepMs(2)) {
      auto metrics = client->Get("/metrics");
      if (metrics && metrics->body.find("\nstrokelab_tasks_leased 0\n") == std::string::npos) break;
    }
    server.child->Signal(SIGKILL);
    ASSERT_EQ(server.child->WaitExit(10), 128 + SIGKILL);

    // What the dead server left in the file: the job unfinished, a lease held by its worker.
    int done_at_kill = 0, leased_at_kill = 0;
    {
      Db file(db);
      done_at_kill = std::stoi(file.One("SELECT tasks_done FROM jobs WHERE id = " + std::to_string(id)));
      EXPECT_EQ(file.One("SELECT status FROM jobs WHERE id = " + std::to_string(id)), "running");
      leased_at_kill = std::stoi(file.One("SELECT count(*) FROM tasks WHERE status = 'leased' AND lease_owner LIKE 'local-%'"));
    }
    EXPECT_GE(done_at_kill, seen);
    kills_with_lease += leased_at_kill > 0;
    EXPECT_LT(done_at_kill, total) << "kill " << k + 1 << " came after the job had finished";

    const auto restart = Clock::now();
    server = StartServer(dir.path(), "serve-" + std::to_string(k + 1), serve_args);
    if (leased_at_kill > 0) {
      EXPECT_NE(server.child->Log().find("\"released_leases\":" + std::to_string(leased_at_kill)), std::string::npos)
          << server.child->Log();
    }
    // The restarted server resumes at once (its dead worker's lease is released, not waited out).
    auto c = Client(server);
    double resumed_s = -1;
    for (;;) {
      const json job = GetJson(*c, "/v1/jobs/" + std::to_string(id));
      if (job.at("progress").at("done").get<int>() > done_at_kill || job.at("status") == "succeeded") {
        resumed_s = SecondsSince(restart);
        break;
      }
      ASSERT_LT(SecondsSince(restart), 20) << "no progress after restart " << k + 1 << ": " << job.dump();
      SleepMs(5);
    }
    EXPECT_LT(resumed_s, 10);
    std::printf("kill %zu: at %d/%d tasks done (%d leased); restart to next task done: %.3f s\n", k + 1,
                done_at_kill, total, leased_at_kill, resumed_s);
  }

  // A kill between two tasks leaves no lease; the worker holds one nearly all the time.
  EXPECT_GE(kills_with_lease, 1) << "no kill caught a task in flight";

  auto client = Client(server);
  const json job = WaitForFinish(*client, id, 30);
  ASSERT_EQ(job.at("status"), "succeeded") << job.dump();
  EXPECT_EQ(job.at("progress").at("done"), total);

  const std::vector<json> points = FetchPoints(*client, id);
  ExpectEachGridPointOnce(points, kFrequencies * kAmplitudes);
  EXPECT_EQ(FetchPoints(*client, id, "up").size(), size_t{kFrequencies * kAmplitudes});
  EXPECT_EQ(FetchPoints(*client, id, "down").size(), size_t{kFrequencies * kAmplitudes});
  {
    Db file(db);
    // Leases granted beyond one per task: one per kill that caught a task in flight.
    std::printf("task leases granted: %s for %d tasks\n",
                file.One("SELECT sum(attempts) FROM tasks WHERE job_id = " + std::to_string(id)).c_str(), total);
  }

  const double service_s = SecondsSince(test_start);
  const json reference = CliSweep(dir.path(), kFrequencies, kAmplitudes);
  ExpectSameRows(points, reference.at("points"), "points");
  ExpectSameMap(*client, id, reference);
  std::printf("%zu point rows; service part %.2f s, whole test %.2f s\n", points.size(), service_s,
              SecondsSince(test_start));

  server.child->Signal(SIGTERM);
  EXPECT_EQ(server.child->WaitExit(20), 0) << server.child->Log();
}

TEST(ServiceProcess, RemoteWorkerKilledMidLease) {
  const auto test_start = Clock::now();
  ScratchDir dir;
  const std::string db = (dir.path() / "jobs.db").string();
  constexpr int kFrequencies = 200, kAmplitudes = 27;  // 27 rows + 13 column chunks = 40 tasks
  constexpr int64_t kLeaseMs = 2000;

  Server server = StartServer(dir.path(), "serve", {"--workers", "0", "--lease-s", "2", "--db", db, "--quiet"});
  auto client = Client(server);
  const int64_t id = Submit(*client, SweepJob(kFrequencies, kAmplitudes, true));
  const int total = GetJson(*client, "/v1/jobs/" + std::to_string(id)).at("progress").at("total");
  ASSERT_EQ(total, 40);

  std::vector<std::unique_ptr<Child>> survivors;
  auto victim = StartWorker(dir.path(), server, "victim", {"--threads", "1"});
  survivors.push_back(StartWorker(dir.path(), server, "w1", {"--threads", "1"}));
  survivors.push_back(StartWorker(dir.path(), server, "w2", {"--threads", "1"}));

  // Kill the victim while it holds a lease: freeze it (SIGSTOP) when the file shows it holding one,
  // let requests in flight settle, and kill it only if it still holds that lease; else thaw, retry.
  std::string victim_task;
  int64_t victim_expires_ms = 0;
  {
    Db file(db);
    const auto start = Clock::now();
    while (victim_task.empty()) {
      ASSERT_LT(SecondsSince(start), 20) << "the victim never held a lease:\n" << victim->Log();
      ASSERT_FALSE(victim->Poll()) << victim->Log();
      const auto held = file.Query(
          "SELECT id, lease_token, lease_expires_ms FROM tasks WHERE status = 'leased' AND lease_owner = 'remote:victim-0'");
      if (held.empty()) {
        SleepMs(2);
        continue;
      }
      victim->Signal(SIGSTOP);
      SleepMs(100);
      const auto still = file.Query("SELECT lease_token FROM tasks WHERE id = " + held[0][0] +
                                    " AND status = 'leased' AND lease_owner = 'remote:victim-0'");
      if (!still.empty() && still[0][0] == held[0][1]) {
        victim->Kill();
        victim_task = held[0][0];
        victim_expires_ms = std::stoll(held[0][2]);
      } else {
        victim->Signal(SIGCONT);
      }
    }
  }
  const double killed_at_s = SecondsSince(test_start);

  const json job = WaitForFinish(*client, id, 40);
  const double finished_at_s = SecondsSince(test_start);
  ASSERT_EQ(job.at("status"), "succeeded") << job.dump();

  // The victim's task: leased again after its lease expired, and completed by another worker.
  Db file(db);
  const auto task = file.Query("SELECT status, attempts, lease_owner, finished_ms FROM tasks WHERE id = " + victim_task);
  ASSERT_EQ(task.size(), 1u);
  EXPECT_EQ(task[0][0], "done");
  EXPECT_GE(std::stoi(task[0][1]), 2);
  EXPECT_NE(task[0][2], "remote:victim-0");
  EXPECT_GE(std::stoll(task[0][3]), victim_expires_ms) << "taken over before the lease expired";
  EXPECT_EQ(file.One("SELECT count(*) FROM tasks WHERE job_id = " + std::to_string(id) + " AND status != 'done'"), "0");

  // Each task's rows exactly once: one block per table it has rows of (a second completion would
  // fail the block's UNIQUE key), and the same rows as a run without kills.
  const auto per_task = file.Query("SELECT task_idx, count(*), count(DISTINCT table_name) FROM result_blocks WHERE job_id = " +
                                   std::to_string(id) + " GROUP BY task_idx ORDER BY task_idx");
  ASSERT_EQ(per_task.size(), size_t(total));
  for (const auto& t : per_task) EXPECT_EQ(t[1], t[2]) << "task " << t[0];

  const std::vector<json> points = FetchPoints(*client, id);
  ExpectEachGridPointOnce(points, kFrequencies * kAmplitudes);
  const json reference = CliSweep(dir.path(), kFrequencies, kAmplitudes);
  ExpectSameRows(points, reference.at("points"), "points");
  ExpectSameMap(*client, id, reference);

  // Who did what: the survivors' own counts agree with the file; all tasks are accounted for.
  int by_workers = std::stoi(file.One("SELECT count(*) FROM tasks WHERE job_id = " + std::to_string(id) +
                                      " AND status = 'done' AND lease_owner = 'remote:victim-0'"));
  const int by_victim = by_workers;
  for (size_t i = 0; i < survivors.size(); ++i) {
    const std::string name = "w" + std::to_string(i + 1);
    survivors[i]->Signal(SIGTERM);
    EXPECT_EQ(survivors[i]->WaitExit(20), 0) << survivors[i]->Log();
    const int in_file = std::stoi(file.One("SELECT count(*) FROM tasks WHERE job_id = " + std::to_string(id) +
                                           " AND status = 'done' AND lease_owner = 'remote:" + name + "-0'"));
    EXPECT_NE(survivors[i]->Log().find("worker " + name + ": " + std::to_string(in_file) + " tasks completed"),
              std::string::npos)
        << survivors[i]->Log();
    by_workers += in_file;
  }
  EXPECT_EQ(by_workers, total);
  std::printf("victim killed holding task %s at %.2f s (had completed %d); job done at %.2f s (lease %lld ms); "
              "whole test %.2f s\n",
              victim_task.c_str(), killed_at_s, by_victim, finished_at_s, static_cast<long long>(kLeaseMs),
              SecondsSince(test_start));
}

TEST(ServiceProcess, WorkerTokens) {
  const auto test_start = Clock::now();
  ScratchDir dir;
  const std::string submit = "submit-token-0123456789abcdef", read = "read-token-0123456789abcdef",
                    worker = "worker-token-0123456789abcdef";
  {
    std::ofstream tokens(dir.path() / "tokens");
    tokens << "# roles and tokens\nsubmit " << submit << "\nread " << read << "\nworker " << worker << "\n";
  }
  Server server = StartServer(dir.path(), "serve",
                              {"--workers", "0", "--db", (dir.path() / "jobs.db").string(), "--token-file",
                               (dir.path() / "tokens").string(), "--quiet"});
  auto client = Client(server);
  constexpr int kFrequencies = 20, kAmplitudes = 2;
  const json job = SweepJob(kFrequencies, kAmplitudes, false);  // 2 tasks

  // Submitting: only the submit token.
  for (const auto& [token, status] : std::vector<std::pair<std::string, int>>{
           {"", 401}, {"wrong-token-0123456789abcdef", 401}, {read, 403}, {worker, 403}}) {
    auto r = client->Post("/v1/jobs", Bearer(token), job.dump(), "application/json");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, status) << "token '" << token << "': " << r->body;
  }
  const int64_t id = Submit(*client, job, submit);

  // A worker with a read token, or none, is refused and says so.
  for (const std::string& token : {read, std::string()}) {
    std::vector<std::string> args = {"--threads", "1"};
    if (!token.empty()) args.insert(args.end(), {"--token", token});
    auto refused = StartWorker(dir.path(), server, token.empty() ? "no-token" : "read-token", args);
    const int code = refused->WaitExit(10);
    EXPECT_NE(code, 0);
    EXPECT_LT(code, 128) << "killed by a signal";
    EXPECT_NE(refused->Log().find("refused the token"), std::string::npos) << refused->Log();
    EXPECT_NE(refused->Log().find(token.empty() ? "HTTP 401" : "HTTP 403"), std::string::npos) << refused->Log();
  }
  EXPECT_EQ(GetJson(*client, "/v1/jobs/" + std::to_string(id), read).at("progress").at("done"), 0);

  // With the worker token it leases and completes both tasks, then stops (--max-tasks 2).
  auto good = StartWorker(dir.path(), server, "good", {"--threads", "1", "--token", worker, "--max-tasks", "2"});
  EXPECT_EQ(good->WaitExit(20), 0) << good->Log();
  EXPECT_NE(good->Log().find("2 tasks completed"), std::string::npos) << good->Log();
  const json done = WaitForFinish(*client, id, 10, read);
  EXPECT_EQ(done.at("status"), "succeeded") << done.dump();

  // The rows equal core's SweepRow in this process, row by row.
  const std::vector<json> points = FetchPoints(*client, id, "", read);
  std::vector<json> want;
  const std::vector<double> frequencies = strokelab::GridAxis{5, 50, kFrequencies}.Values();
  for (double amplitude : strokelab::GridAxis{0.1, 0.6, kAmplitudes}.Values()) {
    for (const strokelab::SweepPoint& p : strokelab::SweepRow(strokelab::PaperModel(), amplitude, frequencies).points) {
      const json row = strokelab::report::RowToJson(p);
      want.push_back(json::parse(row.dump()));  // as stored: through JSON text
    }
  }
  ExpectSameRows(points, json(want), "points");
  ExpectEachGridPointOnce(points, kFrequencies * kAmplitudes);
  std::printf("whole test %.2f s\n", SecondsSince(test_start));
}

}  // namespace
