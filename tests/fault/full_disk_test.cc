// The server's database on a "full disk": the server runs under RLIMIT_FSIZE (prlimit --fsize; the
// server ignores SIGXFSZ itself, so that writes past the limit fail with EFBIG as on a full file system;
// mounting a small tmpfs needs privileges a test does not have). The server must say so (503 with
// the file and the cause; /v1/health degraded), keep what it had committed, not damage the file,
// and finish the job once restarted without the limit.
#include <gtest/gtest.h>
#include <signal.h>

#include "fault/sweep_workload.h"

namespace strokelab::test_fault {
namespace {

constexpr const char* kPrlimit = "/usr/bin/prlimit";

uintmax_t FilesSize(const fs::path& db) {
  uintmax_t total = 0;
  for (const char* suffix : {"", "-wal", "-shm"}) {
    std::error_code ec;
    const uintmax_t n = fs::file_size(db.string() + suffix, ec);
    if (!ec) total += n;
  }
  return total;
}

TEST(FullDisk, WritesFailClearlyAndNothingIsLost) {
  // util-linux is Essential in Debian (and listed in deploy/local.sh): missing it is a broken set-up,
  // not a reason to skip the one full-disk test that needs no privileges.
  ASSERT_TRUE(fs::exists(kPrlimit)) << kPrlimit << " (util-linux) is not installed";
  const auto test_start = Clock::now();
  ScratchDir dir("strokelab-fault-disk");
  const fs::path db = dir.path() / "jobs.db";
  const std::vector<std::string> serve_args = {"--workers", "1", "--db", db.string(), "--quiet"};
  // Job 1 finishes with room to spare; job 2 (about 100 kB of rows) does not fit.
  SweepWorkload first(/*first_frequency_points=*/40, /*amplitude_points=*/3, /*thresholds=*/false);
  SweepWorkload second(/*first_frequency_points=*/200, /*amplitude_points=*/10, /*thresholds=*/true);

  std::vector<json> first_points;
  int64_t first_id = 0;
  {
    Server server = StartServer(dir.path(), "serve-roomy", serve_args);
    auto client = Client(server);
    first_id = first.SubmitNext(*client);
    ASSERT_EQ(WaitForFinish(*client, first_id, 60).at("status"), "succeeded");
    first_points = FetchPoints(*client, first_id);
    server.child->Signal(SIGTERM);
    ASSERT_EQ(server.child->WaitExit(20), 0) << server.child->Log();
  }

  // Room for about 40 kB more than the file has now.
  const uintmax_t limit = fs::file_size(db) + 40 * 1024;
  // SIGXFSZ keeps its default (fatal) disposition here: the server must ignore it on its own.
  signal(SIGXFSZ, SIG_DFL);
  {
    Server server = StartServer(dir.path(), "serve-full", serve_args,
                                {kPrlimit, "--fsize=" + std::to_string(limit), "--"});
    auto client = Client(server);
    const int64_t id = second.SubmitNext(*client);  // small: fits
    // The worker's completions fail; health says why (polled: when the first write fails depends on
    // the order of the rows' pages).
    json health;
    const auto start = Clock::now();
    for (;;) {
      auto r = client->Get("/v1/health");
      ASSERT_TRUE(r) << httplib::to_string(r.error());
      health = json::parse(r->body);
      if (r->status == 503) break;
      ASSERT_EQ(r->status, 200) << r->body;
      const json job = GetJson(*client, "/v1/jobs/" + std::to_string(id));
      ASSERT_NE(job.at("status"), "succeeded") << "the job fit under the limit (" << limit << " bytes): make it larger";
      ASSERT_LT(SecondsSince(start), 60) << "no storage error reported:\n" << server.child->Log();
      SleepMs(50);
    }
    std::printf("health while full: %s\n", health.dump().c_str());
    EXPECT_EQ(health.at("status"), "degraded");
    const std::string message = health.at("storage_error").at("message");
    EXPECT_NE(message.find(db.string()), std::string::npos) << message;
    EXPECT_NE(message.find("file size limit"), std::string::npos) << message;

    // A submission now: refused with 503 and the reason, or accepted (if its rows fit); never a 500.
    auto r = client->Post("/v1/jobs", SweepJob(30, 1, false).dump(), "application/json");
    ASSERT_TRUE(r);
    std::printf("submit while full: HTTP %d %s\n", r->status, r->body.substr(0, 200).c_str());
    EXPECT_TRUE(r->status == 201 || r->status == 503) << r->status << " " << r->body;
    if (r->status == 503) {
      EXPECT_EQ(json::parse(r->body).at("error").at("code"), "storage_error") << r->body;
    }

    // Reads still work: job 1 is all there; job 2 is not failed (the disk is not the job's fault).
    EXPECT_EQ(FetchPoints(*client, first_id).size(), first_points.size());
    const json job = GetJson(*client, "/v1/jobs/" + std::to_string(id));
    EXPECT_TRUE(job.at("status") == "running" || job.at("status") == "queued") << job.dump();
    EXPECT_LE(FilesSize(db), 3 * limit);

    server.child->Signal(SIGTERM);
    EXPECT_EQ(server.child->WaitExit(20), 0) << server.child->Log();
  }
  {
    Db file(db);
    EXPECT_EQ(file.One("PRAGMA integrity_check"), "ok");
  }

  // Space again: everything committed is there, and the job finishes.
  Server server = StartServer(dir.path(), "serve-roomy-again", serve_args);
  auto client = Client(server);
  ExpectSameRows(FetchPoints(*client, first_id), json(first_points), "job 1 after the full disk");
  second.WaitAndCheck(*client, dir.path(), db, 120);
  EXPECT_EQ(GetJson(*client, "/v1/health").at("status"), "ok");
  server.child->Signal(SIGTERM);
  EXPECT_EQ(server.child->WaitExit(20), 0) << server.child->Log();
  std::printf("whole test %.1f s\n", SecondsSince(test_start));
}

}  // namespace
}  // namespace strokelab::test_fault
