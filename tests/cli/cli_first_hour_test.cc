// What a new user met in the CLI's first hour (issue 16, point 3), one test per defect: errors
// under the name of the flag that caused them, a single grid value, help that says what a flag
// does, client commands that name the server they tried, print a fit's result, exit 2 on an
// invalid job, and help of more than one line.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "run_cli.h"

namespace {

using ::strokelab::testing::CliResult;
using ::strokelab::testing::ExpectInputError;
using ::strokelab::testing::RunCli;
using ::testing::HasSubstr;
using ::testing::Not;

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

}  // namespace
