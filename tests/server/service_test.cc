// The REST service in process: every error path answers with its status, a stable code, a message
// and (for bad jobs) the JSON pointer of the field; tokens and roles are enforced.
#include "strokelab/server/service.h"
#include "test_tokens.h"
#include "test_util.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

namespace strokelab::server {
namespace {

using ::testing::HasSubstr;
using nlohmann::json;

using ::strokelab::testing::kReadToken;
using ::strokelab::testing::kSubmitToken;

const json kSmallSweep = {{"kind", "sweep"},
                          {"model", "paper"},
                          {"grid",
                           {{"frequency_hz", {{"from", 6}, {"to", 14}, {"points", 9}}},
                            {"amplitude_v", {{"from", 0.2}, {"to", 0.5}, {"points", 2}}}}}};

class ServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ::strokelab::testing::FreshTestDir("service_test");
    std::ofstream(dir_ / "tokens") << "# role token\nsubmit " << kSubmitToken << "\nread " << kReadToken << "\n";
    ServiceOptions options;
    options.port = 0;
    options.db_path = (dir_ / "jobs.db").string();
    options.workers = 1;
    options.token_file = (dir_ / "tokens").string();
    options.max_body_bytes = 64 * 1024;
    options.quiet = true;
    service_ = std::make_unique<Service>(options);
    port_ = service_->Start();
  }
  void TearDown() override {
    service_->Stop();
    std::filesystem::remove_all(dir_);
  }
  httplib::Client Client() { return httplib::Client("127.0.0.1", port_); }
  static httplib::Headers Auth(const char* token) { return {{"Authorization", std::string("Bearer ") + token}}; }

  // The error object of a reply, checking its status.
  static json Error(const httplib::Result& r, int status) {
    EXPECT_TRUE(r);
    if (!r) return {};
    EXPECT_EQ(r->status, status) << r->body;
    const json body = json::parse(r->body, nullptr, false);
    EXPECT_TRUE(body.contains("error")) << r->body;
    return body.value("error", json::object());
  }

  json Submit(const json& job) {
    auto c = Client();
    auto r = c.Post("/v1/jobs", Auth(kSubmitToken), job.dump(), "application/json");
    EXPECT_TRUE(r && r->status == 201) << (r ? r->body : "no reply");
    return json::parse(r->body);
  }

  json WaitFinished(int64_t id) {
    auto c = Client();
    for (int i = 0; i < 600; ++i) {
      auto r = c.Get("/v1/jobs/" + std::to_string(id), Auth(kReadToken));
      const json job = json::parse(r->body);
      if (job["status"] != "queued" && job["status"] != "running") return job;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    ADD_FAILURE() << "job " << id << " did not finish";
    return {};
  }

  std::filesystem::path dir_;
  std::unique_ptr<Service> service_;
  int port_ = 0;
};

TEST_F(ServiceTest, SubmitRunQueryAndServeTheRepeatFromTheStore) {
  const json reply = Submit(kSmallSweep);
  EXPECT_EQ(reply["status"], "queued");
  const json job = WaitFinished(reply["id"]);
  EXPECT_EQ(job["status"], "succeeded");
  EXPECT_EQ(job["progress"]["done"], job["progress"]["total"]);
  auto c = Client();
  auto points = c.Get("/v1/jobs/" + std::to_string(reply["id"].get<int64_t>()) + "/points?branch=up&limit=100",
                      Auth(kReadToken));
  ASSERT_EQ(points->status, 200);
  EXPECT_EQ(json::parse(points->body)["points"].size(), 18u);  // 9 frequencies x 2 amplitudes
  // The same job again is served from the store: finished at submission.
  const json again = Submit(kSmallSweep);
  EXPECT_EQ(again["status"], "succeeded");
  auto csv = c.Get("/v1/jobs/" + std::to_string(again["id"].get<int64_t>()) + "/points?branch=down",
                   {{"Authorization", std::string("Bearer ") + kReadToken}, {"Accept", "text/csv"}});
  ASSERT_EQ(csv->status, 200);
  EXPECT_EQ(std::count(csv->body.begin(), csv->body.end(), '\n'), 19);  // header + 18 rows
}

TEST_F(ServiceTest, BadJsonIsRefusedWithItsCode) {
  auto c = Client();
  const json e = Error(c.Post("/v1/jobs", Auth(kSubmitToken), "{\"kind\": ", "application/json"), 400);
  EXPECT_EQ(e["code"], "bad_json");
  EXPECT_THAT(e["message"].get<std::string>(), HasSubstr("not valid JSON"));
}

TEST_F(ServiceTest, SchemaViolationNamesTheField) {
  json job = kSmallSweep;
  job["grid"]["amplitude_v"]["to"] = -1;
  auto c = Client();
  json e = Error(c.Post("/v1/jobs", Auth(kSubmitToken), job.dump(), "application/json"), 400);
  EXPECT_EQ(e["code"], "invalid_job");
  EXPECT_EQ(e["field"], "/grid/amplitude_v/to");
  job = kSmallSweep;
  job["grid"]["frequency_hz"].erase("points");
  e = Error(c.Post("/v1/jobs", Auth(kSubmitToken), job.dump(), "application/json"), 400);
  EXPECT_EQ(e["field"], "/grid/frequency_hz/points");
  job = kSmallSweep;
  job["model"] = {{"m_p", -0.032}};
  e = Error(c.Post("/v1/jobs", Auth(kSubmitToken), job.dump(), "application/json"), 400);
  EXPECT_EQ(e["field"], "/model/m_p");
}

TEST_F(ServiceTest, OversizeJobAndBodyNameTheLimit) {
  json job = kSmallSweep;
  job["grid"]["frequency_hz"]["points"] = 2000;
  job["grid"]["amplitude_v"]["points"] = 2000;
  auto c = Client();
  const json e = Error(c.Post("/v1/jobs", Auth(kSubmitToken), job.dump(), "application/json"), 400);
  EXPECT_EQ(e["code"], "job_too_large");
  EXPECT_THAT(e["message"].get<std::string>(), HasSubstr("200000"));
  const std::string big(100 * 1024, ' ');
  const json e2 = Error(c.Post("/v1/jobs", Auth(kSubmitToken), big, "application/json"), 413);
  EXPECT_EQ(e2["code"], "body_too_large");
}

// curl -d sends application/x-www-form-urlencoded: refused (a form post from any web page must not
// submit jobs), and the message names the header to add, whatever the body's size (httplib refuses
// a form body over 8 KiB itself, which was answered 413 body_too_large).
TEST_F(ServiceTest, AFormPostIsRefusedNamingTheHeaderToAdd) {
  auto c = Client();
  const std::string padded = json(kSmallSweep).dump() + std::string(20000, ' ');
  for (const std::string& body : {json(kSmallSweep).dump(), padded}) {
    for (const char* type : {"application/x-www-form-urlencoded", "text/plain", ""}) {
      const json e = Error(c.Post("/v1/jobs", Auth(kSubmitToken), body, type), 415);
      EXPECT_EQ(e["code"], "unsupported_media_type") << type << ", " << body.size() << " bytes";
      EXPECT_THAT(e.value("message", ""), HasSubstr("-H 'Content-Type: application/json'")) << type;
    }
  }
}

TEST_F(ServiceTest, UnknownJobAndCancelOfAFinishedJob) {
  auto c = Client();
  EXPECT_EQ(Error(c.Get("/v1/jobs/12345", Auth(kReadToken)), 404)["code"], "unknown_job");
  EXPECT_EQ(Error(c.Delete("/v1/jobs/12345", Auth(kSubmitToken)), 404)["code"], "unknown_job");
  const json reply = Submit(kSmallSweep);
  WaitFinished(reply["id"]);
  const json e = Error(c.Delete("/v1/jobs/" + std::to_string(reply["id"].get<int64_t>()), Auth(kSubmitToken)), 409);
  EXPECT_EQ(e["code"], "already_finished");
  EXPECT_THAT(e["message"].get<std::string>(), HasSubstr("succeeded"));
}

// A second cancel said "job N has already cancelled": the job has finished, and how.
TEST_F(ServiceTest, CancellingACancelledJobSaysItHasFinished) {
  json job = kSmallSweep;
  job["grid"]["frequency_hz"]["points"] = 400;
  job["grid"]["amplitude_v"]["points"] = 60;
  const std::string path = "/v1/jobs/" + std::to_string(Submit(job)["id"].get<int64_t>());
  auto c = Client();
  auto first = c.Delete(path, Auth(kSubmitToken));
  ASSERT_TRUE(first && first->status == 200) << (first ? first->body : "no reply");
  const json again = Error(c.Delete(path, Auth(kSubmitToken)), 409);
  EXPECT_EQ(again["code"], "already_finished");
  EXPECT_THAT(again.value("message", ""), ::testing::EndsWith("has already finished (cancelled)"));
}

TEST_F(ServiceTest, CancelStopsARunningJob) {
  json job = kSmallSweep;
  job["grid"]["frequency_hz"]["points"] = 400;
  job["grid"]["amplitude_v"]["points"] = 60;
  const json reply = Submit(job);
  auto c = Client();
  auto r = c.Delete("/v1/jobs/" + std::to_string(reply["id"].get<int64_t>()), Auth(kSubmitToken));
  ASSERT_EQ(r->status, 200) << r->body;
  const json finished = WaitFinished(reply["id"]);
  EXPECT_EQ(finished["status"], "cancelled");
  EXPECT_LT(finished["progress"]["done"].get<int>(), finished["progress"]["total"].get<int>());
}

TEST_F(ServiceTest, TokensAndRoles) {
  auto c = Client();
  EXPECT_EQ(Error(c.Get("/v1/jobs"), 401)["code"], "unauthorized");
  EXPECT_EQ(Error(c.Get("/v1/jobs", Auth("wrong-token-0123456789")), 401)["code"], "unauthorized");
  EXPECT_EQ(Error(c.Post("/v1/jobs", Auth(kReadToken), kSmallSweep.dump(), "application/json"), 403)["code"],
            "forbidden");
  EXPECT_EQ(Error(c.Delete("/v1/jobs/1", Auth(kReadToken)), 403)["code"], "forbidden");
  EXPECT_EQ(Error(c.Post("/v1/tasks/lease", Auth(kReadToken), "{}", "application/json"), 403)["code"], "forbidden");
  auto ok = c.Get("/v1/jobs", Auth(kReadToken));
  EXPECT_EQ(ok->status, 200);
}

TEST_F(ServiceTest, QueryParametersAreChecked) {
  auto c = Client();
  const json reply = Submit(kSmallSweep);
  const std::string base = "/v1/jobs/" + std::to_string(reply["id"].get<int64_t>());
  EXPECT_EQ(Error(c.Get(base + "/points?branch=sideways", Auth(kReadToken)), 400)["field"], "branch");
  EXPECT_EQ(Error(c.Get(base + "/points?limit=0", Auth(kReadToken)), 400)["field"], "limit");
  EXPECT_EQ(Error(c.Get(base + "/points?frequency_min_hz=abc", Auth(kReadToken)), 400)["field"], "frequency_min_hz");
  EXPECT_EQ(Error(c.Get(base + "/frf", Auth(kReadToken)), 400)["field"], "amplitude_v");
  EXPECT_EQ(Error(c.Get("/v1/nothing", Auth(kReadToken)), 404)["code"], "not_found");
}

TEST_F(ServiceTest, AKnownPathWithAnotherMethodIs405WithAllow) {
  auto c = Client();
  const std::string job = "/v1/jobs/" + std::to_string(Submit(kSmallSweep)["id"].get<int64_t>());
  struct Case {
    httplib::Result result;
    std::string allow;
  };
  std::vector<Case> cases;
  cases.push_back({c.Put(job, Auth(kSubmitToken), "{}", "application/json"), "GET, DELETE"});
  cases.push_back({c.Post("/v1/health", Auth(kSubmitToken), "{}", "application/json"), "GET"});
  cases.push_back({c.Get("/v1/tasks/lease", Auth(kSubmitToken)), "POST"});
  cases.push_back({c.Delete("/v1/jobs", Auth(kSubmitToken)), "POST, GET"});
  cases.push_back({c.Post(job + "/points", Auth(kSubmitToken), "{}", "application/json"), "GET"});
  for (const Case& k : cases) {
    ASSERT_TRUE(k.result);
    EXPECT_EQ(Error(k.result, 405)["code"], "method_not_allowed") << k.allow;
    EXPECT_EQ(k.result->get_header_value("Allow"), k.allow);
  }
  // Not a route under any method: still 404.
  EXPECT_EQ(Error(c.Put("/v1/nothing", Auth(kSubmitToken), "{}", "application/json"), 404)["code"], "not_found");
}

TEST_F(ServiceTest, HealthMetricsAndPage) {
  auto c = Client();
  auto health = c.Get("/v1/health", Auth(kReadToken));
  ASSERT_EQ(health->status, 200);
  EXPECT_EQ(json::parse(health->body)["status"], "ok");
  auto metrics = c.Get("/metrics", Auth(kReadToken));
  ASSERT_EQ(metrics->status, 200);
  EXPECT_THAT(metrics->body, HasSubstr("strokelab_jobs{state=\"succeeded\"}"));
  EXPECT_THAT(metrics->body, HasSubstr("strokelab_request_duration_seconds_bucket"));
  auto page = c.Get("/");
  ASSERT_EQ(page->status, 200);
  EXPECT_THAT(page->body, HasSubstr("<title>strokelab</title>"));
}

// Issue 16 point 8: the page's plotting library is served by the server itself (no token, no
// network), and the page's policy lets exactly its two scripts run: its own and the library, both
// by this response's nonce; no other script of this server, no eval.
TEST_F(ServiceTest, ThePageLoadsItsPlottingLibraryFromThisServerByNonce) {
  auto c = Client();
  auto page = c.Get("/");
  ASSERT_TRUE(page && page->status == 200);
  const std::string policy = page->get_header_value("Content-Security-Policy");
  const size_t at = policy.find("script-src ");
  ASSERT_NE(at, std::string::npos) << policy;
  const std::string scripts = policy.substr(at, policy.find(';', at) - at);
  ASSERT_THAT(scripts, ::testing::MatchesRegex("script-src 'nonce-[0-9a-f]{32}'")) << policy;
  const std::string nonce = scripts.substr(18, 32);
  EXPECT_THAT(page->body, HasSubstr("<script nonce=\"" + nonce + "\" src=\"/vendor/uPlot.iife.min.js\"></script>"));
  EXPECT_THAT(page->body, HasSubstr("<link rel=\"stylesheet\" href=\"/vendor/uPlot.min.css\">"));
  auto library = c.Get("/vendor/uPlot.iife.min.js");
  ASSERT_TRUE(library && library->status == 200);
  EXPECT_EQ(library->get_header_value("Content-Type"), "text/javascript; charset=utf-8");
  EXPECT_THAT(library->body, HasSubstr("var uPlot"));
  EXPECT_GT(library->body.size(), 40000u);
  auto style = c.Get("/vendor/uPlot.min.css");
  ASSERT_TRUE(style && style->status == 200);
  EXPECT_EQ(style->get_header_value("Content-Type"), "text/css; charset=utf-8");
  EXPECT_THAT(style->body, HasSubstr(".uplot"));
  EXPECT_EQ(Error(c.Get("/vendor/uPlotXiife.min.js"), 404)["code"], "not_found") << "paths match literally";
}

}  // namespace
}  // namespace strokelab::server
