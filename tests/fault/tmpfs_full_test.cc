// The database on a file system that fills up: a 256 kB tmpfs (tests/fault/small_tmpfs.h; skipped
// where user namespaces are not allowed). Writes fail with ENOSPC ("database or disk is full"): the
// service must report it (/v1/health degraded with the file and the cause), keep the job (not fail
// it: the disk is not the job's fault) and, once the file system is given room, finish the job
// without a restart, with exactly its points. The RLIMIT_FSIZE variant (full_disk_test.cc) covers
// the restart.
#include <gtest/gtest.h>
#include <signal.h>

#include "fault/small_tmpfs.h"
#include "fault/sweep_workload.h"

namespace strokelab::test_fault {
namespace {

// Polls /v1/health until it answers 503; returns its body.
json WaitForDegradedHealth(httplib::Client& client, const Child& server, double timeout_s) {
  const auto start = Clock::now();
  for (;;) {
    auto r = client.Get("/v1/health");
    if (!r) throw std::runtime_error("GET /v1/health: " + httplib::to_string(r.error()));
    if (r->status == 503) return json::parse(r->body);
    if (SecondsSince(start) > timeout_s)
      throw std::runtime_error("no storage error reported in " + std::to_string(timeout_s) + " s:\n" + server.Log());
    SleepMs(50);
  }
}

TEST(FullDisk, TmpfsFillsUpThenGrows) {
  const auto test_start = Clock::now();
  ScratchDir dir("strokelab-fault-tmpfs");
  SmallTmpfs tmpfs(dir.path() / "mnt", 256 * 1024);  // room for the schema (6 migrations) and a job
  // Mounting needs unprivileged user namespaces (unshare -rm), which a CI container may forbid:
  // then this test skips, saying why, and FullDisk.WritesFailClearlyAndNothingIsLost (a file-size
  // limit, no privileges) still drives the same server path to a full disk and back.
  if (!tmpfs.Ok()) GTEST_SKIP() << tmpfs.Why();
  const fs::path db_inside = tmpfs.MountPoint() / "jobs.db";
  SweepWorkload work(/*first_frequency_points=*/200, /*amplitude_points=*/10, /*thresholds=*/true);

  Server server = StartServer(dir.path(), "serve", {"--workers", "1", "--db", db_inside.string(), "--quiet"},
                              tmpfs.Wrapper());
  auto client = Client(server);
  const int64_t id = work.SubmitNext(*client);
  const json health = WaitForDegradedHealth(*client, *server.child, 60);
  std::printf("health while full: %s\n", health.dump().c_str());
  EXPECT_EQ(health.at("status"), "degraded");
  const std::string message = health.at("storage_error").at("message");
  EXPECT_NE(message.find(db_inside.string()), std::string::npos) << message;
  EXPECT_NE(message.find("full"), std::string::npos) << message;
  const json job = GetJson(*client, "/v1/jobs/" + std::to_string(id));
  EXPECT_TRUE(job.at("status") == "queued" || job.at("status") == "running") << job.dump();

  // Room again: the stalled completion goes through, the job finishes, health is ok again.
  tmpfs.Resize(16 << 20);
  work.WaitAndCheck(*client, dir.path(), 120);
  EXPECT_EQ(GetJson(*client, "/v1/health").at("status"), "ok");
  server.child->Signal(SIGTERM);
  EXPECT_EQ(server.child->WaitExit(20), 0) << server.child->Log();
  // SQLite resolves /proc/PID/root to "/", so it cannot open the file there: check a copy (the
  // server stopped cleanly, so the file is whole without its WAL).
  fs::copy_file(tmpfs.Path("jobs.db"), dir.path() / "jobs-copy.db");
  work.CheckFile(dir.path() / "jobs-copy.db");
  std::printf("whole test %.1f s\n", SecondsSince(test_start));
}

}  // namespace
}  // namespace strokelab::test_fault
