// Remote workers talking to the server through a proxy that delays, refuses, cuts and drops
// connections (tests/fault/faulty_proxy.h): leases whose reply was lost expire and are issued
// again, completions whose reply was lost are sent again and refused (409: the lease was used up),
// and every job still ends with exactly its points, each task's rows stored once.
#include <gtest/gtest.h>
#include <signal.h>

#include <sstream>
#include <nlohmann/json.hpp>

#include "fault/fault_seed.h"
#include "fault/faulty_proxy.h"
#include "fault/sweep_workload.h"

namespace strokelab::test_fault {
namespace {

// The server's access log: how many requests to `suffix` paths got `status`.
int CountRequests(const std::string& log, const std::string& suffix, int status) {
  int n = 0;
  std::istringstream lines(log);
  for (std::string line; std::getline(lines, line);) {
    const json entry = json::parse(line, nullptr, /*allow_exceptions=*/false);
    if (!entry.is_object() || !entry.contains("path") || !entry.contains("status")) continue;
    n += entry["path"].get<std::string>().ends_with(suffix) && entry["status"] == status;
  }
  return n;
}

TEST(FlakyNetwork, WorkersBehindAFaultyProxy) {
  const auto test_start = Clock::now();
  const uint64_t seed = FaultSeed("FlakyNetwork", 99);
  ScratchDir dir("strokelab-fault-net");
  const fs::path db = dir.path() / "jobs.db";
  SweepWorkload work(/*first_frequency_points=*/80, /*amplitude_points=*/10, /*thresholds=*/false);

  // Not --quiet: the access log tells which completions were refused.
  Server server = StartServer(dir.path(), "serve", {"--workers", "0", "--lease-s", "1", "--db", db.string()});
  FaultyProxy proxy(server.port, ProxyOptions{}, seed);
  Server via_proxy;
  via_proxy.port = proxy.port();

  auto client = Client(server);
  work.SubmitNext(*client);
  work.SubmitNext(*client);
  std::vector<std::unique_ptr<Child>> workers;
  for (const char* name : {"n1", "n2"}) workers.push_back(StartWorker(dir.path(), via_proxy, name, {"--threads", "1"}));

  work.WaitAndCheck(*client, dir.path(), db, 120);
  // A completion stored just before the jobs ended may have lost its reply while its worker waits
  // (500 ms) to send it again: stopping the workers now would cancel that repeat, not refuse it.
  for (const auto wait = Clock::now(); SecondsSince(wait) < 10; SleepMs(50))
    if (CountRequests(server.child->Log(), "/complete", 409) >= proxy.CompletionRepliesLost()) break;
  for (auto& w : workers) {
    w->Signal(SIGTERM);
    EXPECT_EQ(w->WaitExit(20), 0) << w->Log();
  }

  const std::vector<int> counts = proxy.FaultCounts();
  int connections = 0;
  for (size_t f = 0; f < counts.size(); ++f) {
    std::printf("  %-12s %d connections\n", ToString(static_cast<ProxyFault>(f)), counts[f]);
    connections += counts[f];
    if (f != static_cast<size_t>(ProxyFault::kPass)) {
      EXPECT_GT(counts[f], 0) << ToString(static_cast<ProxyFault>(f));  // every fault was tried
    }
  }
  // Every completion whose reply was lost after the server stored it was sent again and refused.
  const int refused = CountRequests(server.child->Log(), "/complete", 409);
  const int stored = CountRequests(server.child->Log(), "/complete", 200);
  std::printf("%d connections; %d completion replies lost; completions stored %d, refused as repeats %d; %.1f s\n",
              connections, proxy.CompletionRepliesLost(), stored, refused, SecondsSince(test_start));
  EXPECT_GE(proxy.CompletionRepliesLost(), ProxyOptions{}.drop_first_completes);
  EXPECT_GE(refused, proxy.CompletionRepliesLost());
  Db file(db);
  EXPECT_EQ(std::to_string(stored), file.One("SELECT count(*) FROM tasks WHERE status = 'done'"))
      << "a task completion was stored twice, or one was stored without a 200";
}

}  // namespace
}  // namespace strokelab::test_fault
