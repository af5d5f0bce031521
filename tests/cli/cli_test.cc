// The CLI end to end: bad input gets one clear line naming the field and exit code 2, never a
// crash; --json prints the promised figures.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "run_cli.h"
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "strokelab/diagnose/diagnose.h"

namespace {

using ::testing::HasSubstr;

using Result = ::strokelab::testing::CliResult;
using ::strokelab::testing::RunCli;

const std::string kSimulate = "simulate --frequency-hz 8 --amplitude-v 0.4 --duration-s 2 ";

using ::strokelab::testing::ExpectInputError;

TEST(CliTest, BadInputNamesTheField) {
  ExpectInputError(kSimulate + "--set m_p=-0.1", "strokelab: error: m_p: must be > 0, got -0.1");
  ExpectInputError(kSimulate + "--set k_p=nan", "--set k_p: must not be NaN");
  ExpectInputError("simulate --frequency-hz 8 --amplitude-v nan", "--amplitude-v: must not be NaN");
  ExpectInputError(kSimulate + "--set k9=1", "--set k9: unknown model parameter");
  ExpectInputError(kSimulate + "--sample-rate-hz 0", "--sample-rate-hz: must be a finite number > 0");
  ExpectInputError(kSimulate + "--method rk4", "--method: unknown method 'rk4' (known: auto, exact, cvode, ode3)");
  ExpectInputError(kSimulate + "--model papr", "--model: unknown model preset 'papr'");
  ExpectInputError(kSimulate + "--frobnicate 1", "--frobnicate: unknown option");
  ExpectInputError("simulate --amplitude-v 0.3", "--frequency-hz: is required");
  ExpectInputError("simulate --frequency-hz -3 --amplitude-v 0.3", "--frequency-hz: must be a finite number > 0");
  ExpectInputError("simulate --frequency-hz 8 --amplitude-v 0.4 --duration-s abc", "--duration-s: expected a number, got 'abc'");
  ExpectInputError(kSimulate + "--set k3=4e7 --method exact",
                   "--method: the exact engine needs a piecewise-linear model; this one has k3 (cubic stiffness) "
                   "(use auto, the default, or cvode)");
  ExpectInputError(kSimulate + "--duration-s 3", "--duration-s: given more than once");
  ExpectInputError("frobnicate", "unknown command 'frobnicate'");
}

TEST(CliTest, ModelFileErrorsNameTheFileAndField) {
  const std::string dir = ::testing::TempDir();
  std::ofstream(dir + "/bad_key.json") << R"({"preset": "paper", "k_q": 3})";
  std::ofstream(dir + "/bad_value.json") << R"({"mass_kg": -1})";
  std::ofstream(dir + "/not_json.json") << R"({"mass_kg": )";
  ExpectInputError(kSimulate + "--model " + dir + "/bad_key.json", "bad_key.json:/k_q: unknown model parameter");
  ExpectInputError(kSimulate + "--model " + dir + "/bad_value.json", "bad_value.json:/mass_kg: must be > 0");
  ExpectInputError(kSimulate + "--model " + dir + "/not_json.json", "not valid JSON");
  ExpectInputError(kSimulate + "--model " + dir + "/missing.json", "--model: model file");
}

TEST(CliTest, JsonSummaryHasThePromisedFields) {
  const Result r = RunCli("simulate --model paper --frequency-hz 8 --amplitude-v 0.4 --duration-s 10 "
                          "--sample-rate-hz 51200 --method exact --json");
  ASSERT_EQ(r.exit_code, 0) << r.stderr_text;
  const nlohmann::json j = nlohmann::json::parse(r.stdout_text);
  for (const char* key : {"min_displacement_m", "max_displacement_m", "contacts", "mean_contact_ms", "peak_force_n",
                          "first_harmonic_force_n", "first_harmonic_phase_rad", "method", "wall_time_s"})
    EXPECT_TRUE(j.contains(key)) << key;
  EXPECT_EQ(j["method"], "exact");
  EXPECT_EQ(j["contacts"], 8);  // one impact per period over the last second at 8 Hz
  EXPECT_NEAR(j["min_displacement_m"].get<double>(), -1.008e-3, 0.001e-3);  // just inside d = -1 mm
  EXPECT_NEAR(j["mean_contact_ms"].get<double>(), 0.49, 0.01);
}

// Without --method the engine follows the model, and both outputs say which and why.
TEST(CliTest, TheDefaultMethodTakesAnEngineTheModelAllows) {
  const Result paper = RunCli(kSimulate + "--json");
  ASSERT_EQ(paper.exit_code, 0) << paper.stderr_text;
  EXPECT_EQ(nlohmann::json::parse(paper.stdout_text)["method"], "exact (auto: the model is piecewise linear)");

  const std::string model_path = ::testing::TempDir() + "/hertzian_model.json";
  std::ofstream(model_path) << R"({"preset": "paper", "contact_law": "hertzian", "contact_stiffness": 2.65e8})";
  const Result hertzian = RunCli(kSimulate + "--json --model " + model_path);
  ASSERT_EQ(hertzian.exit_code, 0) << hertzian.stderr_text;
  const nlohmann::json j = nlohmann::json::parse(hertzian.stdout_text);
  EXPECT_EQ(j["method"], "cvode (auto: the model has Hertzian contact, which the exact engine cannot take)");
  EXPECT_GT(j["contacts"].get<int>(), 0);

  const Result cubic = RunCli(kSimulate + "--set k3=4e7 --method auto");
  ASSERT_EQ(cubic.exit_code, 0) << cubic.stderr_text;
  EXPECT_THAT(cubic.stdout_text,
              HasSubstr("method cvode (auto: the model has k3 (cubic stiffness), which the exact engine cannot take)\n"));
  const Result named = RunCli(kSimulate + "--set k3=4e7 --method ode3 --json");
  ASSERT_EQ(named.exit_code, 0) << named.stderr_text;
  EXPECT_EQ(nlohmann::json::parse(named.stdout_text)["method"], "ode3");
}

TEST(CliTest, OverridesChangeTheModel) {
  // A hardening suspension (k3) raises the drive needed to reach the stop: no contact at 0.3 V.
  const Result base = RunCli("simulate --frequency-hz 8 --amplitude-v 0.3 --method cvode --duration-s 6 --json");
  const Result hard =
      RunCli("simulate --frequency-hz 8 --amplitude-v 0.3 --method cvode --duration-s 6 --json --set k3=4e7");
  ASSERT_EQ(base.exit_code, 0) << base.stderr_text;
  ASSERT_EQ(hard.exit_code, 0) << hard.stderr_text;
  EXPECT_GT(nlohmann::json::parse(base.stdout_text)["contacts"].get<int>(), 0);
  EXPECT_EQ(nlohmann::json::parse(hard.stdout_text)["contacts"].get<int>(), 0);
  EXPECT_EQ(nlohmann::json::parse(hard.stdout_text)["model"]["cubic_stiffness_n_per_m3"].get<double>(), 4e7);
}

TEST(CliTest, WritesTheSeriesAsCsv) {
  const std::string path = ::testing::TempDir() + "/series.csv";
  const Result r = RunCli(kSimulate + "--out " + path);
  ASSERT_EQ(r.exit_code, 0) << r.stderr_text;
  std::ifstream in(path);
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header, "time_s,voltage_V,displacement_m,velocity_m_per_s,force_N,contact");
  size_t rows = 0;
  for (std::string line; std::getline(in, line);) ++rows;
  EXPECT_EQ(rows, 102400u);
}

// fit and diagnose check their options before they read the campaign: a wrong value is reported
// under the flag that set it, in the words of FitOptions / DiagnoseOptions::IsValid.
TEST(CliTest, FitAndDiagnoseOptionErrorsNameTheFlag) {
  ExpectInputError("fit --data no-such-dir --harmonics 0", "strokelab: error: --harmonics: must be >= 1, got 0");
  ExpectInputError("fit --data no-such-dir --mass-kg -1", "--mass-kg: must be a finite number > 0, got -1");
  ExpectInputError("fit --data no-such-dir --max-distortion 0",
                   "--max-distortion: must be a finite number > 0, got 0");
  ExpectInputError("fit --data no-such-dir --max-iterations 0", "--max-iterations: must be >= 1, got 0");
  ExpectInputError("fit --data no-such-dir --model cubic", "--model: unknown fit model 'cubic' (known: paper, linear)");
  ExpectInputError("diagnose --data no-such-dir --heldout-every 1", "--heldout-every: must be >= 2, got 1");
  ExpectInputError("diagnose --data no-such-dir --min-gain -1", "--min-gain: must be a finite number >= 0");
  ExpectInputError("diagnose --data no-such-dir --max-seconds 0", "--max-seconds: must be > 0");
  ExpectInputError("diagnose --data no-such-dir --harmonics 0", "--harmonics: must be >= 1, got 0");
  ExpectInputError("diagnose --data no-such-dir --map-frequency-points 1",
                   "--map-frequency-points: must be 0 (no maps) or 2 .. 400, got 1");
  ExpectInputError("diagnose --data no-such-dir --map-amplitude-points -1",
                   "--map-amplitude-points: must be 0 (no maps) or 2 .. 400, got -1");
}

// Every flag of the option tables (FitOptionFields, DiagnoseOptionFields) is in the help texts.
TEST(CliTest, FitAndDiagnoseHelpListEveryOptionFlag) {
  const Result fit = RunCli("fit --help"), diagnose = RunCli("diagnose --help");
  ASSERT_EQ(fit.exit_code, 0);
  ASSERT_EQ(diagnose.exit_code, 0);
  for (const strokelab::OptionInfo<strokelab::FitOptions>& info : strokelab::FitOptionFields()) {
    if (info.flag == nullptr) continue;
    EXPECT_THAT(fit.stdout_text, HasSubstr(info.flag));
    EXPECT_THAT(diagnose.stdout_text, HasSubstr(info.flag));
  }
  for (const strokelab::OptionInfo<strokelab::DiagnoseOptions>& info : strokelab::DiagnoseOptionFields()) {
    if (info.flag != nullptr) {
      EXPECT_THAT(diagnose.stdout_text, HasSubstr(info.flag));
    }
  }
}

}  // namespace
