// The structured log of `strokelab serve` (server/src/event_log.h): run the real binary with tokens
// and no workers of its own, drive three jobs through every end state with the worker API (one
// succeeds, one fails, one is cancelled), send requests that are refused before and after routing,
// poll the empty queue, stop it, and read its stderr: every line but the two human ones parses as a
// JSON object; empty-queue polls have none; each request has time, method, path, status, duration and remote; each job state change has the job,
// kind, points and reason; no token appears anywhere.
#include <gtest/gtest.h>

#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "serve_child.h"
#include "strokelab/jobs/jobs.h"

namespace strokelab::testing {
namespace {

using nlohmann::json;

const std::string kSubmit = "submit-token-log-0123456789", kWorker = "worker-token-log-0123456789";

httplib::Headers Bearer(const std::string& token) { return {{"Authorization", "Bearer " + token}}; }

json Expect(const httplib::Result& r, int status) {
  if (!r) throw std::runtime_error("no reply: " + httplib::to_string(r.error()));
  if (r->status != status) throw std::runtime_error("HTTP " + std::to_string(r->status) + ": " + r->body);
  return r->body.empty() ? json() : json::parse(r->body);
}

json SimulateJob(double frequency_hz) {
  return {{"kind", "simulate"}, {"model", "paper"}, {"frequency_hz", frequency_hz}, {"amplitude_v", 0.2}};
}

TEST(StructuredLog, RequestsAndJobStateChangesAreJsonLinesWithoutTokens) {
  ScratchDirectory dir("strokelab-log");
  std::ofstream(dir.path() / "tokens") << "submit " << kSubmit << "\nworker " << kWorker << "\n";
  ServeChild server(dir.path() / "jobs.db", dir.path() / "serve.log",
                    {"--workers", "0", "--token-file", (dir.path() / "tokens").string()});
  auto client = server.Client();
  const auto submit = [&](double f) {
    return Expect(client->Post("/v1/jobs", Bearer(kSubmit), SimulateJob(f).dump(), "application/json"), 201)
        .at("id")
        .get<int64_t>();
  };
  const auto lease = [&] {
    return Expect(client->Post("/v1/tasks/lease", Bearer(kWorker), R"({"worker":"w1"})", "application/json"), 200);
  };
  const auto report = [&](const json& l, const std::string& verb, json body) {
    body["job_id"] = l.at("job_id");
    body["lease_token"] = l.at("lease_token");
    const std::string path = "/v1/tasks/" + std::to_string(l.at("task_id").get<int64_t>()) + "/" + verb;
    Expect(client->Post(path, Bearer(kWorker), body.dump(), "application/json"), 200);
  };

  const int64_t done = submit(10);
  {  // the task's own rows: made-up ones are refused (jobs/task_rows.h)
    const json task = lease();
    json rows = json::array();
    for (const jobs::ResultRow& row : jobs::RunTask(task.at("spec")).AllRows())
      rows.push_back({{"table", row.table}, {"values", row.values}});
    report(task, "complete", {{"rows", rows}});
  }
  const int64_t failed = submit(11);
  report(lease(), "fail", {{"error", "solver diverged at t = 0.3 s"}});
  const int64_t cancelled = submit(12);
  Expect(client->Delete("/v1/jobs/" + std::to_string(cancelled), Bearer(kSubmit)), 200);
  EXPECT_EQ(client->Get("/v1/no-such-endpoint")->status, 404);
  EXPECT_EQ(client->Get("/v1/jobs", Bearer("not-a-token-0123456789"))->status, 401);
  // An idle worker's polls of the empty queue: not one line each (issue 17: 429 of 560 lines came
  // from two idle workers); /metrics counts them with every request.
  for (int i = 0; i < 3; ++i)
    EXPECT_EQ(client->Post("/v1/tasks/lease", Bearer(kWorker), R"({"worker":"w1"})", "application/json")->status, 204);
  ASSERT_EQ(server.Stop(), 0);

  const std::string log = server.Log();
  std::vector<json> requests;
  std::map<int64_t, std::vector<json>> jobs;
  std::istringstream lines(log);
  const std::regex iso_time(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z)");
  for (std::string line; std::getline(lines, line);) {
    // The two lines for people: where it serves, and that it stops.
    if (line.rfind("strokelab serving ", 0) == 0 || line == "stopping") continue;
    json entry;
    ASSERT_NO_THROW(entry = json::parse(line)) << line;
    ASSERT_TRUE(entry.is_object()) << line;
    ASSERT_TRUE(entry.contains("time") && std::regex_match(entry["time"].get<std::string>(), iso_time)) << line;
    EXPECT_TRUE(entry["ts_ms"].is_number_integer()) << line;
    if (entry["event"] == "request") requests.push_back(entry);
    else if (entry["event"] == "job") jobs[entry.at("job_id").get<int64_t>()].push_back(entry);
    else ADD_FAILURE() << "a line of no known event: " << line;
  }
  for (const std::string& token : {kSubmit, kWorker, std::string("not-a-token-0123456789")})
    EXPECT_EQ(log.find(token), std::string::npos) << "the log holds a bearer token";

  // Requests: 3 submits, 2 leases, complete, fail, cancel, 404, 401 (and no empty polls).
  ASSERT_EQ(requests.size(), 10u) << log;
  std::map<std::string, int> seen;
  for (const json& r : requests) {
    for (const char* key : {"method", "path", "remote"}) EXPECT_TRUE(r[key].is_string()) << r;
    EXPECT_TRUE(r["status"].is_number_integer()) << r;
    EXPECT_TRUE(r["duration_ms"].is_number() && r["duration_ms"] >= 0) << r;
    EXPECT_EQ(r["remote"].get<std::string>().rfind("127.0.0.1:", 0), 0u) << r;
    ++seen[r["method"].get<std::string>() + " " + r["path"].get<std::string>() + " " + r["status"].dump()];
  }
  EXPECT_EQ(seen["POST /v1/jobs 201"], 3);
  EXPECT_EQ(seen["POST /v1/tasks/lease 200"], 2);
  EXPECT_EQ(seen["POST /v1/tasks/lease 204"], 0) << "idle polls are not logged";
  EXPECT_EQ(seen["DELETE /v1/jobs/" + std::to_string(cancelled) + " 200"], 1);
  EXPECT_EQ(seen["GET /v1/no-such-endpoint 404"], 1) << "unrouted requests are logged too";
  EXPECT_EQ(seen["GET /v1/jobs 401"], 1);

  // Job state changes, in order, with kind, progress, points and reason.
  const auto states = [&](int64_t id) {
    std::string out;
    for (const json& e : jobs[id]) out += (out.empty() ? "" : ",") + e.at("status").get<std::string>();
    return out;
  };
  EXPECT_EQ(states(done), "queued,running,succeeded");
  EXPECT_EQ(states(failed), "queued,running,failed");
  EXPECT_EQ(states(cancelled), "queued,cancelled");
  for (const auto& [id, events] : jobs) {
    for (const json& e : events) {
      EXPECT_EQ(e.at("kind"), "simulate") << e;
      EXPECT_EQ(e.at("tasks_total"), 1) << e;
      EXPECT_TRUE(e.at("reason").is_string() && !e["reason"].get<std::string>().empty()) << e;
    }
  }
  EXPECT_EQ(jobs[done].back().at("points"), 0);  // sweep points; a simulate job writes one record
  EXPECT_EQ(jobs[done].back().at("tasks_done"), 1);
  EXPECT_EQ(jobs[done][1].at("reason"), "first task leased by remote:w1");
  EXPECT_EQ(jobs[failed].back().at("reason"), "solver diverged at t = 0.3 s");
  EXPECT_EQ(jobs[failed].back().at("points"), 0);
  EXPECT_EQ(jobs[cancelled].back().at("reason"), "cancelled by request");
}

}  // namespace
}  // namespace strokelab::testing
