// The synthesiser (data/synth.h) against the engine it drives: clean channels, noise, offset and
// hum, perturbations, option errors; and `strokelab synth` end to end.
#include "strokelab/data/synth.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>
#include <vector>

#include "cli/run_cli.h"
#include "strokelab/base/errors.h"
#include "strokelab/data/recordings.h"
#include "strokelab/engines/engine.h"
#include "strokelab/model/model.h"

#include "recordings_test_util.h"

namespace strokelab {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::testing::HasSubstr;
using recordings_test::ReadText;
using recordings_test::TempDir;

// ---- Synthesis ---------------------------------------------------------------------------------

SynthOptions SmallSynth() {
  SynthOptions options;
  options.frequencies_hz = {8, 13};
  options.amplitudes_v = {0.2, 0.5};
  options.duration_s = 0.5;
  options.settle_s = 0.75;
  options.sample_rate_hz = 8192;
  return options;
}

// The engine's record of one SmallSynth step (0.75 s of settling, then the kept 0.5 s), and the index
// of its first kept sample.
Record SmallSynthStep(const ActuatorModel& model, const SineDrive& drive) {
  SimulationOptions simulation;
  simulation.duration_s = 1.25;
  simulation.sample_rate_hz = 8192;
  return MakeExactEngine()->Simulate(model, drive, simulation);
}
constexpr size_t kSmallSynthFirstKept = 10240 - 4096;

TEST(Synthesize, CleanChannelsAreTheEngineRecordInSensorVolts) {
  const ActuatorModel model = PaperModel();
  for (ResponseKind kind :
       {ResponseKind::kForce, ResponseKind::kAcceleration, ResponseKind::kVelocity, ResponseKind::kDisplacement}) {
    SynthOptions options = SmallSynth();
    options.response = kind;
    const Synthesis synthesis = Synthesize(model, options);
    EXPECT_EQ(synthesis.method, Method::kExact);
    ASSERT_EQ(synthesis.campaign.records.size(), 4u);
    const Recording& rec = synthesis.campaign.records[3];  // 13 Hz, 0.5 V: in contact
    EXPECT_EQ(rec.name, "rec_004.csv");
    EXPECT_EQ(rec.nominal_frequency_hz, 13.0);
    EXPECT_EQ(rec.nominal_amplitude_v, 0.5);
    ASSERT_EQ(rec.size(), 4096u);

    SineDrive drive;
    drive.frequency_hz = 13;
    drive.amplitude_v = 0.5;
    const Record record = SmallSynthStep(model, drive);
    const size_t first = kSmallSynthFirstKept;
    for (size_t n = 0; n < rec.size(); n += 97) {
      const double expected = kind == ResponseKind::kForce          ? record.force_n[first + n]
                              : kind == ResponseKind::kAcceleration ? record.force_n[first + n] / model.mass_kg
                              : kind == ResponseKind::kVelocity     ? record.velocity_m_per_s[first + n]
                                                                    : record.displacement_m[first + n];
      EXPECT_NEAR(rec.response[n], expected, 1e-12 * std::abs(expected) + 1e-300) << ToString(kind) << " n=" << n;
      EXPECT_NEAR(rec.voltage_v[n], drive.Voltage(static_cast<double>(first + n) / 8192), 1e-15);
    }
    EXPECT_FALSE(synthesis.truth.contains("drive_frequency_error"));  // unset: the truth as before
    EXPECT_FALSE(synthesis.truth["records"][3].contains("drive_phase_rad"));
  }

  // A generator 0.1 % fast, each drive at its own phase and a sensor 10 % above its written
  // sensitivity: the channels are the engine's record of that drive, the manifest keeps the nominal.
  SynthOptions off = SmallSynth();
  off.drive_frequency_error = 1e-3;
  off.random_drive_phase = true;
  off.sensitivity_error = 0.1;
  const Synthesis synthesis = Synthesize(model, off);
  const Recording& rec = synthesis.campaign.records[3];
  EXPECT_EQ(rec.nominal_frequency_hz, 13.0);
  EXPECT_EQ(synthesis.truth["drive_frequency_error"], 1e-3);
  EXPECT_DOUBLE_EQ(synthesis.truth["sensitivity_true"].get<double>(), 1.1 * synthesis.write.sensitivity);
  const double phase = synthesis.truth["records"][3]["drive_phase_rad"].get<double>();
  EXPECT_GE(phase, -std::numbers::pi);
  EXPECT_LT(phase, std::numbers::pi);
  EXPECT_NE(phase, synthesis.truth["records"][2]["drive_phase_rad"].get<double>());
  SineDrive drive;
  drive.frequency_hz = 13 * (1.0 + 1e-3);  // as the synthesiser computes it
  drive.amplitude_v = 0.5;
  drive.phase_rad = phase;
  const Record record = SmallSynthStep(model, drive);
  const size_t first = kSmallSynthFirstKept;
  for (size_t n = 0; n < rec.size(); n += 97) {
    const double expected = 1.1 * record.force_n[first + n];
    EXPECT_NEAR(rec.response[n], expected, 1e-12 * std::abs(expected) + 1e-300) << "n=" << n;
    EXPECT_NEAR(rec.voltage_v[n], drive.Voltage(static_cast<double>(first + n) / 8192), 1e-15);
  }
}

TEST(Synthesize, NoiseOffsetAndHumHaveTheirSettingsAndDependOnTheSeedOnly) {
  const ActuatorModel model = PaperModel();
  SynthOptions clean = SmallSynth();
  SynthOptions dirty = clean;
  dirty.noise_rms_v = 2e-3;
  dirty.voltage_noise_rms_v = 1e-4;
  dirty.offset_v = 0.05;
  dirty.hum_v = 0.01;
  dirty.voltage_offset_v = 2e-3;
  dirty.seed = 42;
  dirty.threads = 1;
  const Synthesis a = Synthesize(model, clean);
  const Synthesis b = Synthesize(model, dirty);
  dirty.threads = 3;
  const Synthesis c = Synthesize(model, dirty);
  const double s = DefaultSensitivity(ResponseKind::kForce);
  for (size_t k = 0; k < 4; ++k) {
    EXPECT_EQ(b.campaign.records[k].response, c.campaign.records[k].response) << "thread count changed the result";
    EXPECT_EQ(b.campaign.records[k].voltage_v, c.campaign.records[k].voltage_v);
    // The added signal in sensor volts: offset + hum + noise.
    const size_t count = a.campaign.records[k].size();
    const double hum_phase = b.truth["records"][k]["hum_phase_rad"].get<double>();
    double mean = 0, noise_square = 0, voltage_mean = 0, voltage_square = 0;
    for (size_t n = 0; n < count; ++n) {
      const double added = (b.campaign.records[k].response[n] - a.campaign.records[k].response[n]) * s;
      mean += added;
      const double hum = 0.01 * std::sin(2 * std::numbers::pi * 50 * static_cast<double>(n) / 8192 + hum_phase);
      noise_square += std::pow(added - 0.05 - hum, 2);
      const double voltage_added = b.campaign.records[k].voltage_v[n] - a.campaign.records[k].voltage_v[n];
      voltage_mean += voltage_added;
      voltage_square += std::pow(voltage_added - 2e-3, 2);
    }
    // 4096 samples: the rms estimate is within ~1.1 % (1 sigma), the mean within 3e-5 V (the
    // voltage's within 1.6e-6 V).
    EXPECT_NEAR(mean / count, 0.05, 2e-4);
    EXPECT_NEAR(voltage_mean / count, 2e-3, 1e-5);
    EXPECT_NEAR(std::sqrt(noise_square / count), 2e-3, 2e-3 * 0.06);
    EXPECT_NEAR(std::sqrt(voltage_square / count), 1e-4, 1e-4 * 0.06);
  }
  EXPECT_EQ(b.truth["voltage_offset_v"], 2e-3);
  EXPECT_FALSE(a.truth.contains("voltage_offset_v"));
  dirty.seed = 43;
  const Synthesis d = Synthesize(model, dirty);
  EXPECT_NE(d.campaign.records[0].response, b.campaign.records[0].response);
}

TEST(Synthesize, PerturbationsAreRelativeDrawsRecordedInTheTruth) {
  SynthOptions options = SmallSynth();
  options.frequencies_hz = {8};
  options.amplitudes_v = {0.1};
  options.perturb = {{"k_p", 0.03}, {"damping_n_s_per_m", 0.05}, {"sensitivity", 0.1}, {"k3", 0.5}};
  options.seed = 5;
  const ActuatorModel nominal = PaperModel();
  const Synthesis synthesis = Synthesize(nominal, options);
  const json& p = synthesis.truth["perturbations"];
  ASSERT_EQ(p.size(), 4u);
  EXPECT_EQ(p[0]["key"], "k_p");
  EXPECT_EQ(p[1]["key"], "c_p");
  EXPECT_NEAR(p[0]["factor"].get<double>(), 1.0, 0.03);
  EXPECT_NEAR(p[1]["factor"].get<double>(), 1.0, 0.05);
  EXPECT_NE(p[0]["factor"].get<double>(), 1.0);
  EXPECT_DOUBLE_EQ(synthesis.model.stiffness_n_per_m, nominal.stiffness_n_per_m * p[0]["factor"].get<double>());
  EXPECT_DOUBLE_EQ(synthesis.model.damping_n_s_per_m, nominal.damping_n_s_per_m * p[1]["factor"].get<double>());
  EXPECT_EQ(synthesis.model.cubic_stiffness_n_per_m3, 0.0);  // zero stays zero
  EXPECT_DOUBLE_EQ(synthesis.truth["sensitivity_true"].get<double>(), 0.02248 * p[2]["factor"].get<double>());
  EXPECT_EQ(synthesis.truth["model"]["stiffness_n_per_m"].get<double>(), synthesis.model.stiffness_n_per_m);
  EXPECT_EQ(synthesis.write.sensitivity, 0.02248);
}

TEST(Synthesize, RejectsBadOptionsNamingTheField) {
  const auto expect_refused = [](SynthOptions options, const std::string& field, const std::string& fragment) {
    try {
      Synthesize(PaperModel(), options);
      ADD_FAILURE() << "no error for " << field;
    } catch (const InputError& e) {
      EXPECT_EQ(e.field(), field) << e.what();
      EXPECT_THAT(e.bare_message(), HasSubstr(fragment));
    }
  };
  SynthOptions o = SmallSynth();
  o.frequencies_hz = {};
  expect_refused(o, "frequencies_hz", "at least one");
  o = SmallSynth();
  o.frequencies_hz = {8, 5000};
  expect_refused(o, "frequencies_hz", "Nyquist");
  o = SmallSynth();
  o.noise_rms_v = -1;
  expect_refused(o, "noise_rms_v", ">= 0");
  o = SmallSynth();
  o.perturb = {{"k9", 0.1}};
  expect_refused(o, "perturb", "'k9': unknown model parameter");
  o = SmallSynth();
  o.perturb = {{"k_p", 1.5}};
  expect_refused(o, "perturb", "must be in [0, 1)");
  o = SmallSynth();
  o.perturb = {{"k_p", 0.1}, {"stiffness_n_per_m", 0.1}};
  expect_refused(o, "perturb", "perturbed twice");
  o = SmallSynth();
  o.voltage_offset_v = INFINITY;
  expect_refused(o, "voltage_offset_v", "finite");
  o = SmallSynth();
  o.drive_frequency_error = -1;
  expect_refused(o, "drive_frequency_error", "in (-1, 1)");
  o = SmallSynth();
  o.frequencies_hz = {8, 4000};  // below the Nyquist frequency of 4096 Hz, but driven at 4400
  o.drive_frequency_error = 0.1;
  expect_refused(o, "drive_frequency_error", "drives 4000 Hz at 4400 Hz");
  o = SmallSynth();
  o.sensitivity_error = -1;
  expect_refused(o, "sensitivity_error", "> -1");
  o = SmallSynth();
  o.sensitivity_error = 0.1;
  o.perturb = {{"sensitivity", 0.1}};
  expect_refused(o, "sensitivity_error", "do not go together");
}

// ---- strokelab synth end to end ----------------------------------------------------------------

TEST(SynthCli, WritesACampaignThatReadsBackAndKeepsTheTruthApart) {
  const fs::path dir = TempDir("synth_cli");
  const std::string args = "synth --out " + dir.string() +
                           " --frequencies-hz 8,13 --amplitudes-v 0.2,0.5 --duration-s 0.5 --settle-s 0.75"
                           " --sample-rate-hz 8192 --noise-rms 1e-4 --voltage-noise-rms 1e-5 --offset-v 0.01"
                           " --hum-v 0.002 --perturb k_p=0.03,c_p=0.05 --seed 7 --response acceleration";
  const auto result = testing::RunCli(args);
  ASSERT_EQ(result.exit_code, 0) << result.stderr_text;
  EXPECT_THAT(result.stdout_text, HasSubstr("wrote 4 records"));
  const Campaign campaign = ReadCampaign(dir);
  EXPECT_EQ(campaign.response, ResponseKind::kAcceleration);
  ASSERT_EQ(campaign.records.size(), 4u);
  for (size_t k = 0; k < 4; ++k) {
    EXPECT_EQ(campaign.records[k].size(), 4096u);
    EXPECT_EQ(campaign.records[k].sample_rate_hz, 8192.0);
    EXPECT_EQ(campaign.records[k].nominal_frequency_hz, k % 2 == 0 ? 8.0 : 13.0);
    EXPECT_EQ(campaign.records[k].nominal_amplitude_v, k < 2 ? 0.2 : 0.5);
  }
  ASSERT_TRUE(fs::is_regular_file(dir / "truth.json"));
  const json truth = json::parse(ReadText(dir / "truth.json"));
  EXPECT_EQ(truth["seed"], 7);
  EXPECT_EQ(truth["method"], "exact");
  EXPECT_EQ(truth["perturbations"].size(), 2u);
  EXPECT_EQ(truth["offset_v"], 0.01);
  // The manifest knows nothing of the truth.
  const std::string manifest = ReadText(dir / "manifest.json");
  for (const char* secret : {"stiffness", "k_p", "seed", "noise", "perturb", "truth", "offset", "hum"})
    EXPECT_THAT(manifest, ::testing::Not(HasSubstr(secret))) << secret;

  // The same command again gives the same files (the seed fixes everything).
  const fs::path again = TempDir("synth_cli_again");
  std::string args_again = args;
  args_again.replace(args_again.find(dir.string()), dir.string().size(), again.string());
  ASSERT_EQ(testing::RunCli(args_again).exit_code, 0);
  EXPECT_EQ(ReadText(dir / "rec_003.csv"), ReadText(again / "rec_003.csv"));
  fs::remove_all(dir);
  fs::remove_all(again);
}

TEST(SynthCli, ChoosesCvodeForSmoothNonlinearModelsAndNamesBadFlags) {
  const fs::path dir = TempDir("synth_cvode");
  const fs::path truth = TempDir("synth_truth") / "elsewhere.json";
  const auto result = testing::RunCli("synth --out " + dir.string() + " --truth " + truth.string() +
                                      " --set k3=4e7 --frequencies-hz 9 --amplitudes-v 0.3 --duration-s 0.2"
                                      " --settle-s 0.3 --sample-rate-hz 4096");
  ASSERT_EQ(result.exit_code, 0) << result.stderr_text;
  EXPECT_FALSE(fs::exists(dir / "truth.json"));
  ASSERT_TRUE(fs::is_regular_file(truth));
  EXPECT_EQ(json::parse(ReadText(truth))["method"], "cvode");
  EXPECT_EQ(ReadCampaign(dir).records.at(0).size(), 819u);

  const auto expect_error = [](const std::string& args, const std::string& fragment) {
    const auto r = testing::RunCli(args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.stderr_text;
    EXPECT_THAT(r.stderr_text, HasSubstr(fragment)) << args;
  };
  expect_error("synth --frequencies-hz 8", "--out: is required");
  expect_error("synth --out " + dir.string() + " --response torque", "--response: unknown response channel 'torque'");
  expect_error("synth --out " + dir.string() + " --perturb k9=0.1", "--perturb: 'k9': unknown model parameter");
  expect_error("synth --out " + dir.string() + " --perturb k_p", "--perturb: expected KEY=RELATIVE");
  expect_error("synth --out " + dir.string() + " --frequencies-hz 8,x", "--frequencies-hz: expected a number, got 'x'");
  expect_error("synth --out " + dir.string() + " --noise-rms -1", "--noise-rms: must be a finite number >= 0");
  expect_error("synth --out " + dir.string() + " --seed -3", "--seed: expected a non-negative integer");
  expect_error("synth --out " + dir.string() + " --set k3=4e7 --method exact",
               "--method: the exact engine needs a piecewise-linear model");
  expect_error("synth --out " + dir.string() + " --method rk4", "--method: unknown method 'rk4' (known: auto, exact,");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace strokelab
