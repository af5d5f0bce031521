// The broadband diagnosis (diagnose/broadband_diagnose.h) on multisine campaigns with known truth
// (issue 14 item 2): the paper's model with k_p, c_p, g perturbed by up to 10 % (d by 5 %, k_s by
// 10 %), noise, offset and 50 Hz hum, three levels of random-phase odd multisines, plus one concealed
// effect. The effect must be named first and alone, its parameter within 25 % of the truth, and the
// held-out misfit beyond the true model's at least halved; the control gets nothing named and nothing
// unexplained. The effects' sizes and levels were chosen on seeds 8101-8110
// (broadband_diagnose_study.py); these seeds are used nowhere else.
//
// "Held-out misfit" is the held-out chi-square less the true model's on the same parts: the noise level
// each part's chi-square is scaled by is estimated from the part itself, with a spread (var 2.5 / n,
// broadband_fit.cc) that makes chi-square less its degrees of freedom a poor measure of the misfit
// left, while the difference between two models on the same parts is exact.
#include "strokelab/diagnose/broadband_diagnose.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "strokelab/base/errors.h"
#include "strokelab/data/synth.h"
#include "strokelab/identify/broadband_fit.h"
#include "strokelab/model/model.h"
#include "strokelab/model/model_json.h"
#include "progress_log.h"

namespace strokelab {
namespace {

struct BroadbandCase {
  std::string name;       // the effect's id, or "nothing_missing"
  std::string parameter;  // its parameter's key (model.h), empty for the control
  double value = 0.0;
  std::vector<double> levels_v_rms;
  uint64_t seed = 0;
};
void PrintTo(const BroadbandCase& c, std::ostream* out) { *out << c.name; }

const std::vector<double> kSmoothLevels = {0.1, 0.25, 0.5};  // clear of the stop

Synthesis MultisineCampaign(const BroadbandCase& c) {
  ActuatorModel truth = PaperModel();
  if (!c.parameter.empty()) truth.*(FindParameter(c.parameter).field) = c.value;
  // A transducer's coil carries the back-EMF's part of c_p: 0.8 of its 1.3 N s/m.
  if (c.name == "coil_inductance") truth.back_emf_damping_n_s_per_m = 0.8;
  SynthOptions options;
  options.excitation = Excitation::kMultisine;
  options.levels_v_rms = c.levels_v_rms;
  options.duration_s = 1.0;
  options.settle_s = 2.0;
  options.sample_rate_hz = 8192.0;
  options.noise_rms_v = 2e-4;
  options.offset_v = 5e-3;
  options.hum_v = 5e-4;
  options.perturb = {{"k_p", 0.1}, {"c_p", 0.1}, {"g", 0.1}, {"d", 0.05}, {"k_s", 0.1}};
  options.seed = c.seed;
  return Synthesize(truth, options);
}

// The held-out parts' chi-square at `model`, only their starts, offsets and hum fitted.
double HeldOutChi2(const Campaign& campaign, const ActuatorModel& model) {
  const BroadbandParts parts = SplitBroadbandRecords(campaign, DiagnoseOptions{}.heldout_every);
  std::vector<const Recording*> pointers;
  for (const Recording& r : parts.heldout) pointers.push_back(&r);
  internal::ExtendedProblem held;
  held.base = model;
  return internal::FitBroadband(pointers, campaign.response, held).fit.chi2;
}

class BroadbandDiagnoseTest : public ::testing::TestWithParam<BroadbandCase> {};

TEST_P(BroadbandDiagnoseTest, NamesTheConcealedEffect) {
  const BroadbandCase& c = GetParam();
  const Synthesis synthesis = MultisineCampaign(c);
  DiagnoseOptions options;
  options.map_frequency_points = options.map_amplitude_points = 0;
  testing::ProgressLog progress;
  options.progress = progress.Hook();
  const BroadbandDiagnosis d = DiagnoseBroadbandCampaign(synthesis.campaign, options);
  progress.ExpectConsistent(d.progress_stages);
  EXPECT_EQ(d.progress_stages, progress.reports.back().stage);  // no maps asked for
  std::string candidates;
  for (const CandidateFit& k : d.candidates)
    candidates += "\n  " + k.label + " held-out gain " + std::to_string(k.heldout_gain) + ": " + k.decision;
  SCOPED_TRACE(d.conclusion + candidates);
  if (c.parameter.empty()) {
    EXPECT_TRUE(d.missing_physics.empty());
    EXPECT_FALSE(d.unexplained) << d.unexplained->description;
    EXPECT_THAT(d.conclusion, ::testing::StartsWith("nothing missing"));
    EXPECT_EQ(ModelToJson(d.model), ModelToJson(d.base.result.fit.model));
    return;
  }
  ASSERT_EQ(d.missing_physics.size(), 1u);
  EXPECT_STREQ(Info(d.missing_physics.front()).id, c.name.c_str());
  ASSERT_GE(d.chosen, 0);
  const CandidateFit& chosen = d.candidates[d.chosen];
  const double truth = synthesis.model.*(FindParameter(c.parameter).field);
  bool found = false;
  for (const FitParameter& p : chosen.effect_parameters) {
    if (p.name != c.parameter) continue;
    found = true;
    std::printf("%s: %s = %.5g +- %.3g (truth %.5g, %.1f %%)\n", c.name.c_str(), p.name.c_str(), p.value,
                p.standard_error, truth, 100 * (p.value / truth - 1));
    EXPECT_NEAR(p.value, truth, 0.25 * std::abs(truth));
    if (c.name != "coil_inductance") continue;
    // Clear of the stop, c_emf (0.8 N s/m here) is held at 0, and tau_e's report says so. Its error takes
    // in c_emf's spread, so it covers the 1.7 % that holding c_emf moves tau_e (6.8 errors before 0.29.0).
    EXPECT_THAT(p.note, ::testing::HasSubstr("with c_emf held at 0 N s/m"));
    EXPECT_LE(std::abs(p.value - truth), 3.0 * p.standard_error);
  }
  if (c.name == "coil_inductance") {
    for (const FitParameter& p : chosen.parameters) {
      if (p.name == "k_p" || p.name == "c_p" || p.name == "g") {
        EXPECT_THAT(p.note, ::testing::HasSubstr("c_emf's spread")) << p.name;
      }
    }
  }
  EXPECT_TRUE(found) << "no parameter " << c.parameter << " in the chosen candidate";
  const double true_chi2 = HeldOutChi2(synthesis.campaign, synthesis.model);
  const double before = d.fit_before.heldout_chi2 - true_chi2, after = d.fit_after.heldout_chi2 - true_chi2;
  std::printf("%s: held-out chi-square beyond the true model's %.4g -> %.4g\n", c.name.c_str(), before, after);
  EXPECT_LE(after, 0.5 * before);
  EXPECT_EQ(BroadbandDiagnosisToJson(d)["model"], ModelToJson(chosen.model));
}

INSTANTIATE_TEST_SUITE_P(Library, BroadbandDiagnoseTest,
                         ::testing::Values(BroadbandCase{"nothing_missing", "", 0.0, kSmoothLevels, 8301},
                                           BroadbandCase{"cubic_stiffness", "k3", 1.5e7, kSmoothLevels, 8302},
                                           // L = 2 mH over R = 3 Ohm, named in the coil's round
                                           BroadbandCase{"coil_inductance", "tau_e", 2e-3 / 3.0, kSmoothLevels, 8303}),
                         [](const ::testing::TestParamInfo<BroadbandCase>& info) { return info.param.name; });

// A broadband record of n samples at 1 kHz: voltage u(i), response y(i).
template <typename U, typename Y>
Recording BroadbandRecord(const char* name, int n, U u, Y y) {
  Recording r;
  r.name = name;
  r.sample_rate_hz = 1000.0;
  r.broadband = true;
  for (int i = 0; i < n; ++i) r.voltage_v.push_back(u(i)), r.response.push_back(y(i));
  return r;
}

// A record too short to hold a part out is named; a campaign of stepped sines only is refused.
TEST(BroadbandDiagnoseTest, RefusesRecordsItCannotSplit) {
  Campaign campaign;
  campaign.records = {BroadbandRecord("short.csv", 600, [](int) { return 0.1; }, [](int) { return 0.0; })};
  try {
    SplitBroadbandRecords(campaign, 4);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "short.csv");
    EXPECT_THAT(e.what(), ::testing::HasSubstr("too short to hold out 1/4"));
  }
  campaign.records[0].broadband = false;
  EXPECT_THROW(DiagnoseBroadbandCampaign(campaign), InputError);
}

// The split keeps each record's samples, in order: the fit part then the held-out part.
TEST(BroadbandDiagnoseTest, SplitsEachRecordIntoItsFirstAndLastParts) {
  Campaign campaign;
  campaign.records = {BroadbandRecord("a.csv", 2000, [](int i) { return i; }, [](int i) { return -i; })};
  const BroadbandParts parts = SplitBroadbandRecords(campaign, 4);
  ASSERT_EQ(parts.fit.size(), 1u);
  EXPECT_EQ(parts.names[0], "a.csv");
  EXPECT_EQ(parts.fit[0].size(), 1500u);
  EXPECT_EQ(parts.heldout[0].size(), 500u);
  EXPECT_EQ(parts.heldout[0].voltage_v.front(), 1500.0);
  EXPECT_EQ(parts.heldout[0].response.back(), -1999.0);
  EXPECT_TRUE(parts.heldout[0].broadband);
}

// The held-out quarter is the end whose share of the record's impacts is nearer a quarter: the first
// where the impacts all fall in the last quarter (the fit parts then show the stop too), or where the
// first quarter holds some and the last none; the last with impacts in both ends alike, in the middle
// only, or none.
TEST(BroadbandDiagnoseTest, HoldsOutTheEndWhoseShareOfTheImpactsIsNearerItsShareOfTheSamples) {
  std::mt19937 random(5);
  std::normal_distribution<double> noise(0.0, 1.0);
  auto record = [&](std::vector<size_t> spikes) {
    Recording r = BroadbandRecord("r.csv", 2000, [](int) { return 0.0; }, [&](int) { return noise(random); });
    for (size_t n : spikes) r.response[n] += 500.0;
    return r;
  };
  Campaign campaign;
  campaign.records = {record({1700, 1900}), record({300, 1800}), record({}), record({100, 800, 1200}),
                      record({800, 1200})};
  const BroadbandParts parts = SplitBroadbandRecords(campaign, 4);
  EXPECT_EQ(parts.heldout_first, (std::vector<bool>{true, false, false, true, false}));
  EXPECT_EQ(parts.fit[0].response[1200 - 500], campaign.records[0].response[1200]);
  EXPECT_EQ(parts.heldout[0].response[0], campaign.records[0].response[0]);
}

// Where an unexplained misfit lives, against contacts: the model's (its displacement past a stop) and
// the impacts the record shows that the model does not make (a stop it lacks). A part of noise with two
// impacts (force spikes of 500 noise levels) whose residual is noise but for 40 noise levels at the two
// impacts; the model's motion stays clear of its stop: all the excess lies within 2 ms (17 samples at
// 8,192 Hz) of the impacts' marks (ImpactSamples: a spike's fourth differences stand out at 5 samples,
// each marked with 2 either side), 2 x (9 + 34) of the 2,000 samples. The share is 1 up to the noise's
// excess elsewhere (sd sqrt(2 x 1914) against 3,200: 0.02; 3 sd allowed). (The code before counted the
// model's contacts alone: no share at all.)
TEST(BroadbandDiagnoseTest, AnUnexplainedMisfitAtImpactsTheModelMissesIsPlacedThere) {
  std::mt19937 random(7);
  std::normal_distribution<double> noise(0.0, 1.0);
  Recording part = BroadbandRecord("r.csv", 2000, [](int) { return 0.0; }, [&](int) { return noise(random); });
  part.sample_rate_hz = 8192.0;
  internal::BroadbandRecordFit fit;
  fit.noise_rms = 1.0;
  for (size_t n = 0; n < part.size(); ++n) fit.residual.push_back(noise(random));
  for (const size_t impact : {600, 1400}) {
    part.response[impact] += 500.0;
    fit.residual[impact] += 40.0;
  }
  fit.x_m.assign(part.size(), 0.0);  // the paper model's stop is 1 mm below
  fit.v_m_per_s.assign(part.size(), 0.0);
  const auto [near_share, time_share] = internal::NearContactShares(part, ResponseKind::kForce, fit, PaperModel());
  EXPECT_NEAR(near_share, 1.0, 0.06);
  EXPECT_DOUBLE_EQ(time_share, 2 * (9 + 34) / 2000.0);
}

}  // namespace
}  // namespace strokelab
