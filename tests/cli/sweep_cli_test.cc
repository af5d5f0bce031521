// `strokelab sweep` end to end: bad grids get one line naming the flag and exit code 2; a small
// real sweep prints the promised JSON, agrees with the closed forms where the response stays off
// the stop, and writes its folder; Ctrl-C cancels with exit code 130.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "run_cli.h"
#include <signal.h>
#include <spawn.h>
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>
#include <thread>

#include "strokelab/model/linear_response.h"
#include "strokelab/model/model.h"
#include "test_util.h"

namespace {

using ::testing::HasSubstr;

using Result = ::strokelab::testing::CliResult;
using ::strokelab::testing::RunCli;

// `strokelab sweep ARGS` fails with one line, exit code 2, naming what is wrong.
void ExpectSweepInputError(const std::string& args, const std::string& expected) {
  ::strokelab::testing::ExpectInputError("sweep " + args, expected);
}

TEST(SweepCliTest, BadGridsNameTheFlag) {
  // SweepSpec::Validate's fields (frequency_hz.to, ...) come back as the flags, in FROM:TO words.
  ExpectSweepInputError("--frequency-hz 50:5", "strokelab: error: --frequency-hz: TO must be ");
  ExpectSweepInputError("--frequency-hz 50:5", "FROM (got '50:5')");
  ExpectSweepInputError("--amplitude-v 0.6:0.1", "--amplitude-v: TO must be ");
  ExpectSweepInputError("--frequency-hz 0:50", "--frequency-hz: FROM must be ");
  ExpectSweepInputError("--grid geometric --frequency-hz 5:5", "--frequency-hz: TO must be ");
  ExpectSweepInputError("--amplitude-points 0", "--amplitude-points: must be ");
  ExpectSweepInputError("--frequency-points 0", "--frequency-points: must be ");
  ExpectSweepInputError("--grid eq1 --frequency-points 0", "--frequency-points: must be ");
  ExpectSweepInputError("--threads 0", "--threads: must be ");
  ExpectSweepInputError("--grid foo", "--grid: unknown grid 'foo' (known: linear, geometric, eq1)");
  ExpectSweepInputError("--grid eq1 --frequency-hz 5:9", "--grid: eq1 fixes the frequencies");
  ExpectSweepInputError("--frequency-hz 5:", "--frequency-hz: expected FROM:TO or one value, e.g. 5:50 or 8, got '5:'");
  ExpectSweepInputError("--frequency-hz 5 --frequency-points 3", "--frequency-points: must be 1 with a single");
  ExpectSweepInputError("--frequency-hz a:5", "--frequency-hz: expected a number, got 'a'");
  ExpectSweepInputError("--amplitude-v 0.1:inf", "--amplitude-v: must be finite, got '0.1:inf'");
  ExpectSweepInputError("--frequency-points 2.5", "--frequency-points: expected an integer, got '2.5'");
  ExpectSweepInputError("--json --out x", "--json: cannot be combined with --out");
  ExpectSweepInputError("--set k9=1", "--set k9: unknown model parameter");
  ExpectSweepInputError("--model papr", "--model: unknown model preset 'papr'");
  ExpectSweepInputError("--frobnicate", "--frobnicate: unknown option");
}

TEST(SweepCliTest, HelpListsTheOptionsAndOutputs) {
  const Result r = RunCli("sweep --help");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* text : {"--frequency-hz A:B", "--grid G", "eq1", "--threads N", "--no-thresholds", "--json",
                           "saturation_map.svg", "frf_phase.svg", "aperiodic"})
    EXPECT_THAT(r.stdout_text, HasSubstr(text));
  EXPECT_THAT(RunCli("--help").stdout_text, HasSubstr("sweep "));
}

// 8 x 3 grid around the resonance (9.9 Hz). Below the lowest grazing amplitude (0.255 V near
// 8.8 Hz) the response never reaches the stop, and the sweep must reproduce paper Eq. 3 there.
TEST(SweepCliTest, SmallSweepAsJson) {
  const Result r = RunCli(
      "sweep --model paper --frequency-hz 5:20 --frequency-points 8 --amplitude-v 0.1:0.5 --amplitude-points 3 "
      "--threads 2 --json");
  ASSERT_EQ(r.exit_code, 0) << r.stderr_text;
  EXPECT_EQ(r.stderr_text, "") << "no progress line when stderr is not a terminal";
  const nlohmann::json j = nlohmann::json::parse(r.stdout_text);
  ASSERT_EQ(j["grid"]["frequency_hz"].size(), 8u);
  ASSERT_EQ(j["grid"]["amplitude_v"].size(), 3u);
  EXPECT_DOUBLE_EQ(j["grid"]["frequency_hz"][1].get<double>(), 5.0 + 15.0 / 7);
  EXPECT_DOUBLE_EQ(j["grid"]["amplitude_v"][2].get<double>(), 0.5);
  ASSERT_EQ(j["saturation_threshold"].size(), 8u);
  EXPECT_TRUE(j["jump"].is_array());
  EXPECT_GT(j["wall_time_s"].get<double>(), 0.0);
  EXPECT_GT(j["points_per_second"].get<double>(), 0.0);
  EXPECT_DOUBLE_EQ(j["model"]["stiffness_n_per_m"].get<double>(), 124.0);

  const strokelab::ActuatorModel model = strokelab::PaperModel();
  size_t up_points = 0;
  for (const auto& p : j["points"]) {
    for (const char* key : {"frequency_hz", "amplitude_v", "branch", "stable", "period", "first_harmonic_force_n",
                            "first_harmonic_phase_rad", "h_re_n_per_v", "h_im_n_per_v", "min_displacement_m", "max_displacement_m",
                            "peak_force_n", "contacts_per_period", "max_multiplier"})
      ASSERT_TRUE(p.contains(key)) << key;
    ASSERT_THAT(p["branch"].get<std::string>(), ::testing::AnyOf("up", "down", "unstable"));
    ASSERT_TRUE(p["period"].is_number_integer() || p["period"] == "aperiodic") << p.dump();
    if (p["branch"] != "up") continue;
    ++up_points;
    // 0.1 V: far below every grazing amplitude, a linear steady state.
    if (p["amplitude_v"].get<double>() == 0.1) {
      const double w = 2 * std::numbers::pi * p["frequency_hz"].get<double>();
      const std::complex<double> h(p["h_re_n_per_v"].get<double>(), p["h_im_n_per_v"].get<double>());
      EXPECT_REL_NEAR(h, strokelab::ForceFrf(model, w), 1e-6) << p.dump();
      EXPECT_EQ(p["contacts_per_period"].get<double>(), 0.0);
      EXPECT_EQ(p["period"], 1);
      EXPECT_TRUE(p["stable"].get<bool>());
    }
  }
  EXPECT_GE(up_points, 24u) << "an up-branch steady state at every grid point";
  // The grazing amplitude is the closed form V_sat (linear_response.h) of the piecewise-linear model.
  for (const auto& t : j["saturation_threshold"]) {
    const double w = 2 * std::numbers::pi * t["frequency_hz"].get<double>();
    EXPECT_REL_NEAR(t["grazing_amplitude_v"].get<double>(), strokelab::LinearSaturationThresholdV(model, w), 1e-3);
  }
}

// The Eq. 1 grid, without thresholds; RunSweep promises the same steady states on any thread count.
TEST(SweepCliTest, Eq1GridAndThreadCountDoNotChangeTheResult) {
  const std::string args = "sweep --grid eq1 --frequency-points 20 --amplitude-v 0.3:0.5 --amplitude-points 2 "
                           "--no-thresholds --json --threads ";
  const Result one = RunCli(args + "1"), three = RunCli(args + "3");
  ASSERT_EQ(one.exit_code, 0) << one.stderr_text;
  ASSERT_EQ(three.exit_code, 0) << three.stderr_text;
  const nlohmann::json a = nlohmann::json::parse(one.stdout_text), b = nlohmann::json::parse(three.stdout_text);
  ASSERT_EQ(a["grid"]["frequency_hz"].size(), 20u);
  for (int n = 1; n <= 20; ++n)  // paper Eq. 1: f_n = 5 Hz * 1.02^(n-1)
    EXPECT_REL_NEAR(a["grid"]["frequency_hz"][n - 1].get<double>(), 5.0 * std::pow(1.02, n - 1), 1e-12);
  EXPECT_TRUE(a["saturation_threshold"].empty());
  EXPECT_TRUE(a["jump"].empty());
  EXPECT_EQ(a["points"], b["points"]);
}

TEST(SweepCliTest, WritesTheFolderAndPrintsTheSummary) {
  const std::string dir = ::testing::TempDir() + "/sweep_cli_out";
  std::filesystem::remove_all(dir);
  const Result r = RunCli("sweep --grid eq1 --frequency-points 12 --amplitude-v 0.2:0.4 --amplitude-points 2 --out " +
                          dir);
  ASSERT_EQ(r.exit_code, 0) << r.stderr_text;
  EXPECT_THAT(r.stdout_text, HasSubstr("12 values, 5 .. 6.21"));
  EXPECT_THAT(r.stdout_text, HasSubstr("geometric (ratio 1.02)"));
  for (const char* name : {"points.csv", "saturation_threshold.csv", "jump.csv", "saturation_map.svg",
                           "saturation_map_down.svg", "frf_up.svg", "frf_down.svg", "frf_phase.svg", "summary.txt",
                           "model.json"}) {
    EXPECT_TRUE(std::filesystem::is_regular_file(dir + "/" + name)) << name;
    EXPECT_GT(std::filesystem::file_size(dir + "/" + name), 0u) << name;
  }
}

// SIGINT while sweeping: the sweep stops, says so, exits with 130.
TEST(SweepCliTest, InterruptCancels) {
  const std::string err_path = ::testing::TempDir() + "/sweep_cli_cancel_stderr.txt";
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  // A grid far too big to finish within the wait below.
  std::vector<std::string> args = {STROKELAB_BINARY,    "sweep", "--frequency-points", "4000",
                                   "--amplitude-points", "80",   "--threads",          "1"};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  ASSERT_EQ(posix_spawn(&pid, STROKELAB_BINARY, &actions, nullptr, argv.data(), environ), 0);
  posix_spawn_file_actions_destroy(&actions);
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  ASSERT_EQ(kill(pid, SIGINT), 0);
  int status = 0;
  const auto sent = std::chrono::steady_clock::now();
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  const double wait_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - sent).count();
  ASSERT_TRUE(WIFEXITED(status)) << "killed by signal " << WTERMSIG(status);
  EXPECT_EQ(WEXITSTATUS(status), 130);
  EXPECT_LT(wait_s, 20.0) << "the sweep should stop at its next unit of work";
  std::ifstream err(err_path);
  const std::string text((std::istreambuf_iterator<char>(err)), {});
  EXPECT_EQ(text, "strokelab: cancelled\n");
}

}  // namespace
