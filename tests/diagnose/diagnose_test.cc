// The diagnosis on concealed-effect campaigns with known truth (issue: fit and diagnose, point 4).
//
// Each campaign is synthesised (clients/recordings synth.h) from the paper's model with its
// parameters perturbed by up to 10 %, sensor noise, a DC offset and 50 Hz hum, plus one effect of
// the library, on seeds used nowhere else (the effect sizes and thresholds were tuned on seeds
// 21-28). The effect is concealed: its share of the raw response (the same campaign synthesised
// without it, same seed: same noise, same perturbations) is checked to be below the noise in RMS
// away from the impacts (see EffectRms; over whole records, impacts moved in time dominate).
// The diagnosis must name it first, recover its parameter within 25 % and at least halve the
// held-out error. A control campaign (no effect) must get "nothing missing".
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <ostream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "concealed_effects.h"
#include "strokelab/diagnose/diagnose.h"
#include "strokelab/data/synth.h"
#include "strokelab/model/model_json.h"
#include "gen2_grids.h"
#include "progress_log.h"
#include "test_util.h"

namespace strokelab {
namespace {

using ::strokelab::testing::CampaignOptions;
using ::strokelab::testing::ConcealedEffectCases;
using ::strokelab::testing::EffectCase;
using ::strokelab::testing::WithEffect;

// RMS over the campaign of (response with the effect - response without it) [response units],
// over all samples (whole) and over those farther than kImpactWindowS from an impact in either
// campaign (smooth): an impact moved by a fraction of a millisecond differs by a whole spike there,
// which says nothing of whether the smooth response shows the effect. An impact: a sample above
// kImpactFactor times the record's median |response|.
constexpr double kImpactWindowS = 2e-3;
constexpr double kImpactFactor = 5.0;
struct EffectShare {
  double whole = 0.0, smooth = 0.0;
};
EffectShare EffectRms(const Campaign& with, const Campaign& without) {
  double whole = 0.0, smooth = 0.0;
  size_t n_whole = 0, n_smooth = 0;
  for (size_t r = 0; r < with.records.size(); ++r) {
    const std::vector<double>& a = with.records[r].response;
    const std::vector<double>& b = without.records[r].response;
    std::vector<double> magnitude(a.size());
    for (size_t i = 0; i < a.size(); ++i) magnitude[i] = std::abs(a[i]);
    std::nth_element(magnitude.begin(), magnitude.begin() + magnitude.size() / 2, magnitude.end());
    const double threshold = kImpactFactor * magnitude[magnitude.size() / 2];
    const auto half = static_cast<long>(kImpactWindowS * with.records[r].sample_rate_hz);
    std::vector<bool> near(a.size(), false);
    for (size_t i = 0; i < a.size(); ++i)
      if (std::abs(a[i]) > threshold || std::abs(b[i]) > threshold)
        for (long k = std::max(0L, static_cast<long>(i) - half); k <= static_cast<long>(i) + half && k < static_cast<long>(a.size()); ++k)
          near[k] = true;
    for (size_t i = 0; i < a.size(); ++i) {
      const double d = a[i] - b[i];
      whole += d * d, ++n_whole;
      if (!near[i]) smooth += d * d, ++n_smooth;
    }
  }
  return {std::sqrt(whole / static_cast<double>(n_whole)), std::sqrt(smooth / static_cast<double>(n_smooth))};
}

class DiagnoseTest : public ::testing::TestWithParam<EffectCase> {};

TEST_P(DiagnoseTest, NamesTheConcealedEffect) {
  const EffectCase& c = GetParam();
  const SynthOptions options = CampaignOptions(c.seed);
  const Synthesis synthesis = Synthesize(WithEffect(c), options);
  const Diagnosis d = DiagnoseCampaign(synthesis.campaign);
  std::string candidates;
  for (const CandidateFit& k : d.candidates) candidates += "\n  " + k.label + " held-out gain " + std::to_string(k.heldout_gain);
  SCOPED_TRACE(d.conclusion + candidates);

  if (c.parameter.empty() && !c.hertzian) {
    EXPECT_TRUE(d.missing_physics.empty());
    EXPECT_EQ(d.chosen, -1);
    // The diagnosed model is the base fit's.
    EXPECT_EQ(ModelToJson(d.model), ModelToJson(d.base.model));
    EXPECT_THAT(d.model_note, ::testing::HasSubstr("nothing named"));
    // What the base model leaves is noise.
    EXPECT_FALSE(d.unexplained) << d.unexplained->description;
    EXPECT_THAT(d.conclusion, ::testing::StartsWith("nothing missing"));
    EXPECT_FALSE(d.coil_round);  // nothing unexplained: the coil's slow fits are not tried
    return;
  }
  // Concealed: the effect's share of the raw response is below the noise (sensor volts over the
  // written sensitivity: the noise in response units).
  const Synthesis without = Synthesize(WithEffect({c.name, "", 0.0, false, c.seed}), options);
  const double noise = options.noise_rms_v / synthesis.write.sensitivity;
  const EffectShare effect = EffectRms(synthesis.campaign, without.campaign);
  std::printf("%s: effect RMS %.4g away from impacts, %.4g over whole records; noise RMS %.4g\n", c.name.c_str(),
              effect.smooth, effect.whole, noise);
  EXPECT_LT(effect.smooth, noise) << "the effect is not concealed in the smooth response";

  ASSERT_FALSE(d.missing_physics.empty());
  EXPECT_STREQ(Info(d.missing_physics.front()).id, c.name.c_str());
  // One effect, no spurious second. What the open-world test says beside it is printed, not
  // required empty: a held-out record near a grazing bifurcation (second_stop's record 24) can miss by
  // more than the linear prediction error allows although the named physics is complete.
  EXPECT_EQ(d.missing_physics.size(), 1u);
  if (d.unexplained) std::printf("%s: also unexplained: %s\n", c.name.c_str(), d.unexplained->description.c_str());
  ASSERT_GE(d.chosen, 0);
  const CandidateFit& chosen = d.candidates[d.chosen];
  const std::string key = c.parameter;  // the case's own, one of the effect's parameters
  bool found = false;
  for (const FitParameter& p : chosen.effect_parameters) {
    if (p.name != key) continue;
    found = true;
    const double truth = c.hertzian ? c.value : synthesis.model.*(FindParameter(c.parameter).field);
    std::printf("%s: %s = %.5g +- %.3g (truth %.5g, %.1f %%); held-out nrmse %.4g -> %.4g\n", c.name.c_str(),
                key.c_str(), p.value, p.standard_error, truth, 100 * (p.value / truth - 1), d.fit_before.heldout_nrmse,
                d.fit_after.heldout_nrmse);
    EXPECT_NEAR(p.value, truth, 0.25 * std::abs(truth));
  }
  EXPECT_TRUE(found) << "no parameter " << key << " in the chosen candidate";
  // The diagnosed model is the chosen candidate's, all its parameters as fitted together, and the
  // JSON result carries it in the format of model files.
  EXPECT_EQ(ModelToJson(d.model), ModelToJson(chosen.model));
  EXPECT_EQ(DiagnosisToJson(d)["model"], ModelToJson(chosen.model));
  // second_stop: held-out record 24 (11 Hz, 0.5 V) is, in the truth, a period-2 orbit just past
  // grazing the upper stop, coexisting with a stable two-contact period-1 orbit; it is matched only
  // because the branch choice follows the settled motion (SettledAttractor), not Newton's period 1.
  EXPECT_LE(d.fit_after.heldout_nrmse, 0.5 * d.fit_before.heldout_nrmse);
}

INSTANTIATE_TEST_SUITE_P(Library, DiagnoseTest, ::testing::ValuesIn(ConcealedEffectCases()),
                         [](const ::testing::TestParamInfo<EffectCase>& info) { return info.param.name; });

// A second stop behind a hard first one, seen through an accelerometer at 44.1 kHz (1.5 s records,
// 60 Hz hum; the actuator gen2 drew for seed 9708). The paper model's base fit ends with k_s on its
// bound, a thirtieth of what the contact times say, and the second stop's fit from there stayed below
// the stop: nothing was named and the misfit was "unexplained" at 1.2e3 times the noise. From the
// staged estimates the second stop is found.
TEST(DiagnoseStartsTest, ASecondStopIsFoundBehindABaseFitOnItsBound) {
  SynthOptions o = testing::Gen2Accelerometer44kHz();
  o.hum_v = 0.001;
  o.hum_hz = 60.0;
  o.seed = 21;
  ActuatorModel truth = PaperModel();
  truth.stiffness_n_per_m = 116.72;
  truth.damping_n_s_per_m = 1.2786;
  truth.gain_n_per_v = 0.31725;
  truth.lower_stop_m = -0.99455e-3;
  truth.contact_stiffness = 1.2547e6;
  truth.upper_stop_m = 1.45e-3;
  const Diagnosis d = DiagnoseCampaign(Synthesize(truth, o).campaign);
  SCOPED_TRACE(d.conclusion);
  EXPECT_TRUE(d.base.refinement.ended_on_bound);  // the case this test is for
  EXPECT_EQ(d.selection_rounds, 2);
  EXPECT_EQ(DiagnosisToJson(d)["selection_rounds"], 2);
  ASSERT_EQ(d.missing_physics, std::vector<Effect>{Effect::kSecondStop});
  EXPECT_NEAR(d.model.upper_stop_m, truth.upper_stop_m, 0.01 * truth.upper_stop_m);
  EXPECT_FALSE(d.unexplained);
}

// A correct model seen through gen2's accelerometer at 44.1 kHz, where every drive period is a whole
// number of samples (SamplingCorrection.ImpactsOnAWholeNumberGridDoNotBiasTheFit). The selection's base
// fit, with the sampling correction frozen, left 1.26 times the noise on the held-out records of this
// seed (of 1-8, the one 0.23.0 flagged), and the control was called unexplained. The open-world test
// judges the base model refitted with the correction's slopes, as `fit` does.
TEST(DiagnoseStartsTest, ACorrectModelOnAWholeNumberGridIsNotUnexplained) {
  SynthOptions o = testing::Gen2Accelerometer44kHz();
  o.sensitivity = 0.0102;
  o.seed = 3;
  const Diagnosis d = DiagnoseCampaign(Synthesize(testing::Gen2Control9706(), o).campaign);
  SCOPED_TRACE(d.conclusion);
  EXPECT_TRUE(d.missing_physics.empty());
  EXPECT_FALSE(d.unexplained);
}

// Two effects at once, each of which alone does worse than the base model on the held-out records: a
// Hertzian stop and quadratic damping (the actuator gen2 drew for seed 9903, unperturbed here). Their
// single fits gained 312 and 266 on the fit records and lost 315 and 69 on the held-out ones, so
// forward selection from the best held-out single (force_factor) never fitted the pair, and 0.24.0
// named nothing: "unexplained" at 1.49-1.81 times the noise on synth seeds 1-4. The selection's
// look-ahead, from the single with the largest fit-records gain, names both (selection.h).
TEST(DiagnoseStartsTest, TwoEffectsThatEachLoseAloneAreNamedTogether) {
  SynthOptions o = testing::CampaignOptions(1);
  o.perturb.clear();
  ActuatorModel truth = PaperModel();
  truth.stiffness_n_per_m = 124.4068;
  truth.damping_n_s_per_m = 1.380757;
  truth.gain_n_per_v = 0.2826448;
  truth.lower_stop_m = -0.9997e-3;
  truth.contact_law = ContactLaw::kHertzian;
  truth.contact_stiffness = 1.60045e7;
  truth.quadratic_damping_n_s2_per_m2 = 0.3;
  const Diagnosis d = DiagnoseCampaign(Synthesize(truth, o).campaign);
  SCOPED_TRACE(d.conclusion);
  EXPECT_THAT(d.missing_physics,
              ::testing::UnorderedElementsAre(Effect::kHertzianContact, Effect::kQuadraticDamping));
  EXPECT_NEAR(d.model.contact_stiffness, truth.contact_stiffness, 0.1 * truth.contact_stiffness);
  EXPECT_NEAR(d.model.quadratic_damping_n_s2_per_m2, 0.3, 0.1 * 0.3);
  EXPECT_FALSE(d.unexplained);
}

// The coil's inductance is not a candidate at first (its fits are slow, diagnose.h); where the other
// effects leave the misfit unexplained, the selection runs again with it. The concealed coil of the
// z-score study (L = 2 mH over R = 3 Ohm) on a new seed, in a campaign of 12 records of 0.5 s (the
// other tests' 24 of 1 s would take a minute with the coil's fits).
TEST(DiagnoseStartsTest, TheCoilIsTriedWhereTheOtherEffectsLeaveTheMisfitUnexplained) {
  const EffectCase coil = testing::StudyOnlyEffectCases().front();
  SynthOptions o = testing::CampaignOptions(1201);
  o.frequencies_hz = {5, 7, 9, 11};
  o.amplitudes_v = {0.1, 0.3, 0.5};
  o.duration_s = 0.5;
  DiagnoseOptions options;
  testing::ProgressLog progress;
  options.progress = progress.Hook();
  const Diagnosis d = DiagnoseCampaign(Synthesize(WithEffect(coil), o).campaign, options);
  SCOPED_TRACE(d.conclusion);
  EXPECT_TRUE(d.coil_round);  // so the first round left the misfit unexplained
  // One stage per fit in either round: the first three, then at least the coil round's own fits.
  progress.ExpectConsistent(d.progress_stages);
  EXPECT_GE(progress.DistinctStages(), 3 + d.candidates.size());
  EXPECT_EQ(d.progress_stages, progress.reports.back().stage + 2);  // the maps follow
  EXPECT_EQ(DiagnosisToJson(d)["coil_round"], true);
  EXPECT_THAT(d.missing_physics, ::testing::ElementsAre(Effect::kCoilInductance));
  EXPECT_NEAR(d.model.coil_time_constant_s, coil.value, 0.1 * coil.value);
  EXPECT_FALSE(d.unexplained);
}

// Clear of the stop the response is linear, and its transfer function cannot separate the coil's c_emf
// from g, k_p, c_p and tau_e: c_emf is held at 0, which moves the four together by about c_emf tau_e / m_p
// (1.7 % here: k_p, c_p and g 6-12 of their own errors). Their errors take in c_emf's spread over [0, c_p],
// so they cover the truth (effects.cc, ChargeHeldBackEmf). The study's coil at drives clear of the stop.
TEST(DiagnoseStartsTest, ACoilClearOfTheStopHoldsCEmfAndItsErrorsCoverWhatThatMoves) {
  const EffectCase coil = testing::StudyOnlyEffectCases().front();
  SynthOptions o = testing::CampaignOptions(1202);
  o.frequencies_hz = {6, 7, 8, 9, 11, 13};
  o.amplitudes_v = {0.05, 0.1, 0.15};
  o.sample_rate_hz = 8192;
  o.noise_rms_v = 0.0002;
  o.perturb = {{"k_p", 0.1}, {"c_p", 0.1}, {"g", 0.1}};  // d and k_s stay: the stop is not reached
  const Synthesis synthesis = Synthesize(WithEffect(coil), o);
  const Diagnosis d = DiagnoseCampaign(synthesis.campaign);
  SCOPED_TRACE(d.conclusion);
  ASSERT_THAT(d.missing_physics, ::testing::ElementsAre(Effect::kCoilInductance));
  const CandidateFit& chosen = d.candidates[d.chosen];
  EXPECT_EQ(chosen.model.back_emf_damping_n_s_per_m, 0.0);
  const ActuatorModel& truth = synthesis.model;
  const std::pair<const char*, double> truths[] = {{"tau_e", truth.coil_time_constant_s},
                                                   {"k_p", truth.stiffness_n_per_m},
                                                   {"c_p", truth.damping_n_s_per_m},
                                                   {"g", truth.gain_n_per_v}};
  for (const auto& [name, value] : truths) {
    const auto p = std::ranges::find(chosen.parameters, std::string(name), &FitParameter::name);
    ASSERT_NE(p, chosen.parameters.end()) << name;
    EXPECT_THAT(p->note, ::testing::HasSubstr("c_emf's spread")) << name;
    EXPECT_LE(std::abs(p->value - value), 3.0 * p->standard_error) << name << " = " << p->value << " +- "
                                                                    << p->standard_error << ", truth " << value;
  }
}

// Below the stop the base fit cannot identify d and k_s (fit.h, RefinementSummary::unidentified). Some
// records still count as not clear of the stop (their distortion passes the limit), so the campaign "has
// contacts"; every candidate freed d and k_s with it and ended NOT converged, d not identifiable (all nine
// on a campaign of this shape, seed 1109). A stop the base fit could not identify is held, and the
// effects that act only at it are not tried (the broadband diagnosis does the same).
TEST(DiagnoseStartsTest, AStopTheBaseFitCannotIdentifyIsHeldByEveryCandidate) {
  SynthOptions o = CampaignOptions(1110);
  o.amplitudes_v = {0.05, 0.1, 0.15};
  const Diagnosis d = DiagnoseCampaign(Synthesize(PaperModel(), o).campaign);
  SCOPED_TRACE(d.conclusion);
  ASSERT_EQ(d.base.refinement.unidentified, (std::vector<std::string>{"d", "k_s"})) << d.base.refinement.report;
  for (const CandidateFit& c : d.candidates) {
    // (A second stop fits k_s, which both stops share, from its own impacts: effects.cc BuildProblem.)
    const bool second_stop = std::ranges::count(c.effects, Effect::kSecondStop) > 0;
    for (const FitParameter& p : c.parameters)
      EXPECT_TRUE(p.name != "d" && (second_stop || p.name != "k_s")) << c.label << ": " << p.name;
    for (Effect e : c.effects)
      EXPECT_TRUE(e != Effect::kHertzianContact && e != Effect::kContactDamping) << c.label;
  }
  EXPECT_TRUE(d.missing_physics.empty());
  EXPECT_FALSE(d.unexplained);
}

// The base fit's fields come first, under FitOptions' names; then the diagnosis's own.
TEST(DiagnoseOptionsTest, IsValidNamesTheFieldAndWhatIsWrong) {
  using ::strokelab::testing::IsValidText;
  DiagnoseOptions options;
  EXPECT_EQ(IsValidText(options), "");
  options.fit.max_iterations = 0;
  options.heldout_every = 1;
  EXPECT_EQ(IsValidText(options), "max_iterations: must be >= 1, got 0");
  options.fit = FitOptions{};
  EXPECT_EQ(IsValidText(options), "heldout_every: must be >= 2, got 1");
  options = DiagnoseOptions{};
  options.max_seconds = 0;
  EXPECT_EQ(IsValidText(options), "max_seconds: must be > 0");
  options = DiagnoseOptions{};
  options.map_frequency_points = 1;
  EXPECT_EQ(IsValidText(options), "map_frequency_points: must be 0 (no maps) or 2 .. 400, got 1");
  options.map_frequency_points = 0;  // no maps
  EXPECT_EQ(IsValidText(options), "");
  options.map_amplitude_points = 401;
  EXPECT_EQ(IsValidText(options), "map_amplitude_points: must be 0 (no maps) or 2 .. 400, got 401");
}

TEST(DiagnoseOptionsTest, FieldTableNamesEachOptionAsIsValidDoes) {
  EXPECT_EQ(::strokelab::testing::OptionNames(DiagnoseOptionFields()),
            "heldout_every heldout_every --heldout-every; min_heldout_gain min_heldout_gain --min-gain; "
            "max_seconds max_seconds --max-seconds; pairs pairs --no-pairs (clears); "
            "coil_inductance coil_inductance --coil-inductance; "
            "coil_when_unexplained coil_when_unexplained --no-coil-when-unexplained (clears); max_passes max_passes -; "
            "map_frequency_points map_frequency_points --map-frequency-points; "
            "map_amplitude_points map_amplitude_points --map-amplitude-points");
  ::strokelab::testing::ExpectTableFieldsAreIsValidFields<DiagnoseOptions>(DiagnoseOptionFields());
}

// Records of a grid of drive amplitudes [V] (outer) and frequencies [Hz] (inner), in that order.
std::vector<RecordAnalysis> Grid(const std::vector<double>& amplitudes_v, const std::vector<double>& frequencies_hz) {
  std::vector<RecordAnalysis> records;
  for (double a : amplitudes_v) {
    for (double f : frequencies_hz) {
      RecordAnalysis r;
      r.nominal_amplitude_v = a;
      r.nominal_frequency_hz = f;
      records.push_back(r);
    }
  }
  return records;
}

// The (amplitude, frequency) pairs of the held-out records.
std::vector<std::pair<double, double>> HeldOutPairs(const std::vector<RecordAnalysis>& records, int n) {
  const std::vector<bool> heldout = HeldOutRecords(records, n);
  std::vector<std::pair<double, double>> pairs;
  for (size_t i = 0; i < records.size(); ++i) {
    if (heldout[i]) pairs.emplace_back(records[i].nominal_amplitude_v, records[i].nominal_frequency_hz);
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

// A campaign listed amplitude by amplitude is split as it always was (every n-th in its order); the same
// records listed frequency by frequency, or shuffled, are split alike. Held out in campaign order, the
// frequency-major listing would lose every 0.5 V record, the ones that reach the stop, to the held-out set.
TEST(HeldOutRecordsTest, TheSplitDoesNotDependOnTheCampaignsOrder) {
  const std::vector<double> amplitudes_v = {0.1, 0.3, 0.4, 0.5}, frequencies_hz = {5, 6, 7, 8, 9, 11};
  const std::vector<RecordAnalysis> amplitude_major = Grid(amplitudes_v, frequencies_hz);
  const std::vector<bool> heldout = HeldOutRecords(amplitude_major, 4);
  for (size_t i = 0; i < heldout.size(); ++i) EXPECT_EQ(heldout[i], i % 4 == 3) << i;
  const auto expected = HeldOutPairs(amplitude_major, 4);
  ASSERT_EQ(expected.size(), 6u);
  std::vector<RecordAnalysis> frequency_major;
  for (double f : frequencies_hz) {
    for (double a : amplitudes_v) frequency_major.push_back(Grid({a}, {f})[0]);
  }
  EXPECT_EQ(HeldOutPairs(frequency_major, 4), expected);
  std::vector<RecordAnalysis> shuffled = amplitude_major;
  std::reverse(shuffled.begin(), shuffled.end());
  std::rotate(shuffled.begin(), shuffled.begin() + 7, shuffled.end());
  EXPECT_EQ(HeldOutPairs(shuffled, 4), expected);
  for (double a : amplitudes_v) {  // every level keeps records on both sides
    const auto held = std::count_if(expected.begin(), expected.end(), [&](const auto& p) { return p.first == a; });
    EXPECT_GE(held, 1) << a;
    EXPECT_LT(held, 6) << a;
  }
}

// Four frequencies per level with n = 4: counted straight on, the same frequency would be held out at
// every level; the extra count moves it, so each level holds out a different one.
TEST(HeldOutRecordsTest, ALevelOfAMultipleOfNRecordsMovesTheHeldOutFrequency) {
  const auto pairs = HeldOutPairs(Grid({0.1, 0.2, 0.3, 0.4}, {6, 7, 8, 9}), 4);
  const std::vector<std::pair<double, double>> expected = {{0.1, 9}, {0.2, 8}, {0.3, 7}, {0.4, 6}};
  EXPECT_EQ(pairs, expected);
  EXPECT_THAT(HeldOutRecords(Grid({0.1, 0.2}, {6, 7, 8, 9}), 0), ::testing::Each(false));
}

// Measured drive amplitudes scatter around their level: within 1 % they are one level, ordered by
// frequency, not by the scatter.
TEST(HeldOutRecordsTest, AmplitudesWithinOnePercentAreOneLevel) {
  std::vector<RecordAnalysis> records = Grid({0.2}, {6, 7, 8, 9, 11, 13});
  const std::vector<double> scatter = {1.004, 0.996, 1.002, 0.998, 1.001, 0.999};
  for (size_t i = 0; i < records.size(); ++i) records[i].nominal_amplitude_v *= scatter[i];
  const std::vector<bool> heldout = HeldOutRecords(records, 3);
  EXPECT_THAT(heldout, ::testing::ElementsAre(false, false, true, false, false, true));
}

}  // namespace
}  // namespace strokelab
