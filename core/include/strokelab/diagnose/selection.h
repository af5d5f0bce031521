// The diagnosis's choice among candidate effects (diagnose.h, steps 4 and 5; selection.cc): the rules
// shared by the stepped-sine and the broadband diagnosis, which differ in how a candidate is fitted and
// what its figures are made of, not in how one is chosen. Public for its tests.
#pragma once

#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "strokelab/diagnose/diagnose.h"
#include "strokelab/model/model.h"

namespace strokelab::internal {

// `model` without `effect`: the effect's own parameters (and, for a Hertzian stop, its contact law) back
// at `base`'s values, which lack it; every other parameter as `model` has it (effects.cc). The
// backward check refits a model from the larger one's solution so.
ActuatorModel WithoutEffect(const ActuatorModel& model, Effect effect, const ActuatorModel& base);

// "cubic_stiffness+contact_damping".
std::string Label(const std::vector<Effect>& effects);
// The key of a candidate's fit in a diagnosis's cache: its effects and its start model, exactly (a later
// round of the selection fits again only what it has not fitted).
std::string FitKey(const std::vector<Effect>& effects, const ActuatorModel& start);
// Chi-square drop from `from` to `to` (held-out or fit records) in `to`'s residual variances.
double GainOver(const FitFigures& from, const FitFigures& to, bool heldout);
// Where a fit stands in the selection's plan, for the diagnosis's progress: its index among the fits the
// selection asked for (0-based, the singles first, one after another), and how many fits the selection
// plans as far as it knows (always more than index). It plans one forward move after the singles
// (SelectionFitsPlanned) and revises the plan at each move, when it learns which extensions it tries.
struct SelectionStep {
  int index = 0;
  int planned = 0;
};
// Fits the base model extended by `effects` from `start` (a fitted model's parameters as start values:
// those of the candidate of the effects `from`, the base's when empty, maybe with an effect taken out),
// as fit `step` of the selection's plan under `name`; the candidate's figures on the same records as
// the base's.
using CandidateFitter =
    std::function<CandidateFit(const std::vector<Effect>& effects, const ActuatorModel& start,
                               const std::vector<Effect>& from, const SelectionStep& step, const std::string& name)>;
// The fits planned before the selection starts, with `singles` effects: each single, and with
// options.pairs a forward move that extends the best by each of the others (a control ends after the
// singles; a campaign with effects missing makes more moves).
int SelectionFitsPlanned(size_t singles, const DiagnoseOptions& options);
// Steps 4 and 5 of diagnose.h: each of `singles` fitted from `base` (skipped once seconds_left() is
// spent), sorted by held-out gain, then forward selection with its backward check. An extension that
// beats the current model beyond noise but holds an effect within noise of its null has its significant
// part refitted from its solution, which competes as a move (the stand-in swapped out). The check
// compares the larger model with the best fit of the model without each effect; the current model is
// refitted from the larger one's solution for it (WithoutEffect of the added effect), since a fit from
// the base can end short of its optimum and leave a misfit that a spurious second effect then takes
// up, and so is any model without one effect that was never fitted. Where the effect not needed is one
// the model held before, the selection goes on from the model without it. Where
// the model so chosen still fails the fit records' noise test (FitFigures::beyond_noise), it looks ahead
// from each model on its path through that model's extension with the largest fit-records gain, and
// takes a model found so only where its fit records accept it (selection.cc). Appends every candidate
// to `candidates`, each with its decision (empty: it beats the model it extends beyond noise), and
// returns the chosen one's index (-1: none beats the base).
int SelectEffects(std::span<const Effect> singles, const FitFigures& base_figures, const ActuatorModel& base,
                  const DiagnoseOptions& options, const std::function<double()>& seconds_left,
                  const CandidateFitter& fit, std::vector<CandidateFit>* candidates);
// Why the chosen candidate is not named though it beats noise (empty: it is named): it removes less
// of the held-out (or, with heldout false, the fit records') chi-square's excess over `expected_chi2`
// than it leaves.
std::string PartialExplanation(const CandidateFit& chosen, const FitFigures& before, double expected_chi2,
                               bool heldout = true);
// What the held-out records show and the records the models are fitted to do not (empty: nothing): of the
// fitted candidates that lower the held-out chi-square by more than `min_heldout_gain` though their fit
// records' gain is within Akaike's penalty for their parameters, the one with the lowest held-out
// chi-square, where it removes at least as much of the held-out excess over `expected_chi2` as it leaves.
// It is said where the verdict is "unexplained", never named: its parameters come from records that do
// not show it (a second stop hit once, in a held-out part: broadband study 8415).
std::string UnseenInFitRecords(const std::vector<CandidateFit>& candidates, const FitFigures& before,
                               double expected_chi2, double min_heldout_gain);
// The effects of `c` that stand where its model leaves a misfit of `misfit_to_noise` times the noise
// (the open-world test's ratio): its standard errors, which assume residuals of noise alone, are scaled
// by that ratio (at least 1; Birge's ratio: R. T. Birge, "The calculation of errors by the method of
// least squares", Phys. Rev. 40 (1932) 207-227), and an effect whose parameter is then within two of
// its null is left out, with why appended to `why`. A model that misses by ten times the noise fits
// library effects to a force it lacks, and their parameters' noise-only standard errors then say
// nothing (gen2 9998: damping that grows with x^2 was "explained" by three library effects).
std::vector<Effect> SignificantUnderMisfit(const CandidateFit& c, double misfit_to_noise, std::string* why);
// The fitted candidate whose effects are all among `kept`, that beats the base on the held-out records
// by more than `min_heldout_gain` and has the lowest held-out chi-square, or -1 (the base).
int BestPart(const std::vector<CandidateFit>& candidates, const std::vector<Effect>& kept, double min_heldout_gain);
// What the open-world test found beyond noise in a model's held-out (or fit) residuals.
struct Misfit {
  double to_noise = 1.0;       // the misfit's RMS over noise's
  double expected_chi2 = 0.0;  // the chi-square noise alone gives (PartialExplanation's)
  bool heldout = true;         // false: the fit records' (PartialExplanation's)
  std::string worse_than_base;  // open_world.h WorseThanTheBase's why (empty: none, or not asked)
};
// The effects of candidates[chosen] (among `effects`) that each remove at least as much of the excess
// over `misfit`'s expected chi-square as the model leaves: the chi-square of the best fit without the
// effect, less the model's, is at least the model's less the expected (PartialExplanation's rule for a
// model, asked of each of its effects). An effect that removes less may be fitted to part of what no
// library effect explains (gen2 10037, suspension creep in no library: a force factor and dry friction
// named, the friction removing 437 of an excess of 1,264 it left), so it is left out, with why appended
// to `why`. An effect whose model without it was never fitted is kept.
std::vector<Effect> EachRemovesWhatIsLeft(const std::vector<CandidateFit>& candidates, int chosen,
                                          const std::vector<Effect>& effects, const Misfit& misfit, std::string* why);
// The open world's naming (diagnose.h step 6): `test(index)` runs the open-world test of
// candidates[index] (-1: the base) and returns its misfit where it is beyond noise. While the chosen
// model's misfit leaves one of its effects insignificant (SignificantUnderMisfit), its BestPart of the
// effects that stand answers instead, and so does the part of a model whose effects do not each remove
// what it leaves (EachRemovesWhatIsLeft); then a model that misses some record worse than the base
// (Misfit::worse_than_base), or removes less of the excess than it leaves (PartialExplanation), is not
// named. Returns the index named (-1: none; the last test run was of it), with why the others were not
// in `partial` and the first of them in `best_partial` (LabelDecisions').
int NameWhatStands(const std::vector<CandidateFit>& candidates, int chosen, const FitFigures& before,
                   double min_heldout_gain, const std::function<std::optional<Misfit>(int)>& test,
                   std::string* partial, std::vector<Effect>* best_partial);
// Where a mode rings after the impacts that no library effect holds (open_world.h
// FindRingAboveHarmonics), the effects at the stop of candidates[stand_in] may only stand in for it:
// BestPart of its effects without those (Applicable's contact effects).
int BestWithoutStopEffects(const std::vector<CandidateFit>& candidates, int stand_in, double min_heldout_gain);
// The report's decisions: "named" for `chosen`, "not named: <partial>" for the candidate of
// `best_partial`, "beats noise, but another model is better", "rejected: <why>".
void LabelDecisions(int chosen, const std::string& partial, const std::vector<Effect>& best_partial,
                    std::vector<CandidateFit>* candidates);

}  // namespace strokelab::internal
