// What a new user met in the CLI's first hour (issue 16, point 3), one test per defect: errors
// under the name of the flag that caused them, a single grid value, help that says what a flag
// does, client commands that name the server they tried, print a fit's result, exit 2 on an
// invalid job, and help of more than one line.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "run_cli.h"

namespace {

using ::strokelab::testing::CliResult;
using ::strokelab::testing::ExpectInputError;
using ::strokelab::testing::RunCli;
using ::testing::HasSubstr;

// The drive frequency above Nyquist was refused by the summary's harmonic analysis as "orders:".
TEST(CliFirstHourTest, ASampleRateBelowTwiceTheDriveIsRefusedNamingTheFlag) {
  ExpectInputError("simulate --frequency-hz 8 --amplitude-v 0.4 --sample-rate-hz 10",
                   "--sample-rate-hz: must be more than twice --frequency-hz (8 Hz)");
  ExpectInputError("simulate --frequency-hz 8 --amplitude-v 0.4 --sample-rate-hz 16", "--sample-rate-hz:");
}

}  // namespace
