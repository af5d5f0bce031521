// The diagnosis's choice among candidates (diagnose/selection.h) on scripted fits: the backward check
// refits the current model from the larger one's solution, and a second effect that only takes up what
// the first one's fit from the base left is not named; an effect that only stood in for others is
// swapped out or dropped.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "strokelab/diagnose/selection.h"

namespace strokelab {
namespace {

using internal::SelectEffects;
using internal::WithoutEffect;

// An effect parameter as a fit reports it (its unit and note play no part in the selection).
FitParameter Estimate(const std::string& name, double value, double standard_error) {
  FitParameter p;
  p.name = name;
  p.value = value;
  p.standard_error = standard_error;
  return p;
}

TEST(WithoutEffectTest, PutsBackOnlyTheEffectsOwnParameters) {
  const ActuatorModel base = PaperModel();
  ActuatorModel with = base;
  with.stiffness_n_per_m *= 1.1;  // a base parameter the extended fit moved: kept
  with.cubic_stiffness_n_per_m3 = 1.5e7;
  with.contact_law = ContactLaw::kHertzian;
  with.contact_stiffness = 4e8;
  with.friction_force_n = 0.003;
  with.force_factor_b1_per_m = 30;
  with.force_factor_b2_per_m2 = -6e4;
  with.amplifier_limit_v = 1.0;
  with.upper_stop_m = 1.2e-3;

  const ActuatorModel no_k3 = WithoutEffect(with, Effect::kCubicStiffness, base);
  EXPECT_EQ(no_k3.cubic_stiffness_n_per_m3, 0.0);
  EXPECT_EQ(no_k3.friction_force_n, 0.003);
  EXPECT_EQ(no_k3.stiffness_n_per_m, with.stiffness_n_per_m);

  const ActuatorModel no_hertz = WithoutEffect(with, Effect::kHertzianContact, base);
  EXPECT_EQ(no_hertz.contact_law, ContactLaw::kLinear);
  EXPECT_EQ(no_hertz.contact_stiffness, base.contact_stiffness);  // a linear stop's [N/m] again
  EXPECT_EQ(no_hertz.cubic_stiffness_n_per_m3, 1.5e7);

  const ActuatorModel no_bl = WithoutEffect(with, Effect::kForceFactor, base);
  EXPECT_EQ(no_bl.force_factor_b1_per_m, 0.0);
  EXPECT_EQ(no_bl.force_factor_b2_per_m2, 0.0);
  EXPECT_FALSE(WithoutEffect(with, Effect::kAmplifierSaturation, base).HasAmplifierLimit());
  EXPECT_FALSE(WithoutEffect(with, Effect::kSecondStop, base).HasUpperStop());
  EXPECT_EQ(WithoutEffect(with, Effect::kDryFriction, base).friction_force_n, 0.0);
}

// Scripted candidate fits: chi-square on the fit and held-out records (residual variance 1, kDof
// degrees of freedom; with `broadband`, none, and the fit's own test's verdict) by the candidate's
// label and the label it starts from ("" the base), with significant parameters (1 +- 0.1) but those
// of the effect `insignificant` names (0.05 +- 0.1) and of the one `unidentified` names (1 without a
// standard error).
class ScriptedFits {
 public:
  std::map<std::string, double> chi2;     // "effects<-from" -> chi-square (fit and held-out alike)
  std::map<std::string, double> heldout;  // "effects<-from" -> held-out chi-square, where it differs
  std::map<std::string, Effect> insignificant;  // "effects<-from" -> the effect within noise of zero
  std::map<std::string, Effect> unidentified;   // "effects<-from" -> the effect not identifiable
  std::vector<std::pair<std::string, ActuatorModel>> starts;  // every fit's label and start model
  std::vector<internal::SelectionStep> steps;                 // and its place in the progress's plan
  bool broadband = false;  // figures as the broadband diagnosis's: beyond noise past kBroadbandChi2Limit

  void SetNoiseTest(FitFigures* f) const {
    f->dof = broadband ? 0 : kDof;
    f->beyond_noise = broadband ? f->chi2 > kBroadbandChi2Limit : internal::BeyondNoise(f->chi2, kDof);
  }

  internal::CandidateFitter Fitter() {
    return [this](const std::vector<Effect>& effects, const ActuatorModel& start, const std::vector<Effect>& from,
                  const internal::SelectionStep& step, const std::string&) {
      steps.push_back(step);
      CandidateFit c;
      c.effects = effects;
      c.label = internal::Label(effects);
      const std::string key = c.label + "<-" + internal::Label(from);
      starts.emplace_back(key, start);
      c.fitted = chi2.count(key) > 0;
      if (!c.fitted) return c;
      c.figures.chi2 = c.figures.heldout_chi2 = chi2.at(key);
      if (heldout.count(key) > 0) c.figures.heldout_chi2 = heldout.at(key);
      c.figures.residual_variance = 1.0;
      SetNoiseTest(&c.figures);
      c.fit_gain = kBase - c.figures.chi2;
      c.heldout_gain = kBase - c.figures.heldout_chi2;
      for (Effect e : effects) {
        const bool weak = insignificant.count(key) > 0 && insignificant.at(key) == e;
        const double error = unidentified.count(key) > 0 && unidentified.at(key) == e ? std::nan("") : 0.1;
        for (const char* name : Info(e).parameters)
          c.effect_parameters.push_back(Estimate(name, weak ? 0.05 : 1.0, error));
      }
      c.model = start;
      if (std::find(effects.begin(), effects.end(), Effect::kCubicStiffness) != effects.end())
        c.model.cubic_stiffness_n_per_m3 = 1.5e7;
      if (std::find(effects.begin(), effects.end(), Effect::kDryFriction) != effects.end())
        c.model.friction_force_n = 0.003;
      return c;
    };
  }
  static constexpr double kBase = 1000.0;
  static constexpr size_t kDof = 100;  // chi-square(100)'s 0.999 point is 149
  static constexpr double kBroadbandChi2Limit = 149.0;
};

int Select(ScriptedFits& fits, std::vector<CandidateFit>* candidates,
           std::vector<Effect> singles = {Effect::kCubicStiffness, Effect::kDryFriction}) {
  FitFigures base;
  base.chi2 = base.heldout_chi2 = ScriptedFits::kBase;
  base.residual_variance = 1.0;
  fits.SetNoiseTest(&base);
  return SelectEffects(singles, base, PaperModel(), DiagnoseOptions{}, [] { return 1e9; }, fits.Fitter(), candidates);
}

TEST(SelectEffectsTest, ASecondEffectThatTakesUpWhatTheFirstFitLeftIsNotNamed) {
  ScriptedFits fits;
  fits.chi2 = {{"cubic_stiffness<-", 500},  // short of its optimum
               {"dry_friction<-", 900},
               {"cubic_stiffness+dry_friction<-cubic_stiffness", 400},  // beats it by 100 > 10
               {"cubic_stiffness<-cubic_stiffness+dry_friction", 405}};  // within 5 of the pair
  std::vector<CandidateFit> candidates;
  const int chosen = Select(fits, &candidates);
  ASSERT_GE(chosen, 0);
  EXPECT_EQ(candidates[chosen].label, "cubic_stiffness");
  EXPECT_EQ(candidates[chosen].figures.chi2, 405);  // the refit, not the fit from the base
  bool pair_rejected = false;
  for (const CandidateFit& c : candidates)
    if (c.label == "cubic_stiffness+dry_friction")
      pair_rejected = c.decision.find("backward check: without dry_friction") != std::string::npos;
  EXPECT_TRUE(pair_rejected);
  // The refit started from the pair's solution with the friction taken out.
  bool refit_seen = false;
  for (const auto& [key, start] : fits.starts)
    if (key == "cubic_stiffness<-cubic_stiffness+dry_friction") {
      refit_seen = true;
      EXPECT_EQ(start.cubic_stiffness_n_per_m3, 1.5e7);
      EXPECT_EQ(start.friction_force_n, 0.0);
    }
  EXPECT_TRUE(refit_seen);
}

// An effect whose null is a limit at infinity stands on its gains alone, unless none of its parameters
// is identifiable: a second stop the motion never reaches changes nothing the records show, and what
// its fit gained the refit of the other parameters did (broadband study 8410).
// The progress's plan: one stage per fit, and at each forward move every fit of that move still planned,
// so that the time left is not read as nothing while the selection fits on (broadband coil 8435 said
// "0.0 s left" for 200 s when the whole forward selection was one stage).
TEST(SelectEffectsTest, EachFitIsAStageAndTheMovesFitsArePlannedAhead) {
  ScriptedFits fits;
  fits.chi2 = {{"cubic_stiffness<-", 500},
               {"dry_friction<-", 900},
               {"quadratic_stiffness<-", 950},
               {"cubic_stiffness+dry_friction<-cubic_stiffness", 120},         // move 1, within noise
               {"cubic_stiffness+quadratic_stiffness<-cubic_stiffness", 495},  // within noise of k3
               {"cubic_stiffness<-cubic_stiffness+dry_friction", 500}};        // its backward check
  std::vector<CandidateFit> candidates;
  const int chosen =
      Select(fits, &candidates, {Effect::kCubicStiffness, Effect::kDryFriction, Effect::kQuadraticStiffness});
  ASSERT_GE(chosen, 0);
  EXPECT_EQ(candidates[chosen].label, "cubic_stiffness+dry_friction");
  // The fits: the singles 0-2; move 1's two extensions and one refit 3-5; move 2's extension 6 (not fitted).
  ASSERT_EQ(fits.steps.size(), 7u);
  const int move_ends[] = {3, 3, 3, 6, 6, 6, 7};  // one past the last fit of each fit's move
  for (size_t i = 0; i < fits.steps.size(); ++i) {
    EXPECT_EQ(fits.steps[i].index, static_cast<int>(i));
    EXPECT_GE(fits.steps[i].planned, move_ends[i]) << "fit " << i;
  }
  // Before any move, the plan is the singles and one move over the others.
  EXPECT_EQ(fits.steps[0].planned, 5);
  EXPECT_EQ(internal::SelectionFitsPlanned(3, DiagnoseOptions{}), 5);
}

TEST(SelectEffectsTest, AnEffectWithoutAnIdentifiableParameterIsNotNamed) {
  ScriptedFits fits;
  fits.chi2 = {{"second_stop<-", 300}, {"cubic_stiffness<-", 500}};
  fits.unidentified = {{"second_stop<-", Effect::kSecondStop}};
  std::vector<CandidateFit> candidates;
  const int chosen = Select(fits, &candidates, {Effect::kSecondStop, Effect::kCubicStiffness});
  ASSERT_GE(chosen, 0);
  EXPECT_EQ(candidates[chosen].label, "cubic_stiffness");
  const auto second_stop = std::find_if(candidates.begin(), candidates.end(),
                                        [](const CandidateFit& c) { return c.label == "second_stop"; });
  ASSERT_NE(second_stop, candidates.end());
  EXPECT_EQ(second_stop->decision,
            "d_upper = 1 not identifiable from these records (the gain is the other parameters' refit)");
  fits.unidentified.clear();  // reached: its gains decide
  candidates.clear();
  const int reached = Select(fits, &candidates, {Effect::kSecondStop, Effect::kCubicStiffness});
  ASSERT_GE(reached, 0);
  EXPECT_EQ(candidates[reached].label, "second_stop");
}

TEST(SelectEffectsTest, APairThatAlsoBeatsTheRefitBeyondNoiseIsNamed) {
  ScriptedFits fits;
  fits.chi2 = {{"cubic_stiffness<-", 500},
               {"dry_friction<-", 900},
               {"cubic_stiffness+dry_friction<-cubic_stiffness", 400},
               {"cubic_stiffness<-cubic_stiffness+dry_friction", 480}};  // the pair still beats it by 80
  std::vector<CandidateFit> candidates;
  const int chosen = Select(fits, &candidates);
  ASSERT_GE(chosen, 0);
  EXPECT_EQ(candidates[chosen].label, "cubic_stiffness+dry_friction");
  EXPECT_EQ(candidates[chosen].decision, "");
}

TEST(SelectEffectsTest, ARefitThatEndsWorseLeavesTheFitFromTheBase) {
  ScriptedFits fits;
  fits.chi2 = {{"cubic_stiffness<-", 500},
               {"dry_friction<-", 900},
               {"cubic_stiffness+dry_friction<-cubic_stiffness", 495},  // gain 5: not beyond noise
               {"cubic_stiffness<-cubic_stiffness+dry_friction", 600}};
  std::vector<CandidateFit> candidates;
  const int chosen = Select(fits, &candidates);
  ASSERT_GE(chosen, 0);
  EXPECT_EQ(candidates[chosen].label, "cubic_stiffness");
  EXPECT_EQ(candidates[chosen].figures.chi2, 500);
}

// Two effects present at once, where each one's single fit does worse than the base on the held-out
// records (it bends the shared parameters towards the other's misfit), and a third effect's single
// fit gains a little on them: forward selection from that one never fits the pair. The look-ahead
// from the base, through the single that lowers the fit records' chi-square most, does.
ScriptedFits TwoEffectsHiddenFromTheFirstPath(double damping_heldout_chi2) {
  ScriptedFits fits;
  fits.chi2 = {{"quadratic_damping<-", 800},
               {"cubic_stiffness<-", 500},  // the largest fit gain
               {"dry_friction<-", 600},
               {"quadratic_damping+cubic_stiffness<-quadratic_damping", 790},
               {"cubic_stiffness+quadratic_damping<-cubic_stiffness", 480},
               {"cubic_stiffness+dry_friction<-cubic_stiffness", 110},  // the truth: within noise
               {"cubic_stiffness<-cubic_stiffness+dry_friction", 500}};
  fits.heldout = {{"quadratic_damping<-", damping_heldout_chi2},
                  {"cubic_stiffness<-", 1100},
                  {"dry_friction<-", 1050},
                  {"quadratic_damping+cubic_stiffness<-quadratic_damping", damping_heldout_chi2 - 5},
                  {"cubic_stiffness+quadratic_damping<-cubic_stiffness", 1090},
                  {"cubic_stiffness+dry_friction<-cubic_stiffness", 100},
                  {"cubic_stiffness<-cubic_stiffness+dry_friction", 1100}};
  return fits;
}

const std::vector<Effect> kThreeSingles = {Effect::kCubicStiffness, Effect::kDryFriction, Effect::kQuadraticDamping};

TEST(SelectEffectsTest, APairWhoseSinglesLoseOnTheHeldOutRecordsIsFoundFromTheLargestFitGain) {
  ScriptedFits fits = TwoEffectsHiddenFromTheFirstPath(950);
  std::vector<CandidateFit> candidates;
  const int chosen = Select(fits, &candidates, kThreeSingles);
  ASSERT_GE(chosen, 0);
  EXPECT_EQ(candidates[chosen].label, "cubic_stiffness+dry_friction");
  EXPECT_EQ(candidates[chosen].decision, "");
}

// The broadband diagnosis's figures carry no degrees of freedom: the fit's own test says whether the
// chosen model leaves its fit records beyond noise (broadband pair 8413, contact damping and a force
// factor, where the first path took k2).
TEST(SelectEffectsTest, ABroadbandSelectionLooksAheadWhereItsFitsOwnTestRejectsTheChosenModel) {
  ScriptedFits fits = TwoEffectsHiddenFromTheFirstPath(950);
  fits.broadband = true;
  std::vector<CandidateFit> candidates;
  const int chosen = Select(fits, &candidates, kThreeSingles);
  ASSERT_GE(chosen, 0);
  EXPECT_EQ(candidates[chosen].figures.dof, 0u);
  EXPECT_EQ(candidates[chosen].label, "cubic_stiffness+dry_friction");

  fits.chi2["quadratic_damping<-"] = 120;  // within the fit's own test: no look-ahead
  candidates.clear();
  const int within = Select(fits, &candidates, kThreeSingles);
  ASSERT_GE(within, 0);
  EXPECT_EQ(candidates[within].label, "quadratic_damping");
}

TEST(SelectEffectsTest, ALookAheadModelThatItsFitRecordsRejectIsNotTaken) {
  ScriptedFits fits = TwoEffectsHiddenFromTheFirstPath(950);
  fits.chi2["cubic_stiffness+dry_friction<-cubic_stiffness"] = 300;  // beyond noise (149)
  std::vector<CandidateFit> candidates;
  const int chosen = Select(fits, &candidates, kThreeSingles);
  ASSERT_GE(chosen, 0);
  EXPECT_EQ(candidates[chosen].label, "quadratic_damping");
  const auto pair = std::find_if(candidates.begin(), candidates.end(),
                                 [](const CandidateFit& c) { return c.label == "cubic_stiffness+dry_friction"; });
  ASSERT_NE(pair, candidates.end());
  EXPECT_EQ(pair->decision, "looked ahead to, but its fit records reject it too");
}

TEST(SelectEffectsTest, TheLookAheadMustBeatTheFirstPathBeyondNoise) {
  ScriptedFits fits = TwoEffectsHiddenFromTheFirstPath(105);  // the pair gains only 5 over it
  std::vector<CandidateFit> candidates;
  const int chosen = Select(fits, &candidates, kThreeSingles);
  ASSERT_GE(chosen, 0);
  EXPECT_EQ(candidates[chosen].label, "quadratic_damping");
}

TEST(SelectEffectsTest, NoLookAheadWhereTheFirstPathFitsWithinNoise) {
  ScriptedFits fits = TwoEffectsHiddenFromTheFirstPath(950);
  fits.chi2["quadratic_damping<-"] = 120;  // within noise, though cubic_stiffness lowers it more
  fits.chi2["cubic_stiffness<-"] = 100;
  std::vector<CandidateFit> candidates;
  const int chosen = Select(fits, &candidates, kThreeSingles);
  ASSERT_GE(chosen, 0);
  EXPECT_EQ(candidates[chosen].label, "quadratic_damping");
  for (const CandidateFit& c : candidates) EXPECT_NE(c.label, "cubic_stiffness+dry_friction");
}

// Three effects present, one large: forward selection takes it, and then neither second effect beats
// it on the held-out records (the third one missing bends each pair). The look-ahead from the large
// one's widest pair (the largest fit-records gain) reaches the triple.
TEST(SelectEffectsTest, TheLookAheadFromTheFirstEffectsWidestPairReachesATriple) {
  ScriptedFits fits;
  fits.chi2 = {{"cubic_stiffness<-", 300},  // beyond noise (149)
               {"quadratic_damping<-", 990},
               {"dry_friction<-", 995},
               {"cubic_stiffness+quadratic_damping<-cubic_stiffness", 200},
               {"cubic_stiffness+dry_friction<-cubic_stiffness", 290},
               {"cubic_stiffness+quadratic_damping+dry_friction<-cubic_stiffness+quadratic_damping", 100}};
  fits.heldout = {{"quadratic_damping<-", 1000},
                  {"dry_friction<-", 1005},
                  {"cubic_stiffness+quadratic_damping<-cubic_stiffness", 305},  // loses 5 held out
                  {"cubic_stiffness+dry_friction<-cubic_stiffness", 310}};
  std::vector<CandidateFit> candidates;
  const int chosen = Select(fits, &candidates, kThreeSingles);
  ASSERT_GE(chosen, 0);
  EXPECT_EQ(candidates[chosen].label, "cubic_stiffness+quadratic_damping+dry_friction");
  EXPECT_EQ(candidates[chosen].decision, "");
}

// Three effects present where one's single fit stands in for another: k3 first, then k3 + quadratic
// damping beats it beyond noise with k3 within noise of zero. Its significant part, quadratic damping
// refitted from its solution, beats k3 alone, and from there the pair with friction is the truth. (Without
// the swap the selection ends at k3 + friction, which gains 20 over k3.)
TEST(SelectEffectsTest, AnExtensionWithAnInsignificantEffectSwapsItOut) {
  ScriptedFits fits;
  fits.chi2 = {{"cubic_stiffness<-", 500},
               {"dry_friction<-", 900},
               {"quadratic_damping<-", 950},
               {"cubic_stiffness+dry_friction<-cubic_stiffness", 480},
               {"cubic_stiffness+quadratic_damping<-cubic_stiffness", 300},
               {"quadratic_damping<-cubic_stiffness+quadratic_damping", 310},
               {"quadratic_damping+cubic_stiffness<-quadratic_damping", 305},
               {"quadratic_damping+dry_friction<-quadratic_damping", 100},
               {"quadratic_damping<-quadratic_damping+dry_friction", 320}};
  fits.insignificant = {{"cubic_stiffness+quadratic_damping<-cubic_stiffness", Effect::kCubicStiffness}};
  std::vector<CandidateFit> candidates;
  const int chosen = Select(fits, &candidates, kThreeSingles);
  ASSERT_GE(chosen, 0);
  EXPECT_EQ(candidates[chosen].label, "quadratic_damping+dry_friction");
  EXPECT_EQ(candidates[chosen].decision, "");
  bool swapped_from_the_pair = false;
  for (const auto& [key, start] : fits.starts)
    if (key == "quadratic_damping<-cubic_stiffness+quadratic_damping") {
      swapped_from_the_pair = true;
      EXPECT_EQ(start.cubic_stiffness_n_per_m3, 0.0);  // the pair's solution without k3
    }
  EXPECT_TRUE(swapped_from_the_pair);
}

// A stand-in taken first: friction, then k3, then quadratic damping. The triple's pair without
// friction was never fitted; fitted from the triple's solution, it is within noise of the triple, so
// friction is dropped and the pair is the answer, not the triple.
TEST(SelectEffectsTest, AnEarlierEffectThatTheLaterOnesMakeNeedlessIsDropped) {
  ScriptedFits fits;
  fits.chi2 = {{"dry_friction<-", 500},
               {"cubic_stiffness<-", 600},
               {"quadratic_damping<-", 700},
               {"dry_friction+cubic_stiffness<-dry_friction", 300},
               {"dry_friction+quadratic_damping<-dry_friction", 400},
               {"dry_friction<-dry_friction+cubic_stiffness", 490},
               {"dry_friction+cubic_stiffness+quadratic_damping<-dry_friction+cubic_stiffness", 100},
               {"cubic_stiffness+quadratic_damping<-dry_friction+cubic_stiffness+quadratic_damping", 105},
               {"dry_friction+cubic_stiffness<-dry_friction+cubic_stiffness+quadratic_damping", 300}};
  std::vector<CandidateFit> candidates;
  const int chosen = Select(fits, &candidates, kThreeSingles);
  ASSERT_GE(chosen, 0);
  EXPECT_EQ(candidates[chosen].label, "cubic_stiffness+quadratic_damping");
  for (const CandidateFit& c : candidates) {
    if (c.label == "dry_friction+cubic_stiffness+quadratic_damping") {
      EXPECT_NE(c.decision.find("backward check: without dry_friction"), std::string::npos) << c.decision;
    }
  }
}

TEST(PartialExplanationTest, ACandidateThatLeavesMoreThanItRemovesIsNotNamedOnEitherParts) {
  FitFigures before;
  before.chi2 = 25000;  // fit parts
  before.heldout_chi2 = 6200;
  CandidateFit c;
  c.label = "quadratic_stiffness+cubic_stiffness";
  c.figures.chi2 = 24400;  // removes 600 of the fit parts' excess, leaves 5400 over 19000
  c.figures.heldout_chi2 = 6100;
  EXPECT_EQ(internal::PartialExplanation(c, before, 19000, false),
            "the best library candidate, quadratic_stiffness+cubic_stiffness, removes only 600 of the fit records' "
            "chi-square's excess and leaves 5400: it is not named");
  EXPECT_EQ(internal::PartialExplanation(c, before, 6000, true), "");  // held out: removes 100, leaves 100
  c.figures.chi2 = 19500;  // removes 5500, leaves 500: named
  EXPECT_EQ(internal::PartialExplanation(c, before, 19000, false), "");
}

// Beside a mode that rings after the impacts, the answer is the best fitted part of the chosen model
// without its effects at the stop that beats the base: k3 of k3 + contact damping (the lower held-out
// chi-square of k3's two fits), not c2 (not a part), nor a part that does not beat the base.
TEST(BestWithoutStopEffectsTest, TakesTheBestPartWithoutTheStopsEffectsThatBeatsTheBase) {
  auto fit = [](std::vector<Effect> effects, double heldout_chi2, double heldout_gain, bool fitted = true) {
    CandidateFit c;
    c.effects = std::move(effects);
    c.fitted = fitted;
    c.figures.heldout_chi2 = heldout_chi2;
    c.heldout_gain = heldout_gain;
    return c;
  };
  const Effect k3 = Effect::kCubicStiffness, cs = Effect::kContactDamping, c2 = Effect::kQuadraticDamping;
  std::vector<CandidateFit> all = {fit({cs}, 150, 5000), fit({k3}, 900, 4000), fit({c2}, 500, 4500),
                                   fit({k3, cs}, 120, 5100), fit({k3}, 800, 4100), fit({k3}, 100, 0, false)};
  EXPECT_EQ(internal::BestWithoutStopEffects(all, 3, 10), 4);
  EXPECT_EQ(internal::BestPart(all, {k3, c2}, 10), 2);  // any part: c2's held-out chi-square is the lowest
  all[4].heldout_gain = all[1].heldout_gain = 5;  // neither beats the base by more than 10
  EXPECT_EQ(internal::BestWithoutStopEffects(all, 3, 10), -1);
  EXPECT_EQ(internal::BestWithoutStopEffects(all, 0, 10), -1);  // contact damping alone: the base
}

// A model that misses by ten times the noise: its standard errors, from noise alone, scaled by ten. An
// effect 12 standard errors from zero (1.2 scaled ones) is left out, one 30 from zero stands, and so
// does an amplifier limit 25 below the largest drive (2.5 scaled ones), but not one 16.7 below; within
// noise (a ratio of 1 or less, or undefined) nothing is scaled.
TEST(SignificantUnderMisfitTest, ScalesTheStandardErrorsByTheMisfitsRatioToNoise) {
  CandidateFit c;
  c.effects = {Effect::kCubicStiffness, Effect::kContactDamping, Effect::kAmplifierSaturation};
  c.label = internal::Label(c.effects);
  c.max_drive_v = 0.5;
  c.effect_parameters = {Estimate("k3", 1.2e7, 1e6), Estimate("c_s", 30.0, 1.0),
                         Estimate("amplifier_limit_v", 0.45, 0.002)};
  std::string why;
  EXPECT_EQ(internal::SignificantUnderMisfit(c, 10.0, &why),
            (std::vector<Effect>{Effect::kContactDamping, Effect::kAmplifierSaturation}));
  EXPECT_EQ(why, "cubic_stiffness+contact_damping+amplifier_saturation leaves a misfit of 10 times the noise, and "
                 "with its standard errors scaled by that, k3 = 1.2e+07 +- 1e+07 is within 2 standard errors of "
                 "zero: cubic_stiffness not named");
  c.effect_parameters[2].standard_error = 0.003;  // 16.7 standard errors, 1.67 scaled ones
  why.clear();
  EXPECT_EQ(internal::SignificantUnderMisfit(c, 10.0, &why), (std::vector<Effect>{Effect::kContactDamping}));
  for (double within_noise : {1.0, 0.7, std::nan("")}) {
    why.clear();
    EXPECT_EQ(internal::SignificantUnderMisfit(c, within_noise, &why), c.effects) << within_noise;
    EXPECT_EQ(why, "");
  }
}

// The open world's naming: k3 + c_s misses by ten times the noise and c_s (5 standard errors) does not
// stand then, so k3 alone answers. Where k3 alone is within noise, or misses but removed more of the
// excess than it leaves, it is named; where it removed less, nothing is, and the base is tested last.
TEST(NameWhatStandsTest, TakesThePartThatStandsThenAsksItToExplainMostOfTheMisfit) {
  auto fit = [](std::vector<Effect> effects, std::vector<FitParameter> parameters, double chi2) {
    CandidateFit c;
    c.effects = std::move(effects);
    c.label = internal::Label(c.effects);
    c.fitted = true;
    c.effect_parameters = std::move(parameters);
    c.figures.chi2 = c.figures.heldout_chi2 = chi2;
    c.heldout_gain = 500;
    return c;
  };
  const FitParameter k3 = Estimate("k3", 1.5e7, 1e5);
  const FitParameter c_s = Estimate("c_s", 5.0, 1.0);
  FitFigures before;
  before.chi2 = before.heldout_chi2 = 10000;
  struct Case {
    double k3_chi2;
    bool k3_within_noise;
    int named;
    std::vector<int> tested;
  };
  for (const Case& x : {Case{3000, true, 0, {1, 0}}, Case{3000, false, 0, {1, 0}}, Case{6000, false, -1, {1, 0, -1}}}) {
    const std::vector<CandidateFit> all = {
        fit({Effect::kCubicStiffness}, {k3}, x.k3_chi2),
        fit({Effect::kCubicStiffness, Effect::kContactDamping}, {k3, c_s}, 2500)};
    std::vector<int> tested;
    auto test = [&](int index) -> std::optional<internal::Misfit> {
      tested.push_back(index);
      if (index == 1) return internal::Misfit{10.0, 100.0, true, ""};
      if (index == 0 && !x.k3_within_noise) return internal::Misfit{5.0, 100.0, true, ""};  // k3: 30 scaled errors
      return std::nullopt;
    };
    std::string partial;
    std::vector<Effect> best_partial;
    EXPECT_EQ(internal::NameWhatStands(all, 1, before, 10, test, &partial, &best_partial), x.named) << x.k3_chi2;
    EXPECT_EQ(tested, x.tested);
    EXPECT_EQ(best_partial, all[1].effects);
    EXPECT_NE(partial.find("c_s = 5 +- 10 is within 2 standard errors of zero: contact_damping not named"),
              std::string::npos) << partial;
    EXPECT_EQ(partial.find("removes only") != std::string::npos, x.named < 0) << partial;  // PartialExplanation
  }
}

// Each effect of a model that misses must remove at least what the model leaves (gen2 10037's figures:
// suspension creep, in no library, taken up by a force factor and dry friction). The pair leaves 1264
// over the 120 noise gives; without friction the force factor alone is at 1821 (friction removes 437),
// without the force factor friction alone at 3982 (2598): friction is left out, and the force factor
// alone answers. An effect whose model without it was never fitted is kept; so is a single effect
// (PartialExplanation's to judge); on the fit records' figures the same.
TEST(EachRemovesWhatIsLeftTest, AnEffectThatRemovesLessThanTheModelLeavesIsLeftOut) {
  auto fit = [](std::vector<Effect> effects, double chi2) {
    CandidateFit c;
    c.effects = std::move(effects);
    c.label = internal::Label(c.effects);
    c.fitted = true;
    c.effect_parameters = {Estimate("b2", -1e4, 900)};
    c.figures.chi2 = c.figures.heldout_chi2 = chi2;
    c.heldout_gain = 1000;
    return c;
  };
  const Effect ff = Effect::kForceFactor, fc = Effect::kDryFriction, k3 = Effect::kCubicStiffness;
  const std::vector<CandidateFit> all = {fit({ff}, 1821), fit({fc}, 3982), fit({ff, fc}, 1384), fit({k3}, 5000),
                                         fit({ff, fc, k3}, 1370)};
  for (bool heldout : {true, false}) {
    std::string why;
    EXPECT_EQ(internal::EachRemovesWhatIsLeft(all, 2, all[2].effects, internal::Misfit{3.4, 120, heldout, ""}, &why),
              std::vector<Effect>{ff});
    EXPECT_EQ(why, std::string("force_factor+dry_friction leaves 1264 of the ") +
                       (heldout ? "held-out chi-square's" : "fit records' chi-square's") +
                       " excess, and dry_friction removes only 437 of it beside force_factor: not named");
  }
  std::string why;
  EXPECT_EQ(internal::EachRemovesWhatIsLeft(all, 2, all[2].effects, internal::Misfit{1.5, 1200, true, ""}, &why),
            all[2].effects);  // leaves 184: each removes more
  EXPECT_EQ(why, "");
  EXPECT_EQ(internal::EachRemovesWhatIsLeft(all, 0, all[0].effects, internal::Misfit{3.4, 120, true, ""}, &why),
            all[0].effects);
  // The triple: without k3 (the pair) 14 more, without friction or the force factor never fitted.
  EXPECT_EQ(internal::EachRemovesWhatIsLeft(all, 4, all[4].effects, internal::Misfit{3.4, 120, true, ""}, &why),
            (std::vector<Effect>{ff, fc}));
  // In the naming: the pair misses, both parameters stand, and the force factor alone answers.
  std::vector<int> tested;
  auto test = [&](int index) -> std::optional<internal::Misfit> {
    tested.push_back(index);
    return internal::Misfit{3.4, 120, true, ""};
  };
  std::string partial;
  std::vector<Effect> best_partial;
  FitFigures before;
  before.heldout_chi2 = 8889;  // the force factor alone removes 7068 and leaves 1701: named
  EXPECT_EQ(internal::NameWhatStands(all, 2, before, 10, test, &partial, &best_partial), 0);
  EXPECT_EQ(tested, (std::vector<int>{2, 0}));
  EXPECT_EQ(best_partial, all[2].effects);
}

// A model that misses some record worse than the base (open_world.h WorseThanTheBase) is not named,
// though it removes most of the excess: the base is tested last, and the why is the candidate's.
TEST(NameWhatStandsTest, AModelWorseThanTheBaseOnARecordIsNotNamed) {
  CandidateFit ff;
  ff.effects = {Effect::kForceFactor};
  ff.label = internal::Label(ff.effects);
  ff.fitted = true;
  ff.effect_parameters = {Estimate("b2", -1e4, 900)};
  ff.figures.heldout_chi2 = 1821;
  ff.heldout_gain = 1000;
  FitFigures before;
  before.heldout_chi2 = 8889;
  for (bool worse : {false, true}) {
    std::vector<int> tested;
    auto test = [&](int index) -> std::optional<internal::Misfit> {
      tested.push_back(index);
      return internal::Misfit{3.9, 120, true, worse && index == 0 ? "misses rec_008.csv" : ""};
    };
    std::string partial;
    std::vector<Effect> best_partial;
    EXPECT_EQ(internal::NameWhatStands({ff}, 0, before, 10, test, &partial, &best_partial), worse ? -1 : 0);
    EXPECT_EQ(tested, (worse ? std::vector<int>{0, -1} : std::vector<int>{0}));
    EXPECT_EQ(partial, worse ? "force_factor misses rec_008.csv" : "");
  }
}

// A second stop hit once, in a held-out part (broadband study 8415): its candidate removes the whole
// held-out excess, but the records it is fitted to do not show it (fit gain within Akaike's penalty,
// d_upper without a standard error). It is said, not named; k3, which also gains nothing on them but
// removes less of the held-out excess than it leaves, is not; nor is an effect the fit records show.
TEST(UnseenInFitRecordsTest, SaysWhatOnlyTheHeldOutRecordsShow) {
  auto fit = [](Effect e, FitParameter parameter, double fit_gain, double heldout_chi2) {
    CandidateFit c;
    c.effects = {e};
    c.label = internal::Label(c.effects);
    c.fitted = true;
    c.effect_parameters = {parameter};
    c.fit_gain = fit_gain;
    c.figures.heldout_chi2 = heldout_chi2;
    c.heldout_gain = 1.7e6 - heldout_chi2;
    return c;
  };
  FitFigures before;
  before.heldout_chi2 = 1.7e6;
  const double expected = 6144;
  const CandidateFit stop = fit(Effect::kSecondStop, Estimate("d_upper", 1.2e-3, std::nan("")), 1e-4, 6085);
  const CandidateFit k3 = fit(Effect::kCubicStiffness, Estimate("k3", -8e5, 6e5), 1.9, 1.56e6);
  const CandidateFit shown = fit(Effect::kContactDamping, Estimate("c_s", 40, 2), 2.1, 6000);
  const std::string said = internal::UnseenInFitRecords({k3, stop}, before, expected, 10);
  EXPECT_EQ(said.rfind("second_stop would remove 1.694e+06 of the held-out chi-square's excess and leave none", 0), 0u)
      << said;
  EXPECT_NE(said.find("within Akaike's penalty 2; d_upper not identifiable from them): it is not named"),
            std::string::npos) << said;
  EXPECT_EQ(internal::UnseenInFitRecords({k3}, before, expected, 10), "");
  EXPECT_EQ(internal::UnseenInFitRecords({shown, k3}, before, expected, 10), "");
}

}  // namespace
}  // namespace strokelab
