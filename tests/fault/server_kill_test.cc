// The server SIGKILLed at random moments of several sweeps, many times over, and restarted on the
// same file each time: it must come back every time, and every job must end with exactly its
// points, bit for bit those of a single-process CLI sweep (tests/fault/sweep_workload.h).
//
// The moments are drawn from a seeded generator (printed; STROKELAB_FAULT_SEED): a delay of 20 to
// 400 ms after the server said it was serving. A new job is submitted every few kills, and whenever
// none is left unfinished, so that kills land in the middle of sweeps rather than on an idle server.
#include <gtest/gtest.h>
#include <signal.h>

#include <random>

#include "fault/fault_seed.h"
#include "fault/sweep_workload.h"

namespace strokelab::test_fault {
namespace {

TEST(ServerKill, RandomKillsAcrossSeveralSweeps) {
  const auto test_start = Clock::now();
  std::mt19937_64 rng(FaultSeed("ServerKill", 20240611));
  ScratchDir dir("strokelab-fault-kill");
  const fs::path db = dir.path() / "jobs.db";
  const std::vector<std::string> serve_args = {"--workers", "2", "--db", db.string(), "--quiet"};
  constexpr int kKills = 24, kJobEvery = 6;
  // Jobs of ~0.5 s of sweeping on 2 cores (1500 x 8 with thresholds), more than the longest kill
  // delay, so that kills find work in progress on a fast machine too: with 100 x 8 only 11 of 24 did
  // on an idle machine, and with 300 x 8 (0.1 s) 10 of 24 once the continuation got faster.
  SweepWorkload work(/*first_frequency_points=*/1500, /*amplitude_points=*/8, /*thresholds=*/true);

  Server server = StartServer(dir.path(), "serve-0", serve_args);
  int kills_mid_sweep = 0, restarts = 0, kills_with_lease = 0;
  for (int k = 0; k < kKills; ++k) {
    {
      auto client = Client(server);
      Db file(db);
      if (k % kJobEvery == 0 || work.Unfinished(file) == 0) work.SubmitNext(*client);
    }
    SleepMs(std::uniform_int_distribution<int>(20, 400)(rng));
    ASSERT_FALSE(server.child->Poll()) << "the server died by itself:\n" << server.child->Log();
    server.child->Signal(SIGKILL);
    ASSERT_EQ(server.child->WaitExit(10), 128 + SIGKILL);
    {
      Db file(db);
      kills_mid_sweep += work.Unfinished(file) > 0;
      kills_with_lease += file.One("SELECT count(*) FROM tasks WHERE status = 'leased'") != "0";
    }
    // It comes back on the file the dead one left, and answers.
    server = StartServer(dir.path(), "serve-" + std::to_string(k + 1), serve_args);
    const json health = GetJson(*Client(server), "/v1/health");
    ASSERT_EQ(health.at("status"), "ok") << health.dump();
    ++restarts;
  }
  std::printf("%d kills: %d with a job unfinished, %d with a task in flight; %d restarts; %zu jobs; kill phase %.1f s\n",
              kKills, kills_mid_sweep, kills_with_lease, restarts, work.size(), SecondsSince(test_start));
  EXPECT_EQ(restarts, kKills);
  // Jobs take seconds and a new one is submitted whenever none is left: nearly every kill should
  // find work in progress. Fewer than half means the test stopped testing what it says.
  EXPECT_GE(kills_mid_sweep, kKills / 2);

  auto client = Client(server);
  work.WaitAndCheck(*client, dir.path(), db, 120);
  server.child->Signal(SIGTERM);
  EXPECT_EQ(server.child->WaitExit(20), 0) << server.child->Log();
  std::printf("whole test %.1f s\n", SecondsSince(test_start));
}

}  // namespace
}  // namespace strokelab::test_fault
