// What a new user met in the CLI's first hour (issue 16, point 3), one test per defect: errors
// under the name of the flag that caused them, a single grid value, help that says what a flag
// does, client commands that name the server they tried, print a fit's result, exit 2 on an
// invalid job, and help of more than one line.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "process/service.h"
#include "run_cli.h"

namespace {

using ::strokelab::testing::CliResult;
using ::strokelab::testing::ExpectInputError;
using ::strokelab::testing::RunCli;
using ::testing::HasSubstr;
using ::testing::Not;
namespace process = ::strokelab::test_process;

// The drive frequency above Nyquist was refused by the summary's harmonic analysis as "orders:".
TEST(CliFirstHourTest, ASampleRateBelowTwiceTheDriveIsRefusedNamingTheFlag) {
  ExpectInputError("simulate --frequency-hz 8 --amplitude-v 0.4 --sample-rate-hz 10",
                   "--sample-rate-hz: must be more than twice --frequency-hz (8 Hz)");
  ExpectInputError("simulate --frequency-hz 8 --amplitude-v 0.4 --sample-rate-hz 16", "--sample-rate-hz:");
}

// `--amplitude-v 0.3` was refused ("expected FROM:TO"): one value is one grid amplitude.
TEST(CliFirstHourTest, OneAmplitudeOrFrequencyIsOneGridValue) {
  const CliResult r = RunCli("sweep --frequency-hz 5:20 --frequency-points 4 --amplitude-v 0.3 --json");
  ASSERT_EQ(r.exit_code, 0) << r.stderr_text;
  const nlohmann::json j = nlohmann::json::parse(r.stdout_text);
  EXPECT_EQ(j["grid"]["amplitude_v"], nlohmann::json::array({0.3}));
  EXPECT_EQ(j["grid"]["frequency_hz"].size(), 4u);
  const CliResult f = RunCli("sweep --frequency-hz 8 --amplitude-v 0.2:0.4 --amplitude-points 3 --json");
  ASSERT_EQ(f.exit_code, 0) << f.stderr_text;
  EXPECT_EQ(nlohmann::json::parse(f.stdout_text)["grid"]["frequency_hz"], nlohmann::json::array({8.0}));
  ExpectInputError("sweep --amplitude-v 0.3 --amplitude-points 3", "--amplitude-points: must be 1 with a single");
}

// The help said --no-thresholds skips the jump intervals, which are printed anyway (they come with
// the rows): the help says what is skipped and what is still given.
TEST(CliFirstHourTest, TheNoThresholdsHelpSaysWhatTheFlagSkips) {
  const CliResult help = RunCli("sweep --help");
  EXPECT_THAT(help.stdout_text, Not(HasSubstr("skip the saturation thresholds and jump intervals")));
  EXPECT_THAT(help.stdout_text, HasSubstr("jump\n                         intervals come with the amplitude rows and "
                                          "are still given"));
  const CliResult r = RunCli("sweep --frequency-hz 10:16 --frequency-points 13 --amplitude-v 0.6 --no-thresholds --json");
  ASSERT_EQ(r.exit_code, 0) << r.stderr_text;
  const nlohmann::json j = nlohmann::json::parse(r.stdout_text);
  EXPECT_TRUE(j["saturation_threshold"].empty());
  EXPECT_FALSE(j["jump"].empty()) << "the paper model jumps near 14-15 Hz at 0.6 V";
}

// "cannot reach the server (Connection)" without the URL; STROKELAB_SERVER was not read.
TEST(CliFirstHourTest, AClientCommandNamesTheServerItTried) {
  ::setenv("STROKELAB_SERVER", "http://127.0.0.1:1", 1);
  const CliResult from_env = RunCli("status 3");
  EXPECT_EQ(from_env.exit_code, 1);
  EXPECT_THAT(from_env.stderr_text, HasSubstr("cannot reach the server at http://127.0.0.1:1 ($STROKELAB_SERVER)"));
  const CliResult from_flag = RunCli("results 3 --server http://127.0.0.1:2");
  EXPECT_THAT(from_flag.stderr_text, HasSubstr("cannot reach the server at http://127.0.0.1:2 (--server)"));
  ::unsetenv("STROKELAB_SERVER");
}

// A server with a finished fit job, for the client commands' tests below.
class CliFirstHourServiceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const process::fs::path campaigns = dir_.path() / "campaigns";
    const CliResult synth = RunCli("synth --out " + (campaigns / "c").string() +
                                   " --amplitudes-v 0.1,0.4 --settle-s 2 --seed 5");
    ASSERT_EQ(synth.exit_code, 0) << synth.stderr_text;
    server_ = process::StartServer(dir_.path(), "serve",
                                   {"--db", (dir_.path() / "jobs.db").string(), "--workers", "1", "--quiet",
                                    "--data-root", campaigns.string()});
    server_flag_ = " --server " + server_.Url();
  }
  std::string WriteJob(const std::string& name, const std::string& text) {
    const std::string path = (dir_.path() / name).string();
    std::ofstream(path) << text;
    return path;
  }

  process::ScratchDir dir_{"strokelab-cli-first-hour"};
  process::Server server_;
  std::string server_flag_;
};

// `results 5` on a fit job printed {"points": []} with exit code 0.
TEST_F(CliFirstHourServiceTest, ResultsOfAFitJobPrintTheFitOrNameTheFlag) {
  const std::string job = WriteJob("fit.json", R"({"kind": "fit", "campaign": {"path": "c"}})");
  const CliResult submitted = RunCli("submit " + job + " --wait" + server_flag_);
  ASSERT_EQ(submitted.exit_code, 0) << submitted.stderr_text;
  const std::string id = submitted.stdout_text.substr(0, submitted.stdout_text.find('\n'));
  const CliResult r = RunCli("results " + id + server_flag_);
  ASSERT_EQ(r.exit_code, 0) << r.stderr_text;
  const nlohmann::json fit = nlohmann::json::parse(r.stdout_text);
  EXPECT_FALSE(fit.contains("points")) << r.stdout_text.substr(0, 200);
  EXPECT_TRUE(fit.contains("parameters")) << r.stdout_text.substr(0, 200);
  ExpectInputError("results " + id + " --csv" + server_flag_, "--csv: applies to sweep jobs; job " + id + " is a fit job");
}

// An invalid job exited with 1 (a failure) instead of 2 (bad input) and did not name the file.
TEST_F(CliFirstHourServiceTest, SubmittingAnInvalidJobExitsWith2NamingFileAndField) {
  const std::string job = WriteJob("bad.json", R"({"kind": "sweep", "model": "paper",
    "grid": {"frequency_hz": {"from": 5, "to": 20, "points": 4}, "amplitude_v": {"from": 0.5, "to": -1, "points": 2}}})");
  ExpectInputError("submit " + job + server_flag_, job + ":/grid/amplitude_v/to: invalid_job: ");
  const std::string broken = WriteJob("broken.json", R"({"kind": )");
  ExpectInputError("submit " + broken + server_flag_, broken + ": bad_json: ");
}

// submit, status, results and worker had a one-line --help.
TEST(CliFirstHourTest, ClientCommandsHelpSaysWhatTheyDoAndEveryFlag) {
  const struct {
    std::string command;
    std::vector<std::string> mentions;
  } cases[] = {
      {"submit", {"--server", "--token", "--wait", "STROKELAB_SERVER", "STROKELAB_TOKEN", "Exit codes"}},
      {"status", {"--server", "--token", "--wait", "STROKELAB_SERVER", "succeeded"}},
      {"results", {"--server", "--token", "--csv", "--branch", "--amplitude-v", "fit or diagnose", "Exit codes"}},
      {"worker", {"--server", "--token", "--threads", "--name", "--max-tasks", "STROKELAB_SERVER"}},
  };
  for (const auto& c : cases) {
    const CliResult help = RunCli(c.command + " --help");
    EXPECT_EQ(help.exit_code, 0) << c.command;
    EXPECT_GE(std::count(help.stdout_text.begin(), help.stdout_text.end(), '\n'), 6) << help.stdout_text;
    for (const std::string& word : c.mentions) EXPECT_THAT(help.stdout_text, HasSubstr(word)) << c.command;
  }
}

// `paper` was listed under "service:" though it runs locally.
TEST(CliFirstHourTest, TheUsageListsPaperWithTheLocalCommands) {
  const std::string usage = RunCli("--help").stdout_text;
  const size_t service = usage.find("\nservice:\n");
  ASSERT_NE(service, std::string::npos) << usage;
  const size_t paper = usage.find("\n  paper ");
  ASSERT_NE(paper, std::string::npos) << usage;
  EXPECT_LT(paper, service) << usage;
}

}  // namespace
