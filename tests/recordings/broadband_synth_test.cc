// Broadband drives (data/excitation.h) and broadband campaigns from the synthesiser (data/synth.h):
// each signal's spectrum and level, a multisine through a linear actuator against paper Eq. 3 line by
// line, its even lines lit by the stop's distortion, and `strokelab synth --excitation` and `strokelab
// fit` on a broadband campaign end to end.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "cli/run_cli.h"
#include "strokelab/base/errors.h"
#include "strokelab/data/excitation.h"
#include "strokelab/data/recordings.h"
#include "strokelab/data/synth.h"
#include "strokelab/model/linear_response.h"
#include "strokelab/model/model.h"
#include "strokelab/model/model_json.h"

#include "recordings_test_util.h"

namespace strokelab {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// The DFT of x at bin k: sum_n x_n e^{-j 2 pi k n / N}, directly (the test needs a few bins).
std::complex<double> Bin(const std::vector<double>& x, size_t k) {
  std::complex<double> sum = 0.0;
  const double step = -2.0 * std::numbers::pi * static_cast<double>(k) / static_cast<double>(x.size());
  for (size_t n = 0; n < x.size(); ++n) sum += x[n] * std::polar(1.0, step * static_cast<double>(n));
  return sum;
}

double Rms(const std::vector<double>& x) {
  double sum = 0.0;
  for (double v : x) sum += v * v;
  return std::sqrt(sum / static_cast<double>(x.size()));
}

std::function<double()> Uniforms(unsigned seed) {
  auto engine = std::make_shared<std::mt19937_64>(seed);
  return [engine] { return static_cast<double>((*engine)() >> 11) * 0x1.0p-53; };
}

// One period of a multisine at fs = 1024 Hz, T = 1 s: the odd lines of 10..40 Hz carry equal
// amplitudes, every other bin is empty (to rounding), the rms is the level, and it repeats.
TEST(BroadbandVoltage, AMultisineHasEqualOddLinesInItsBandOnly) {
  BroadbandSignal signal;
  signal.excitation = Excitation::kMultisine;
  signal.band_low_hz = 10.0;
  signal.band_high_hz = 40.0;
  signal.level_v_rms = 0.2;
  const std::vector<double> v = BroadbandVoltage(signal, 1024.0, 0.0, 2048, 0.0, Uniforms(1));
  const std::vector<double> first(v.begin(), v.begin() + 1024), second(v.begin() + 1024, v.end());
  EXPECT_EQ(first, second);
  EXPECT_NEAR(Rms(first), 0.2, 1e-12);
  const double line = std::abs(Bin(first, 11));
  for (size_t k = 0; k < 512; ++k) {
    const bool excited = k >= 10 && k <= 40 && k % 2 == 1;
    if (excited) EXPECT_NEAR(std::abs(Bin(first, k)), line, 1e-9 * line) << k;
    else EXPECT_LT(std::abs(Bin(first, k)), 1e-9 * line) << k;
  }
  signal.odd_grid = false;
  const std::vector<double> full = BroadbandVoltage(signal, 1024.0, 0.0, 1024, 0.0, Uniforms(1));
  EXPECT_GT(std::abs(Bin(full, 12)), 0.5 * std::abs(Bin(full, 11)));
}

// Noise over its whole length N: nothing outside the band, the rms the level, and Rayleigh line
// amplitudes (their mean square over their squared mean is 4 / pi for a Rayleigh law; 1 for a multisine).
TEST(BroadbandVoltage, NoiseIsBandLimitedWithRandomAmplitudes) {
  BroadbandSignal signal;
  signal.excitation = Excitation::kNoise;
  signal.band_low_hz = 20.0;
  signal.band_high_hz = 300.0;
  signal.level_v_rms = 0.3;
  const size_t n = 4000;  // 2^5 5^3: the generator's own length, so that its grid is the DFT's
  const std::vector<double> v = BroadbandVoltage(signal, 2000.0, 0.0, n, 2.0, Uniforms(2));
  EXPECT_NEAR(Rms(v), 0.3, 1e-12);
  double sum = 0.0, sum_squares = 0.0, peak = 0.0;
  int lines = 0;
  for (size_t k = 0; k < n / 2; ++k) peak = std::max(peak, std::abs(Bin(v, k)));
  for (size_t k = 0; k < n / 2; ++k) {
    const double a = std::abs(Bin(v, k));
    const double f_hz = static_cast<double>(k) / 2.0;
    if (f_hz < 20.0 || f_hz > 300.0) {
      EXPECT_LT(a, 1e-9 * peak) << f_hz << " Hz";
      continue;
    }
    sum += a;
    sum_squares += a * a;
    ++lines;
  }
  // 561 Rayleigh draws: the ratio's standard error is ~0.02; 4 / pi = 1.27.
  EXPECT_NEAR(sum_squares * lines / (sum * sum), 4.0 / std::numbers::pi, 0.1);
}

// The sweep's half-periods follow its exponential frequency, the sine at f1 before it; its amplitude is
// sqrt(2) times the level.
TEST(BroadbandVoltage, ASweepRunsFromTheLowToTheHighEdge) {
  BroadbandSignal signal;
  signal.excitation = Excitation::kSweep;
  signal.band_low_hz = 5.0;
  signal.band_high_hz = 100.0;
  signal.level_v_rms = 0.1;
  signal.period_s = 2.0;
  const double fs = 20000.0;
  const std::vector<double> v = BroadbandVoltage(signal, fs, -0.5, 50000, 0.0, Uniforms(3));
  std::vector<double> crossings;  // instants of upward and downward zero crossings
  for (size_t n = 1; n < v.size(); ++n)
    if ((v[n - 1] < 0) != (v[n] < 0)) crossings.push_back(-0.5 + (n - v[n] / (v[n] - v[n - 1])) / fs);
  // Between two crossings around t the sine has run half a period of f(t) = f1 e^{t ln(f2 / f1) / T}
  // (to (rate dt)^2 / 24 ~ 1e-5 of it; before t = 0, f1).
  auto expect_half_period = [&](double t) {
    for (size_t i = 1; i < crossings.size(); ++i) {
      if (crossings[i] <= t) continue;
      const double middle = 0.5 * (crossings[i] + crossings[i - 1]);
      const double f_hz = middle < 0 ? 5.0 : 5.0 * std::exp(middle * std::log(20.0) / 2.0);
      EXPECT_NEAR((crossings[i] - crossings[i - 1]) * 2.0 * f_hz, 1.0, 1e-3) << t;
      return;
    }
    ADD_FAILURE() << "no crossing after " << t;
  };
  for (double t : {-0.3, 0.02, 1.0, 1.99}) expect_half_period(t);
  EXPECT_LT(crossings.back() - crossings[crossings.size() - 2], 1.0 / 150.0);  // f2 = 100 Hz after T
  double peak = 0.0;
  for (double x : v) peak = std::max(peak, std::abs(x));
  EXPECT_NEAR(peak, std::sqrt(2.0) * 0.1, 1e-6);
}

TEST(BroadbandVoltage, BadSignalsNameTheField) {
  auto field_of = [](BroadbandSignal s, double fs) {
    const auto error = s.IsValid(fs);
    return error ? error->field : std::string();
  };
  BroadbandSignal ok;
  EXPECT_EQ(field_of(ok, 1000.0), "");
  EXPECT_EQ(field_of(ok, 300.0), "band_high_hz");  // 200 Hz is above Nyquist
  BroadbandSignal narrow = ok;
  narrow.band_low_hz = 2.2;
  narrow.band_high_hz = 2.8;  // no line k / 1 s
  EXPECT_EQ(field_of(narrow, 1000.0), "band_low_hz");
  BroadbandSignal uneven = ok;
  uneven.period_s = 1.0005;  // 1000.5 samples at 1 kHz
  EXPECT_EQ(field_of(uneven, 1000.0), "period_s");
  BroadbandSignal sweep = ok;
  sweep.excitation = Excitation::kSweep;
  sweep.band_low_hz = 0.0;
  EXPECT_EQ(field_of(sweep, 1000.0), "band_low_hz");
  BroadbandSignal negative = ok;
  negative.level_v_rms = -1;
  EXPECT_EQ(field_of(negative, 1000.0), "level_v_rms");
}

SynthOptions MultisineSynth() {
  SynthOptions options;
  options.excitation = Excitation::kMultisine;
  options.broadband.band_low_hz = 2.0;
  options.broadband.band_high_hz = 200.0;
  options.levels_v_rms = {0.05, 1.0};  // 1 V rms reaches 1.8 mm: into the paper's stop at 1 mm
  options.duration_s = 1.0;
  options.settle_s = 3.0;  // e^{-c_p / (2 m_p) 3 s} = e^{-61}: the start is forgotten
  options.sample_rate_hz = 8192.0;
  return options;
}

// Without a stop the actuator is linear: the blocked force over the voltage at each excited line is
// paper Eq. 3 (ForceFrf). The first-order hold of the voltage departs from the sampled multisine by
// at most (w / fs)^2 / 12 relative at a line (2.5e-4 at 200 Hz and 8192 Hz); 5e-4 allows for it.
TEST(SynthesizeBroadband, AMultisineThroughALinearActuatorIsEquationThreeAtEveryLine) {
  ActuatorModel linear = PaperModel();
  linear.lower_stop_m = ActuatorModel::kNoLowerStop;
  const Synthesis synthesis = Synthesize(linear, MultisineSynth());
  ASSERT_EQ(synthesis.campaign.records.size(), 2u);
  EXPECT_EQ(synthesis.engine, "flow");
  for (const Recording& record : synthesis.campaign.records) {
    ASSERT_TRUE(record.broadband);
    ASSERT_EQ(record.size(), 8192u);
    for (size_t k = 3; k <= 199; k += 2) {
      const std::complex<double> measured = Bin(record.response, k) / Bin(record.voltage_v, k);
      const std::complex<double> expected = ForceFrf(linear, 2.0 * std::numbers::pi * static_cast<double>(k));
      EXPECT_LT(std::abs(measured / expected - 1.0), 5e-4) << k << " Hz";
    }
  }
}

// With the paper's stop the low level (0.05 V rms) stays clear of it and the response has nothing
// at the even lines (an odd multisine's linear response is odd in half a period); the high level hits
// the stop, whose one-sided force lights the even lines.
TEST(SynthesizeBroadband, TheStopsDistortionShowsAtTheEvenLines) {
  const Synthesis synthesis = Synthesize(PaperModel(), MultisineSynth());
  double ratio[2];
  for (int r = 0; r < 2; ++r) {
    const Recording& record = synthesis.campaign.records[r];
    double odd = 0.0, even = 0.0;
    for (size_t k = 2; k <= 200; ++k) (k % 2 ? odd : even) += std::norm(Bin(record.response, k));
    ratio[r] = even / odd;
  }
  EXPECT_LT(ratio[0], 1e-12);
  EXPECT_GT(ratio[1], 1e-4);
}

TEST(SynthesizeBroadband, RejectsAMethodAndBadLevelsNamingTheField) {
  auto field_of = [](SynthOptions options) -> std::string {
    try {
      Synthesize(PaperModel(), options);
    } catch (const InputError& e) {
      return e.field();
    }
    return "";
  };
  SynthOptions method = MultisineSynth();
  method.method = Method::kCvode;
  EXPECT_EQ(field_of(method), "method");
  SynthOptions empty = MultisineSynth();
  empty.levels_v_rms.clear();
  EXPECT_EQ(field_of(empty), "levels_v_rms");
  SynthOptions uneven = MultisineSynth();
  uneven.duration_s = 1.00001;
  EXPECT_EQ(field_of(uneven), "duration_s");
}

// `strokelab synth --excitation noise` writes broadband records that read back as such, with the
// excitation in the truth and not in the manifest; the same seed gives the same files.
TEST(SynthCli, WritesABroadbandCampaignThatReadsBack) {
  const fs::path dir = recordings_test::TempDir("synth_broadband");
  const std::string args = "synth --out " + dir.string() +
                           " --excitation noise --levels-v-rms 0.1,0.2 --band-hz 5:100 --duration-s 0.5"
                           " --settle-s 0.5 --sample-rate-hz 4096 --noise-rms 1e-4 --seed 11 --set k3=4e7";
  const auto result = testing::RunCli(args);
  ASSERT_EQ(result.exit_code, 0) << result.stderr_text;
  EXPECT_THAT(result.stdout_text, HasSubstr("wrote 2 records (force, noise, method flow)"));
  const Campaign campaign = ReadCampaign(dir);
  ASSERT_EQ(campaign.records.size(), 2u);
  for (const Recording& record : campaign.records) {
    EXPECT_TRUE(record.broadband);
    EXPECT_EQ(record.size(), 2048u);
  }
  EXPECT_NEAR(Rms(campaign.records[1].voltage_v), 0.2, 0.02);
  const nlohmann::json truth = nlohmann::json::parse(recordings_test::ReadText(dir / "truth.json"));
  EXPECT_EQ(truth["excitation"]["kind"], "noise");
  EXPECT_EQ(truth["records"][1]["level_v_rms"], 0.2);
  EXPECT_THAT(recordings_test::ReadText(dir / "manifest.json"), ::testing::Not(HasSubstr("noise")));
  const fs::path again = recordings_test::TempDir("synth_broadband_again");
  std::string args_again = args;
  args_again.replace(args_again.find(dir.string()), dir.string().size(), again.string());
  ASSERT_EQ(testing::RunCli(args_again).exit_code, 0);
  EXPECT_EQ(recordings_test::ReadText(dir / "rec_002.csv"), recordings_test::ReadText(again / "rec_002.csv"));
  fs::remove_all(dir);
  fs::remove_all(again);
}

// `strokelab fit` on a broadband campaign fits it by its time series: the text report says so and the
// JSON carries the parameters with their standard errors (the stop is not fitted: no record reaches it).
TEST(FitCli, FitsABroadbandCampaignByItsTimeSeries) {
  const fs::path dir = recordings_test::TempDir("fit_broadband");
  const auto synth = testing::RunCli("synth --out " + dir.string() +
                                     " --excitation multisine --levels-v-rms 0.1 --duration-s 1 --settle-s 2"
                                     " --sample-rate-hz 8192 --noise-rms 2e-4 --seed 12");
  ASSERT_EQ(synth.exit_code, 0) << synth.stderr_text;
  const auto text = testing::RunCli("fit --data " + dir.string());
  ASSERT_EQ(text.exit_code, 0) << text.stderr_text;
  EXPECT_THAT(text.stdout_text, HasSubstr("1 broadband records fitted by their time series"));
  EXPECT_THAT(text.stdout_text, HasSubstr("converged"));
  EXPECT_THAT(text.stdout_text, HasSubstr("no record shows an impact"));
  const auto json = testing::RunCli("fit --json --data " + dir.string());
  ASSERT_EQ(json.exit_code, 0) << json.stderr_text;
  const nlohmann::json result = nlohmann::json::parse(json.stdout_text);
  EXPECT_EQ(result["kind"], "broadband");
  EXPECT_TRUE(result["converged"].get<bool>());
  EXPECT_FALSE(result["rejected"].get<bool>());
  EXPECT_NEAR(result["parameters"]["k_p"]["value"].get<double>(), 124.0,
              4.0 * result["parameters"]["k_p"]["standard_error"].get<double>());
  EXPECT_FALSE(result["parameters"].contains("d"));
  fs::remove_all(dir);
}

// `strokelab diagnose` on a broadband campaign diagnoses it by its time series: the text report and the
// JSON say so, and --out writes the diagnosis and the diagnosed model as a model file. (A time limit of
// 1 s skips the candidates: the diagnosis itself is broadband_diagnose_test.cc's.)
TEST(DiagnoseCli, DiagnosesABroadbandCampaignByItsTimeSeries) {
  const fs::path dir = recordings_test::TempDir("diagnose_broadband");
  const fs::path out = recordings_test::TempDir("diagnose_broadband_out");
  const auto synth = testing::RunCli("synth --out " + dir.string() +
                                     " --excitation multisine --levels-v-rms 0.1,0.2 --duration-s 1 --settle-s 2"
                                     " --sample-rate-hz 8192 --noise-rms 2e-4 --seed 13");
  ASSERT_EQ(synth.exit_code, 0) << synth.stderr_text;
  const auto text = testing::RunCli("diagnose --max-seconds 1 --data " + dir.string() + " --out " + out.string());
  ASSERT_EQ(text.exit_code, 0) << text.stderr_text;
  EXPECT_THAT(text.stdout_text, HasSubstr("normalised RMS error of the time series"));
  EXPECT_THAT(text.stdout_text, HasSubstr("held-out parts (1/4 of each record"));
  EXPECT_THAT(text.stdout_text, HasSubstr("skipped: the diagnosis's time limit"));
  const nlohmann::json model = nlohmann::json::parse(std::ifstream(out / "model.json"));
  EXPECT_NEAR(ModelFromJson(model).stiffness_n_per_m, PaperModel().stiffness_n_per_m,
              0.05 * PaperModel().stiffness_n_per_m);  // a model file, with the fitted k_p
  const nlohmann::json result = nlohmann::json::parse(std::ifstream(out / "diagnosis.json"));
  EXPECT_EQ(result["kind"], "broadband");
  EXPECT_EQ(result["model"], model);
  EXPECT_EQ(result["records"].size(), 2u);
  EXPECT_GT(result["heldout_dof"].get<double>(), 0.0);
  // The report folder (report/broadband_report.h), its page named on stdout.
  EXPECT_THAT(text.stdout_text, HasSubstr("report: " + (out / "index.html").string()));
  std::stringstream page;
  page << std::ifstream(out / "index.html").rdbuf();
  EXPECT_THAT(page.str(), HasSubstr("strokelab diagnosis (broadband records)"));
  EXPECT_THAT(page.str(), HasSubstr("Held-out parts (no fit saw them)"));
  for (const char* file : {"records.csv", "candidates.csv", "candidate_parameters.csv"})
    EXPECT_TRUE(fs::exists(out / file)) << file;
  fs::remove_all(dir);
  fs::remove_all(out);
}

}  // namespace
}  // namespace strokelab
