// Issue 16, points 5 and 11, through the binary: the fit's JSON does not contradict itself (a fixed
// parameter has no standard error and is not "identifiable"; the contact stage counts the records
// and spikes that the records table holds); a sweep's bar counts grid points, not rows; `results
// --csv` reads the server's CSV stream. (`diagnose --progress`, stage k of N with the time left, is
// checked on the small diagnosis of ceres_log_test.cc.)
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>

#include <cstdio>
#include <filesystem>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "run_cli.h"
#include "test_util.h"

namespace {

using ::strokelab::testing::CliResult;
using ::strokelab::testing::RunCli;
using ::testing::HasSubstr;
using nlohmann::json;

// A small campaign: two amplitudes clear of the stop, two that reach it, at three frequencies.
class FitProgressCliTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    campaign_ = ::testing::TempDir() + "/fit_progress_campaign_" + std::to_string(::getpid());
    const CliResult synth = RunCli("synth --out " + campaign_ + " --frequencies-hz 7,9,11 --amplitudes-v 0.1,0.15,0.4,0.5 --settle-s 2 --seed 11");
    ASSERT_EQ(synth.exit_code, 0) << synth.stderr_text;
  }
  static void TearDownTestSuite() { std::filesystem::remove_all(campaign_); }
  static std::string campaign_;
};
std::string FitProgressCliTest::campaign_;

// Every reported parameter: a fixed one has a null standard error and is not identifiable; none is
// "identifiable" with a note that says it is not (m_p was, with "not identifiable, held fixed").
void ExpectParametersAgreeWithTheirNotes(const json& parameters, const std::string& where) {
  ASSERT_TRUE(parameters.is_object()) << where;
  ASSERT_TRUE(parameters.contains("m_p")) << where << ": " << parameters.dump();
  for (const auto& [name, p] : parameters.items()) {
    if (p["fixed"].get<bool>()) {
      EXPECT_TRUE(p["standard_error"].is_null()) << where << " " << name << ": " << p.dump();
      EXPECT_FALSE(p["identifiable"].get<bool>()) << where << " " << name << ": " << p.dump();
    }
    if (p["identifiable"].get<bool>()) {
      EXPECT_THAT(p.value("note", ""), ::testing::Not(HasSubstr("not identifiable"))) << where << " " << name;
    }
  }
}

TEST_F(FitProgressCliTest, TheFitJsonDoesNotContradictItself) {
  const CliResult fit = RunCli("fit --json --data " + campaign_);
  ASSERT_EQ(fit.exit_code, 0) << fit.stderr_text;
  const json r = json::parse(fit.stdout_text);
  ExpectParametersAgreeWithTheirNotes(r["parameters"], "fit");
  // The contact stage counts what the records table shows.
  size_t not_clear = 0, with_spikes = 0, spikes = 0;
  for (const json& record : r["records"]) {
    if (record["clear"].get<bool>()) continue;
    ++not_clear;
    with_spikes += record["spikes"].get<size_t>() > 0 ? 1 : 0;
    spikes += record["spikes"].get<size_t>();
  }
  const json& contact = r["stages"]["contact"];
  ASSERT_GT(with_spikes, 0u) << "the campaign should reach the stop: " << contact.dump();
  EXPECT_EQ(contact["records_not_clear"], not_clear) << contact.dump();
  EXPECT_EQ(contact["records_with_spikes"], with_spikes) << contact.dump();
  EXPECT_EQ(contact["spikes"], spikes) << contact.dump();
  EXPECT_LE(contact["spikes_with_contact_time"].get<size_t>(), spikes) << contact.dump();
  // The text report says the same counts under the same names.
  const CliResult text = RunCli("fit --data " + campaign_);
  ASSERT_EQ(text.exit_code, 0) << text.stderr_text;
  EXPECT_THAT(text.stdout_text, HasSubstr(std::to_string(not_clear) + " records not clear of the stop, " +
                                          std::to_string(with_spikes) + " of them with impact spikes (" +
                                          std::to_string(spikes) + " spikes"));
}

// A sweep's bar moved once per amplitude row: a one-row sweep of a smooth model (seconds per row)
// showed 0/1 until it ended. It counts grid points, a row's as its continuation passes them. The bar
// is drawn on a terminal only: the sweep runs under script(1), which gives it one.
TEST(SweepBarCliTest, ASweepsBarCountsGridPoints) {
  const std::string sweep = std::string(STROKELAB_BINARY) +
                            " sweep --set k3=4e7 --frequency-hz 6:12 --frequency-points 12 --amplitude-v 0.3 --no-thresholds";
  const std::string command = "script -qec '" + sweep + "' /dev/null";
  FILE* pipe = popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string out;
  char buffer[4096];
  for (size_t n; (n = fread(buffer, 1, sizeof buffer, pipe)) > 0;) out.append(buffer, n);
  ASSERT_EQ(pclose(pipe), 0) << out;
  EXPECT_THAT(out, HasSubstr("12/12 grid points")) << out;
  EXPECT_THAT(out, ::testing::Not(HasSubstr("1/1 "))) << out;
}

// `results --csv` paged the JSON-era way (limit=10000&cursor=...) instead of reading the server's CSV
// stream. A stand-in server answers only the stream (?format=csv, neither limit nor cursor).
TEST(ResultsCsvCliTest, ResultsCsvReadsTheServersCsvStream) {
  httplib::Server server;
  std::vector<std::string> queries;
  std::mutex mutex;
  server.Get("/v1/jobs/7", [](const httplib::Request&, httplib::Response& res) {
    res.set_content(R"({"id": 7, "kind": "sweep", "status": "succeeded", "progress": {"done": 1, "total": 1}})",
                    "application/json");
  });
  server.Get("/v1/jobs/7/points", [&](const httplib::Request& req, httplib::Response& res) {
    {
      std::lock_guard<std::mutex> lock(mutex);
      queries.push_back(req.target);
    }
    if (req.get_param_value("format") != "csv" || req.has_param("limit") || req.has_param("cursor")) {
      res.status = 400;
      res.set_content(R"({"error": {"code": "bad_query", "message": "not the stream", "field": "limit"}})",
                      "application/json");
      return;
    }
    res.set_content("job_id,frequency_hz,amplitude_v,branch\n7,5,0.1,up\n7,6,0.1,up\n", "text/csv");
  });
  const int port = server.bind_to_any_port("127.0.0.1");
  ASSERT_GT(port, 0);
  std::thread listener([&server] { server.listen_after_bind(); });
  const CliResult r = RunCli("results 7 --csv --branch up --server http://127.0.0.1:" + std::to_string(port));
  server.stop();
  listener.join();
  EXPECT_EQ(r.exit_code, 0) << r.stderr_text;
  EXPECT_EQ(r.stdout_text, "job_id,frequency_hz,amplitude_v,branch\n7,5,0.1,up\n7,6,0.1,up\n");
  ASSERT_EQ(queries.size(), 1u);
  EXPECT_THAT(queries[0], HasSubstr("format=csv"));
  EXPECT_THAT(queries[0], HasSubstr("branch=up"));
}

}  // namespace
