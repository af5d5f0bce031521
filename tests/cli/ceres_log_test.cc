// Ceres' glog lines stay off the console unless STROKELAB_CERES_LOG asks for them (cli/ceres_log.h;
// issue 16, point 10). The campaign has its clear records at one frequency, where the linear fit's
// covariance is rank deficient: Ceres logs "covariance_impl.cc:772] Error: Covariance matrix is near
// rank deficient ..." at ERROR, which glog wrote to stderr before (after "WARNING: Logging before
// InitGoogleLogging() is written to STDERR").
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "run_cli.h"

namespace {

using ::strokelab::testing::CliResult;
using ::strokelab::testing::ExpectInputError;
using ::strokelab::testing::RunCli;
using ::testing::HasSubstr;

// A line glog wrote itself: its own prefix ("E20261125 16:58:51.731223 22052 file.cc:772] ...") or
// its warning about logging before initialisation.
bool IsGlogLine(const std::string& line) {
  static const std::regex glog_prefix(R"(^[IWEF]\d{8} \d\d:\d\d:\d\d\.\d+ +\d+ [^ ]+:\d+\] )");
  return std::regex_search(line, glog_prefix) || line.find("InitGoogleLogging") != std::string::npos;
}

std::vector<std::string> GlogLines(const std::string& text) {
  std::vector<std::string> found;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);)
    if (IsGlogLine(line)) found.push_back(line);
  return found;
}

class CeresLogTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    campaign_ = ::testing::TempDir() + "/ceres_log_campaign_" + std::to_string(::getpid());
    // Four clear records at 8 Hz (one frequency: the linear fit's w_p and zeta_p are not separable),
    // two that reach the stop.
    const CliResult synth = RunCli("synth --out " + campaign_ +
                                   " --amplitudes-v 0.05,0.06,0.07,0.08,0.4,0.5 --frequencies-hz 8 --settle-s 2 --seed 3");
    ASSERT_EQ(synth.exit_code, 0) << synth.stderr_text;
  }
  static void TearDownTestSuite() { std::filesystem::remove_all(campaign_); }
  void TearDown() override { ::unsetenv("STROKELAB_CERES_LOG"); }

  static std::string campaign_;
};
std::string CeresLogTest::campaign_;

TEST_F(CeresLogTest, AFitPrintsOnlyStrokelabsOwnLines) {
  const CliResult fit = RunCli("fit --data " + campaign_);
  ASSERT_EQ(fit.exit_code, 0) << fit.stderr_text;
  EXPECT_THAT(GlogLines(fit.stderr_text), ::testing::IsEmpty()) << fit.stderr_text;
  EXPECT_EQ(fit.stderr_text, "");
}

// Every line is a progress line of its own, and says stage k of N with the time elapsed and, from the
// second stage on, an estimate of the time left (issue 16, point 11: the lines were "2.72e-06 s:
// analysing 24 records", then one per candidate with the seconds since the start, nothing in between).
TEST_F(CeresLogTest, ADiagnosisPrintsOnlyItsProgress) {
  const CliResult diagnose = RunCli("diagnose --json --no-pairs --progress --data " + campaign_);
  ASSERT_EQ(diagnose.exit_code, 0) << diagnose.stderr_text;
  EXPECT_THAT(GlogLines(diagnose.stderr_text), ::testing::IsEmpty()) << diagnose.stderr_text;
  static const std::regex line_form(
      R"(stage (\d+) of (\d+): ([^|,]+)(, [^|]+)? \| ([0-9.]+) s elapsed(, about ([0-9.]+) s left \(estimate\))?)");
  std::istringstream lines(diagnose.stderr_text);
  int last_stage = 0, stages = 0;
  std::vector<std::string> names;
  for (std::string line; std::getline(lines, line);) {
    std::smatch m;
    ASSERT_TRUE(std::regex_match(line, m, line_form)) << line << "\n" << diagnose.stderr_text;
    const int stage = std::stoi(m[1]);
    stages = std::stoi(m[2]);
    EXPECT_GE(stage, last_stage) << diagnose.stderr_text;
    EXPECT_LE(stage, stages) << diagnose.stderr_text;
    if (stage > last_stage) {
      names.push_back(m[3]);
      EXPECT_EQ(m[6].matched, stage > 1) << line;  // an estimate once a stage has finished
    }
    last_stage = stage;
  }
  ASSERT_GE(names.size(), 4u) << diagnose.stderr_text;
  EXPECT_EQ(names[0], "analysing 6 records");
  EXPECT_EQ(names[1].rfind("base fit on ", 0), 0u) << names[1];
  EXPECT_EQ(names[3].rfind("candidate ", 0), 0u) << names[3];
  // Without --out there are no maps and with --no-pairs no pair: N is the analysis, the base fit,
  // the signatures and one stage per candidate effect, and the last candidate is stage N.
  EXPECT_EQ(stages, static_cast<int>(names.size())) << diagnose.stderr_text;
  EXPECT_EQ(last_stage, stages) << diagnose.stderr_text;
  // Issue 16, point 5: the fixed m_p has no standard error and is not "identifiable" (its note says so).
  const nlohmann::json m_p = nlohmann::json::parse(diagnose.stdout_text)["base_parameters"]["m_p"];
  EXPECT_TRUE(m_p["standard_error"].is_null()) << m_p.dump();
  EXPECT_FALSE(m_p["identifiable"].get<bool>()) << m_p.dump();
}

TEST_F(CeresLogTest, TheVariableSendsThemToStderrOrAFileAtItsLevel) {
  ::setenv("STROKELAB_CERES_LOG", "error", 1);
  const CliResult on_stderr = RunCli("fit --data " + campaign_);
  ASSERT_EQ(on_stderr.exit_code, 0) << on_stderr.stderr_text;
  EXPECT_THAT(on_stderr.stderr_text, HasSubstr("ceres: ERROR covariance_impl.cc:"));
  EXPECT_THAT(GlogLines(on_stderr.stderr_text), ::testing::IsEmpty());

  const std::string file = ::testing::TempDir() + "/ceres_" + std::to_string(::getpid()) + ".log";
  std::filesystem::remove(file);
  ::setenv("STROKELAB_CERES_LOG", ("warning:" + file).c_str(), 1);
  const CliResult to_file = RunCli("fit --data " + campaign_);
  ASSERT_EQ(to_file.exit_code, 0) << to_file.stderr_text;
  EXPECT_EQ(to_file.stderr_text, "");
  std::ifstream in(file);
  const std::string logged((std::istreambuf_iterator<char>(in)), {});
  EXPECT_THAT(logged, HasSubstr("ceres: ERROR covariance_impl.cc:"));
  std::filesystem::remove(file);
}

TEST_F(CeresLogTest, ABadValueIsRefusedNamingTheVariable) {
  ::setenv("STROKELAB_CERES_LOG", "loud", 1);
  ExpectInputError("fit --data " + campaign_, "STROKELAB_CERES_LOG: expected off, error, warning or info");
  ::setenv("STROKELAB_CERES_LOG", "error:", 1);
  ExpectInputError("fit --data " + campaign_, "STROKELAB_CERES_LOG: no file after ':'");
}

}  // namespace
