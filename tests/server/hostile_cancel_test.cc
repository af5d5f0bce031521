// Issue 15, item 2: cancellation and shutdown reach running computations. A simulate of an
// extreme but valid model (dry friction with a 1e-9 m/s transition velocity, which CVODE crawls
// through: ~100 s of work for 60 s simulated) kept its worker to the end after its job was
// cancelled, and SIGTERM left `strokelab serve` running until it was done. A task whose computation
// spent its work budget goes back to the queue once and fails its job the second time.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "hostile_service.h"
#include "raw_db.h"
#include "serve_child.h"

namespace strokelab::server {
namespace {

using nlohmann::json;
using CancelClock = std::chrono::steady_clock;

// Within ModelBounds, and minutes of CVODE steps for a minute of record.
const json kExtremeSimulate = {{"kind", "simulate"},
                            {"model", {{"preset", "paper"}, {"friction_n", 0.5}, {"friction_velocity", 1e-9}}},
                            {"frequency_hz", 8},
                            {"amplitude_v", 0.5},
                            {"duration_s", 60},
                            {"sample_rate_hz", 1000}};

double ElapsedS(CancelClock::time_point start) { return std::chrono::duration<double>(CancelClock::now() - start).count(); }

class HostileCancelTest : public HostileServiceTest {
 protected:
  // Polls the job until `status` (or `seconds` pass); the job's last state.
  json WaitForStatus(int64_t id, const std::string& status, double seconds) {
    const CancelClock::time_point start = CancelClock::now();
    json job = JobStatus(id);
    while (job.value("status", "") != status && ElapsedS(start) < seconds) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      job = JobStatus(id);
    }
    return job;
  }
};

TEST_F(HostileCancelTest, CancellingALongSimulateFreesItsWorkerWithinASecond) {
  options_.workers = 1;
  Start();
  const int64_t id = Submit(kExtremeSimulate);
  ASSERT_EQ(WaitForStatus(id, "running", 10).value("status", ""), "running");
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // well into CVODE's steps
  auto cancel = Client().Delete("/v1/jobs/" + std::to_string(id), Auth(kSubmitToken));
  ASSERT_TRUE(cancel && cancel->status == 200) << (cancel ? cancel->body : "no reply");
  const CancelClock::time_point cancelled = CancelClock::now();
  // The one worker takes the next job as soon as the cancelled computation has ended.
  const int64_t next = Submit(kOneTaskSimulate);
  const json job = WaitForStatus(next, "succeeded", 10);
  const double seconds = ElapsedS(cancelled);
  EXPECT_EQ(job.value("status", ""), "succeeded") << job.dump();
  EXPECT_LT(seconds, 1.0) << "the worker was busy with the cancelled simulate for " << seconds << " s";
  EXPECT_EQ(JobStatus(id).value("status", ""), "cancelled");
}

TEST_F(HostileCancelTest, ATaskThatSpentItsBudgetTwiceIsNotLeasedAgain) {
  Start();
  const int64_t id = Submit(kOneTaskSimulate);
  const auto fail_on_budget = [&](const json& task) {
    const json body = {{"job_id", task.at("job_id")}, {"lease_token", task.at("lease_token")},
                       {"error", "exact engine: work budget spent: ..."}, {"budget", true}};
    auto r = Client().Post("/v1/tasks/" + task.at("task_id").dump() + "/fail", Auth(kWorkerToken), body.dump(),
                           "application/json");
    ASSERT_TRUE(r && r->status == 200) << (r ? r->body : "no reply");
  };
  const json first = Lease();
  fail_on_budget(first);
  EXPECT_EQ(JobStatus(id).value("status", ""), "running") << "one spent budget may be the load: tried again";
  const json second = Lease();
  EXPECT_EQ(second.at("task_id"), first.at("task_id"));
  fail_on_budget(second);
  const json job = JobStatus(id);
  EXPECT_EQ(job.value("status", ""), "failed");
  EXPECT_NE(job.value("error", "").find("work budget spent twice"), std::string::npos) << job.dump();
  auto none = Client().Post("/v1/tasks/lease", Auth(kWorkerToken), "{}", "application/json");
  ASSERT_TRUE(none);
  EXPECT_EQ(none->status, 204) << "the task was leased a third time";
}

// SIGTERM printed "stopping" and the process lived on until the task in hand was done (>10 s). The
// stop takes ~0.2 s in Release; under ASan on a loaded machine 2.2 s was seen, so sanitizer builds
// allow 6 s, still far short of the task's own run.
constexpr double kStopDeadlineS = testing::kSanitizedBuild ? 6.0 : 2.0;

TEST(ServeShutdown, SigtermEndsServeWithinTwoSecondsAndTheTaskIsLeasedAgainOnRestart) {
  testing::ScratchDirectory dir("serve_shutdown");
  const std::filesystem::path db = dir.path() / "jobs.db";
  int64_t id = 0;
  {
    testing::ServeChild serve(db, dir.path() / "serve.log", {"--workers", "1", "--quiet"});
    auto client = serve.Client();
    auto r = client->Post("/v1/jobs", kExtremeSimulate.dump(), "application/json");
    ASSERT_TRUE(r && r->status == 201) << (r ? r->body : "no reply");
    id = json::parse(r->body).at("id").get<int64_t>();
    const CancelClock::time_point submitted = CancelClock::now();
    for (std::string status; status != "running" && ElapsedS(submitted) < 10;) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      auto job = client->Get("/v1/jobs/" + std::to_string(id));
      status = job && job->status == 200 ? json::parse(job->body).value("status", "") : "";
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    const CancelClock::time_point term = CancelClock::now();
    ::kill(serve.pid(), SIGTERM);
    while (serve.Alive() && ElapsedS(term) < 10) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    const double seconds = ElapsedS(term);
    EXPECT_LT(seconds, kStopDeadlineS) << "serve ran on for " << seconds << " s after SIGTERM";
    EXPECT_EQ(serve.Stop(), 0);
  }
  // The task went back to the queue, leased once so far.
  testing::RawDb raw(db.string());
  EXPECT_EQ(raw.Text("SELECT status || ' ' || attempts FROM tasks WHERE job_id = " + std::to_string(id)), "queued 1");
  testing::ServeChild again(db, dir.path() / "serve2.log", {"--workers", "1", "--quiet"});
  const CancelClock::time_point started = CancelClock::now();
  std::string task;
  while (task != "leased 2" && ElapsedS(started) < 10) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    task = raw.Text("SELECT status || ' ' || attempts FROM tasks WHERE job_id = " + std::to_string(id));
  }
  EXPECT_EQ(task, "leased 2") << "the task was not leased again after the restart";
  const CancelClock::time_point term = CancelClock::now();
  EXPECT_EQ(again.Stop(), 0);
  EXPECT_LT(ElapsedS(term), kStopDeadlineS);
}

}  // namespace
}  // namespace strokelab::server
