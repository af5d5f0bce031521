// Hostile requests against the service in process (issue 15): deep JSON in a completion, roles and
// forged rows, security headers and methods. The slow-client, header and body-size attacks, which
// need raw sockets, are in hostile_http_test.cc.
#include "hostile_service.h"
#include "strokelab/jobs/jobs.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

namespace strokelab::server {
namespace {

using nlohmann::json;

class HostileInputTest : public HostileServiceTest {};

// Item 1: 70,000 levels under a valid lease overflowed the stack when the rows were copied.
TEST_F(HostileInputTest, DeepValuesInACompletionAreRefusedAsTheyAreParsed) {
  Start();
  const int64_t id = Submit(kOneTaskSimulate);
  const json task = Lease();
  const std::string deep = std::string(70000, '[') + std::string(70000, ']');
  EXPECT_EQ(ErrorCode(Complete(task, R"([{"table":"records","values":{"x":)" + deep + "}}]")), "400 bad_json");
  EXPECT_EQ(JobStatus(id).value("status", ""), "running") << "nothing was written";
  EXPECT_EQ(Client().Get("/v1/health")->status, 200);
}

// Item 5: a submit token leased tasks, and a worker token read every job and result.
TEST_F(HostileInputTest, OnlyWorkerTokensLeaseAndWorkerTokensReadNothing) {
  Start();
  const int64_t id = Submit(kOneTaskSimulate);
  EXPECT_EQ(ErrorCode(Client().Post("/v1/tasks/lease", Auth(kSubmitToken), "{}", "application/json")), "403 forbidden");
  const std::string job = "/v1/jobs/" + std::to_string(id);
  for (const std::string& path : {std::string("/v1/jobs"), job, job + "/points", std::string("/metrics")})
    EXPECT_EQ(ErrorCode(Client().Get(path, Auth(kWorkerToken))), "403 forbidden") << path;
  EXPECT_EQ(Lease().at("job_id"), id);
}

// Item 5: made-up rows (another table, extra fields, off the grid, not finite, too many) were
// stored and then served from the cache to anyone who submitted the same job.
TEST_F(HostileInputTest, CompletedRowsMustBeRowsTheTaskCouldHaveWritten) {
  Start();
  const int64_t id = Submit(kOneTaskSimulate);
  const json task = Lease();
  const std::vector<jobs::ResultRow> honest = jobs::RunTask(task.at("spec")).AllRows();
  ASSERT_EQ(honest.size(), 1u);
  const json record = honest[0].values;
  const auto rows = [](const std::string& table, const json& values) {
    return json::array({{{"table", table}, {"values", values}}}).dump();
  };
  json extra = record, off_grid = record, wrong_type = record;
  extra["h_re"] = 1e9;
  off_grid["frequency_hz"] = 9;
  wrong_type["contacts"] = "many";
  const std::vector<std::pair<std::string, std::string>> forged = {
      {rows("points", record), "/rows/0/table"},
      {rows("records", extra), "/rows/0/values/h_re"},
      {rows("records", off_grid), "/rows/0/values/frequency_hz"},
      {rows("records", wrong_type), "/rows/0/values/contacts"},
      {"[" + rows("records", record).substr(1, rows("records", record).size() - 2) + "," +
           rows("records", record).substr(1), "/rows"},
      {"[]", "/rows"}};
  for (const auto& [body, field] : forged) {
    const httplib::Result r = Complete(task, body);
    EXPECT_EQ(ErrorCode(r), "400 invalid_rows") << body.substr(0, 200);
    if (r) {
      EXPECT_EQ(json::parse(r->body)["error"].value("field", ""), field) << r->body;
    }
  }
  EXPECT_EQ(JobStatus(id).value("status", ""), "running") << "nothing was written";
  EXPECT_EQ(ErrorCode(Complete(task, rows(honest[0].table, record))), "200 ");
  EXPECT_EQ(JobStatus(id).value("status", ""), "succeeded");
}

// Item 7: the page had no Content-Security-Policy, X-Frame-Options or nosniff. Its policy allows
// its own inline script by this response's nonce (tests/web/web_page_test.sh checks in Chromium
// that nothing on the page is blocked).
TEST_F(HostileInputTest, ThePageCarriesSecurityHeadersAndItsScriptTheNonce) {
  Start();
  auto page = Client().Get("/");
  ASSERT_TRUE(page && page->status == 200);
  EXPECT_EQ(page->get_header_value("X-Frame-Options"), "DENY");
  EXPECT_EQ(page->get_header_value("X-Content-Type-Options"), "nosniff");
  const std::string policy = page->get_header_value("Content-Security-Policy");
  const size_t at = policy.find("'nonce-");
  ASSERT_NE(at, std::string::npos) << policy;
  const std::string nonce = policy.substr(at + 7, policy.find('\'', at + 7) - at - 7);
  EXPECT_NE(page->body.find("<script nonce=\"" + nonce + "\">"), std::string::npos);
  EXPECT_NE(policy.find("frame-ancestors 'none'"), std::string::npos) << policy;
  EXPECT_EQ(Client().Get("/v1/health")->get_header_value("X-Content-Type-Options"), "nosniff");
}

// Item 7: cpp-httplib trims blanks from header values, so "Bearer TOKEN " passed for the token.
TEST_F(HostileInputTest, ABearerTokenWithATrailingBlankIsRefused) {
  Start();
  for (const char* blank : {" ", "\t", "  "})
    EXPECT_EQ(ErrorCode(Client().Get("/v1/jobs", {{"Authorization", std::string("Bearer ") + kReadToken + blank}})),
              "401 unauthorized");
  EXPECT_EQ(Client().Get("/v1/jobs", Auth(kReadToken))->status, 200);
}

// Item 7: a SIGKILL during an upload left DB.campaigns/.incoming-ID behind for good.
TEST_F(HostileInputTest, UnpackingLeftoversAreRemovedAtStart) {
  const std::filesystem::path uploads = dir_ / "jobs.db.campaigns";
  std::filesystem::create_directories(uploads / ".incoming-0123456789abcdef" / "campaign");
  std::ofstream(uploads / ".incoming-0123456789abcdef" / "campaign" / "rec_001.csv") << "t,v\n";
  std::filesystem::create_directories(uploads / "0123456789abcdef");
  Start();
  EXPECT_FALSE(std::filesystem::exists(uploads / ".incoming-0123456789abcdef"));
  EXPECT_TRUE(std::filesystem::exists(uploads / "0123456789abcdef")) << "finished uploads are kept";
}

// Item 7: error messages carried the server's absolute paths (here: a campaign without a manifest
// under the data root).
TEST_F(HostileInputTest, ErrorMessagesDoNotShowServerPaths) {
  options_.data_root = (dir_ / "root").string();
  std::filesystem::create_directories(dir_ / "root" / "empty");
  Start();
  const json fit = {{"kind", "fit"}, {"model", "paper"}, {"campaign", {{"path", "empty"}}}};
  auto r = Client().Post("/v1/jobs", Auth(kSubmitToken), fit.dump(), "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(ErrorCode(r), "400 invalid_campaign");
  EXPECT_EQ(r->body.find(dir_.string()), std::string::npos) << r->body;
  EXPECT_NE(r->body.find("<data-root>"), std::string::npos) << r->body;
}

}  // namespace
}  // namespace strokelab::server
