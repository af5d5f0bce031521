// The diagnosis's choice among candidate effects (diagnose/selection.h).
#include "strokelab/diagnose/selection.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "diagnose_internal.h"
#include "strokelab/base/chi_square.h"
#include "strokelab/base/nan.h"

namespace strokelab::internal {
namespace {

std::string Format(double value, int digits = 4) {
  std::ostringstream out;
  out.precision(digits);
  out << value;
  return out.str();
}

// Forward selection's limit: effects in one model.
constexpr size_t kMaxEffects = 3;
// An effect whose parameter is within this many standard errors of its null value (zero) is not named.
constexpr double kMinSignificance = 2.0;


// Effects whose parameter is zero when the effect is absent (the others change a law or move a
// limit from infinity; the held-out gain alone decides for them).
bool NullIsZero(Effect e) {
  return e == Effect::kCubicStiffness || e == Effect::kQuadraticStiffness || e == Effect::kContactDamping ||
         e == Effect::kDryFriction || e == Effect::kQuadraticDamping || e == Effect::kForceFactor ||
         e == Effect::kCoilInductance;
}

// Why an amplifier limit is not significant: it clips no record, or not by more than kMinSignificance
// standard errors (its null is the largest drive, above which it changes nothing; without a standard
// error it is held at a bound or not identifiable). Such a "saturation" gains only by the refit of
// the base parameters (a control at 44.1 kHz, gen2 9706: a limit of 0.45005 V, the largest drive
// 0.45 V, named for a held-out gain of 12 residual variances). Empty when it clips significantly.
std::string UnclippedLimit(const CandidateFit& c) {
  if (std::find(c.effects.begin(), c.effects.end(), Effect::kAmplifierSaturation) == c.effects.end()) return "";
  for (const FitParameter& p : c.effect_parameters) {
    if (p.name != "amplifier_limit_v") continue;
    if (std::isfinite(p.standard_error) && c.max_drive_v - p.value > kMinSignificance * p.standard_error) return "";
    return "amplifier_limit_v = " + Format(p.value) + " +- " + Format(p.standard_error) + " V is within " +
           Format(kMinSignificance) + " standard errors of clipping nothing (the largest drive: " +
           Format(c.max_drive_v) + " V)";
  }
  return "";
}

// Why an effect whose null is a law or a limit at infinity is not significant: none of its parameters
// has a standard error (not identifiable: a second stop the motion never reaches, a Hertzian stop never
// touched). It then changes nothing the records show, and its gain is the other parameters' refit (a
// broadband campaign whose base fit lacked a soft stop, study seed 8410: a second stop above the motion
// was named for the lower stop its fit added). Empty when one has a standard error: the held-out gain
// alone decides for such effects.
std::string Unidentified(const CandidateFit& c, Effect e) {
  std::string why;
  for (const char* key : Info(e).parameters)
    for (const FitParameter& p : c.effect_parameters) {
      if (p.name != key) continue;
      if (std::isfinite(p.standard_error)) return "";
      why += (why.empty() ? "" : ", ") + p.name + " = " + Format(p.value);
    }
  if (why.empty()) return "";
  return why + " not identifiable from these records (the gain is the other parameters' refit)";
}

// Why effect `e` of candidate `c` is not significant (empty: it is). A zero-null effect is not when
// none of its parameters lies beyond kMinSignificance standard errors of zero (within them, or
// without a standard error: held at a bound or not identifiable). An amplifier limit's null is the
// largest drive (UnclippedLimit); the other effects' null is a law or a limit at infinity
// (Unidentified).
std::string Insignificance(const CandidateFit& c, Effect e) {
  if (e == Effect::kAmplifierSaturation) return UnclippedLimit(c);
  if (!NullIsZero(e)) return Unidentified(c, e);
  std::string why;
  bool significant = false;
  for (const char* key : Info(e).parameters)
    for (const FitParameter& p : c.effect_parameters) {
      if (p.name != key) continue;
      if (std::isfinite(p.standard_error) && std::abs(p.value) > kMinSignificance * p.standard_error) significant = true;
      why += (why.empty() ? "" : ", ") + p.name + " = " + Format(p.value) + " +- " + Format(p.standard_error);
    }
  if (significant) return "";
  return why + (Info(e).parameters.size() > 1 ? " are" : " is") + " within " + Format(kMinSignificance) +
         " standard errors of zero";
}

// Why some effect of the candidate is not significant (Insignificance); empty when every one is.
std::string InsignificantParameter(const CandidateFit& c) {
  for (Effect e : c.effects)
    if (std::string why = Insignificance(c, e); !why.empty()) return why;
  return "";
}

// The Akaike penalty of the candidate's parameters beyond the `from_effect_parameters` of the model it
// extends (at least one).
double AkaikePenalty(const CandidateFit& c, size_t from_effect_parameters) {
  return kAkaikePenaltyPerParameter *
         std::max(1.0, static_cast<double>(c.effect_parameters.size()) - static_cast<double>(from_effect_parameters));
}

// Why the candidate's figures do not improve on `from` beyond noise (empty: they do): the held-out
// chi-square must drop by more than min_heldout_gain residual variances, the fit records' by more
// than the Akaike penalty of its new parameters.
std::string GainShortfall(const CandidateFit& c, const FitFigures& from, size_t from_effect_parameters,
                          double min_heldout_gain) {
  if (!c.fitted) return "not fitted";
  const double heldout_gain = GainOver(from, c.figures, true), fit_gain = GainOver(from, c.figures, false);
  if (!std::isfinite(heldout_gain) || heldout_gain <= min_heldout_gain)
    return "held-out gain " + Format(heldout_gain) + " <= " + Format(min_heldout_gain);
  if (const double penalty = AkaikePenalty(c, from_effect_parameters); fit_gain <= penalty)
    return "fit gain " + Format(fit_gain) + " <= Akaike penalty " + Format(penalty);
  return "";
}

// Why the candidate does not improve on `from` (empty: it does): its figures beyond noise
// (GainShortfall), and its effects' parameters significant.
std::string Rejection(const CandidateFit& c, const FitFigures& from, size_t from_effect_parameters,
                      double min_heldout_gain) {
  if (std::string why = GainShortfall(c, from, from_effect_parameters, min_heldout_gain); !why.empty()) return why;
  return InsignificantParameter(c);
}

// Whether two models have the same effects, in any order.
bool SameEffects(std::vector<Effect> a, std::vector<Effect> b) {
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  return a == b;
}

// The best fit (lowest chi-square on the fit records) of exactly these effects (any order), or -1.
int FindFit(const std::vector<CandidateFit>& candidates, const std::vector<Effect>& effects) {
  int best = -1;
  for (size_t i = 0; i < candidates.size(); ++i) {
    if (candidates[i].fitted && SameEffects(candidates[i].effects, effects) &&
        (best < 0 || candidates[i].figures.chi2 < candidates[best].figures.chi2))
      best = static_cast<int>(i);
  }
  return best;
}

// `effects` without `e`.
std::vector<Effect> Without(std::vector<Effect> effects, Effect e) {
  std::erase(effects, e);
  return effects;
}

// Backward check of candidates[index]: dropping any one effect must raise the held-out chi-square
// beyond noise. Returns why not (empty: each is needed), and in `smaller` the best fit of the model
// without the unneeded effect (of several, the one with the least held-out chi-square).
std::string UnneededEffect(const std::vector<CandidateFit>& candidates, int index, double min_heldout_gain,
                           int* smaller) {
  const CandidateFit& c = candidates[index];
  std::string why;
  *smaller = -1;
  for (Effect drop : c.effects) {
    const int other = FindFit(candidates, Without(c.effects, drop));
    if (other < 0) continue;
    const double gain = GainOver(candidates[other].figures, c.figures, true);
    if (gain > min_heldout_gain ||
        (*smaller >= 0 && candidates[other].figures.heldout_chi2 >= candidates[*smaller].figures.heldout_chi2))
      continue;
    *smaller = other;
    why = std::string("backward check: without ") + Info(drop).id + " the held-out chi-square rises by only " +
          Format(gain) + " <= " + Format(min_heldout_gain);
  }
  return why;
}

// The fitted model that extends all[from] (the base when from < 0) by one effect and lowers the fit
// records' chi-square most below it, by more than the Akaike penalty of its new parameters; -1: none.
int WidestExtension(const std::vector<CandidateFit>& all, int from, const FitFigures& base_figures) {
  const std::vector<Effect> none;
  const std::vector<Effect>& have = from >= 0 ? all[from].effects : none;
  const FitFigures& below = from >= 0 ? all[from].figures : base_figures;
  const size_t have_parameters = from >= 0 ? all[from].effect_parameters.size() : 0;
  int widest = -1;
  double widest_gain = 0.0;
  for (size_t i = 0; i < all.size(); ++i) {
    const CandidateFit& c = all[i];
    if (!c.fitted || c.effects.size() != have.size() + 1 ||
        !std::all_of(have.begin(), have.end(), [&](Effect e) {
          return std::find(c.effects.begin(), c.effects.end(), e) != c.effects.end();
        }))
      continue;
    const double gain = GainOver(below, c.figures, false);
    if (gain > AkaikePenalty(c, have_parameters) && (widest < 0 || gain > widest_gain))
      widest = static_cast<int>(i), widest_gain = gain;
  }
  return widest;
}

}  // namespace

std::string Label(const std::vector<Effect>& effects) {
  std::string label;
  for (Effect e : effects) label += (label.empty() ? "" : "+") + std::string(Info(e).id);
  return label;
}

std::string FitKey(const std::vector<Effect>& effects, const ActuatorModel& start) {
  std::ostringstream key;
  key << Label(effects) << std::hexfloat;
  for (const ParameterInfo& p : ::strokelab::Parameters()) key << ' ' << start.*p.field;
  key << ' ' << static_cast<int>(start.contact_law);
  return key.str();
}

double GainOver(const FitFigures& from, const FitFigures& to, bool heldout) {
  const double variance = std::max(1.0, to.residual_variance);
  return ((heldout ? from.heldout_chi2 : from.chi2) - (heldout ? to.heldout_chi2 : to.chi2)) / variance;
}

int SelectionFitsPlanned(size_t singles, const DiagnoseOptions& options) {
  const size_t move = options.pairs && singles > 0 ? singles - 1 : 0;
  return static_cast<int>(singles + move);
}

int SelectEffects(std::span<const Effect> singles, const FitFigures& base_figures, const ActuatorModel& base,
                  const DiagnoseOptions& options, const std::function<double()>& seconds_left,
                  const CandidateFitter& fit_at, std::vector<CandidateFit>* candidates) {
  std::vector<CandidateFit>& all = *candidates;
  // The progress's plan (SelectionStep): `planned` is revised at each forward move.
  int fits = 0, planned = SelectionFitsPlanned(singles.size(), options);
  auto fit = [&](const std::vector<Effect>& effects, const ActuatorModel& start, const std::vector<Effect>& from,
                 const std::string& name) {
    planned = std::max(planned, fits + 1);
    return fit_at(effects, start, from, {fits++, planned}, name);
  };
  for (size_t i = 0; i < singles.size(); ++i) {
    const EffectInfo& info = Info(singles[i]);
    if (seconds_left() <= 0) {
      CandidateFit skipped;
      skipped.effects = {info.effect};
      skipped.label = info.id;
      skipped.note = "skipped: the diagnosis's time limit of " + Format(options.max_seconds) + " s was reached";
      all.push_back(skipped);
      continue;
    }
    all.push_back(fit({info.effect}, base, {}, "candidate " + std::string(info.id)));
  }
  auto by_gain = [](const CandidateFit& a, const CandidateFit& b) {
    const double ga = a.fitted ? a.heldout_gain : -kInf, gb = b.fitted ? b.heldout_gain : -kInf;
    return ga > gb;
  };
  std::stable_sort(all.begin(), all.end(), by_gain);
  std::vector<Effect> fitted;  // every single that was fitted, best held-out gain first
  int chosen = -1;             // the best single that beats the base beyond noise
  for (size_t i = 0; i < all.size(); ++i) {
    CandidateFit& c = all[i];
    c.decision = Rejection(c, base_figures, 0, options.min_heldout_gain);
    if (c.decision.empty() && chosen < 0) chosen = static_cast<int>(i);
    if (c.fitted) fitted.push_back(c.effects[0]);
  }

  // Forward selection: add the effect that lowers the held-out chi-square most beyond noise over the
  // current model, refit with every parameter free, repeat. Every effect is tried at each step, not
  // only those that beat the base alone: beside a large first effect, a second one's single fit can
  // do worse than the base (it bends the model towards the first's misfit). Returns the model it
  // ends at (`from` when nothing beats it); `path` (may be null) gets each model it moves to.
  auto forward = [&](int from, std::vector<int>* path) {
    int current_index = from;
    // Each move lowers the held-out chi-square beyond noise; the bound only guards against fits that
    // end differently from different starts.
    for (size_t moves = 0; options.pairs && current_index >= 0 && moves < 2 * kMaxEffects; ++moves) {
      const std::vector<Effect> current = all[current_index].effects;
      const FitFigures now = all[current_index].figures;
      const size_t now_parameters = all[current_index].effect_parameters.size();
      int best = -1;
      // This move's plan: an extension by each effect not held, and the backward check's refits.
      const auto extensions = std::count_if(fitted.begin(), fitted.end(), [&](Effect e) {
        return std::find(current.begin(), current.end(), e) == current.end();
      });
      planned = fits + static_cast<int>((current.size() >= kMaxEffects ? 0 : extensions) + current.size() + 1);
      auto consider = [&](CandidateFit next) {
        next.note += (next.note.empty() ? "" : "; ") + std::string("held-out gain over ") + Label(current) + ": " +
                     Format(GainOver(now, next.figures, true));
        next.decision = Rejection(next, now, now_parameters, options.min_heldout_gain);
        all.push_back(std::move(next));
        const int index = static_cast<int>(all.size() - 1);
        if (all[index].decision.empty() && (best < 0 || all[index].figures.heldout_chi2 < all[best].figures.heldout_chi2))
          best = index;
        return index;
      };
      for (Effect e : fitted) {
        if (current.size() >= kMaxEffects || std::find(current.begin(), current.end(), e) != current.end()) continue;
        if (seconds_left() <= 0) break;
        std::vector<Effect> effects = current;
        effects.push_back(e);
        const int next =
            consider(fit(effects, all[current_index].model, current, "forward selection: candidate " + Label(effects)));
        // An extension that beats the current model beyond noise, but with an effect whose parameter
        // is within noise of its null, has found that effect's stand-in: its significant part is refitted
        // from its solution and competes as a move of its own, the insignificant effect swapped out
        // (gen2 9967, a force factor, k2 and c2 concealed: k3, then k2, and k3 + k2 + the force factor
        // with k3 = (1.4 +- 1.7)e5 N/m^3, whose held-out chi-square was 385 against k3 + k2's 6,988).
        if (all[next].decision.empty() || !GainShortfall(all[next], now, now_parameters, options.min_heldout_gain).empty() ||
            seconds_left() <= 0)
          continue;
        const std::vector<Effect> grown = all[next].effects;
        std::vector<Effect> kept;
        ActuatorModel start = all[next].model;
        for (Effect x : grown) {
          if (Insignificance(all[next], x).empty()) kept.push_back(x);
          else start = WithoutEffect(start, x, base);
        }
        if (kept.empty() || kept.size() == grown.size() || SameEffects(kept, current)) continue;
        consider(fit(kept, start, grown,
                     "forward selection: candidate " + Label(kept) + ", the significant part of " + Label(grown)));
      }
      if (best < 0) break;
      // The models without one effect of the new one, refitted from its solution: the current model
      // always, and any other never fitted (a triple's other pairs). A fit from the base can end short
      // of the current model's optimum, and a second effect then "explains" what that fit left (a
      // clipping level fitted beside a Hertzian stop that takes up the rest of the misfit): from the
      // better start the current model can reach that optimum on its own.
      const std::vector<Effect> extended = all[best].effects;
      const ActuatorModel solution = all[best].model;
      for (Effect x : extended) {
        const std::vector<Effect> without = Without(extended, x);
        if (seconds_left() <= 0) break;
        if (without.empty() || (!SameEffects(without, current) && FindFit(all, without) >= 0)) continue;
        CandidateFit refit = fit(without, WithoutEffect(solution, x, base), extended,
                                 "backward check: " + Label(without) + " refitted from " + Label(extended) + "'s solution");
        refit.note += (refit.note.empty() ? "" : "; ") + std::string("refitted from ") + Label(extended) +
                      "'s solution without " + Info(x).id;
        refit.decision = Rejection(refit, base_figures, 0, options.min_heldout_gain);
        all.push_back(refit);
      }
      // Backward check: each effect of the new model must still beat noise against the best fit of the
      // model without it. Where the one not needed is the effect just added, the selection ends at the
      // current model (its refit, where that fits better); where it is one the model held before (the
      // stand-in of gen2 9966: a force factor taken first, then contact damping and k3, which explain
      // the records without it), it goes on from the model without that one.
      int smaller = -1;
      all[best].decision = UnneededEffect(all, best, options.min_heldout_gain, &smaller);
      if (!all[best].decision.empty()) {
        if (SameEffects(all[smaller].effects, current) || !all[smaller].decision.empty()) {
          const int better = FindFit(all, current);  // the refit, where it fits better
          if (better >= 0 && all[better].decision.empty()) current_index = better;
          break;
        }
        current_index = smaller;
        if (path) path->push_back(smaller);
        continue;
      }
      current_index = best;
      if (path) path->push_back(best);
    }
    return current_index;
  };
  std::vector<int> path = {-1};  // the first path's models: the base, the best single, ...
  if (chosen >= 0) path.push_back(chosen);
  chosen = forward(chosen, &path);

  // Look-ahead, where the first path leaves the fit records beyond noise: from each model on that
  // path (the base first), forward selection again from its extension by the one effect that lowers
  // the fit records' chi-square most, though that extension loses on the held-out records. With two
  // effects missing, the fit of either one alone bends the shared parameters towards the other's
  // misfit and can do worse than the smaller model on the held-out records, so the first path never
  // fits the pair (gen2 9903: a Hertzian stop and quadratic damping; alone they lost 315 and 69 on
  // the held-out records and gained 312 and 266 on the fit records; 9925, k3 with those two: k3 +
  // quadratic damping took the fit records' chi-square from k3's 961 to 507, the held-out one from 612
  // to 624). A model found so must beat the base as any candidate must, fit its own fit records
  // within noise (else it is one more partial answer, reached through a fit that lost on the held-out
  // records: broadband coil 8414 took the force factor beside the coil, both left "unexplained"), and
  // beat the model chosen so far by more than noise on the held-out records. It stops once the chosen
  // model fits the fit records within noise, by the fit's own test (broadband: its noise levels'
  // spread included; broadband pair 8413, contact damping and a force factor: the first path took k2,
  // then contact damping, and left "unexplained", while contact damping alone fitted the fit parts
  // within noise and lost 49,516 on the held-out parts).
  auto beyond_noise = [&] { return (chosen >= 0 ? all[chosen].figures : base_figures).beyond_noise; };
  for (size_t step = 0; options.pairs && step < path.size() && beyond_noise(); ++step) {
    const int widest = WidestExtension(all, path[step], base_figures);
    if (widest < 0 || std::any_of(path.begin(), path.end(), [&](int on) {
          return on >= 0 && SameEffects(all[on].effects, all[widest].effects);
        }))
      continue;  // the first path went there
    const int other = forward(widest, nullptr);
    if (other == widest) continue;
    const std::string rejection = Rejection(all[other], base_figures, 0, options.min_heldout_gain);
    if (!rejection.empty()) all[other].decision = "against the base model: " + rejection;
    else if (all[other].figures.beyond_noise)
      all[other].decision = "looked ahead to, but its fit records reject it too";
    else if (chosen < 0 || GainOver(all[chosen].figures, all[other].figures, true) > options.min_heldout_gain)
      chosen = other;
  }
  return chosen;
}

std::string PartialExplanation(const CandidateFit& chosen, const FitFigures& before, double expected_chi2,
                               bool heldout) {
  const double before_chi2 = heldout ? before.heldout_chi2 : before.chi2;
  const double chosen_chi2 = heldout ? chosen.figures.heldout_chi2 : chosen.figures.chi2;
  const double removed = before_chi2 - chosen_chi2, left = chosen_chi2 - expected_chi2;
  if (removed >= left) return "";
  return "the best library candidate, " + chosen.label + ", removes only " + Format(removed) + " of the " +
         (heldout ? "held-out chi-square's" : "fit records' chi-square's") + " excess and leaves " + Format(left) +
         ": it is not named";
}

std::string UnseenInFitRecords(const std::vector<CandidateFit>& candidates, const FitFigures& before,
                               double expected_chi2, double min_heldout_gain) {
  const auto penalty = [](const CandidateFit& c) { return AkaikePenalty(c, 0); };  // against the base
  int best = -1;
  for (size_t i = 0; i < candidates.size(); ++i) {
    const CandidateFit& c = candidates[i];
    if (c.fitted && c.heldout_gain > min_heldout_gain && !(c.fit_gain > penalty(c)) &&
        (best < 0 || c.figures.heldout_chi2 < candidates[best].figures.heldout_chi2))
      best = static_cast<int>(i);
  }
  if (best < 0) return "";
  const CandidateFit& c = candidates[best];
  const double removed = before.heldout_chi2 - c.figures.heldout_chi2, left = c.figures.heldout_chi2 - expected_chi2;
  if (removed < left) return "";
  std::string unidentified;
  for (const FitParameter& p : c.effect_parameters)
    if (!std::isfinite(p.standard_error)) unidentified += (unidentified.empty() ? "; " : ", ") + p.name;
  if (!unidentified.empty()) unidentified += " not identifiable from them";
  return c.label + " would remove " + Format(removed) + " of the held-out chi-square's excess and leave " +
         (left > 0 ? Format(left) : std::string("none")) + ", but the records it is fitted to do not show it (their " +
         "chi-square falls by " + Format(c.fit_gain) + " residual variances, within Akaike's penalty " +
         Format(penalty(c)) + unidentified +
         "): it is not named; records that show it where they are fitted would tell";
}

std::vector<Effect> SignificantUnderMisfit(const CandidateFit& c, double misfit_to_noise, std::string* why) {
  CandidateFit scaled = c;
  const double ratio = std::isfinite(misfit_to_noise) ? std::max(1.0, misfit_to_noise) : 1.0;
  for (FitParameter& p : scaled.effect_parameters) p.standard_error *= ratio;
  std::vector<Effect> kept, dropped;
  std::string reasons;
  for (Effect e : c.effects) {
    const std::string insignificant = Insignificance(scaled, e);
    if (insignificant.empty()) {
      kept.push_back(e);
    } else {
      dropped.push_back(e);
      reasons += (reasons.empty() ? "" : "; ") + insignificant;
    }
  }
  if (!dropped.empty())
    *why += (why->empty() ? "" : "; ") + c.label + " leaves a misfit of " + Format(ratio, 3) +
            " times the noise, and with its standard errors scaled by that, " + reasons + ": " + Label(dropped) +
            " not named";
  return kept;
}

int BestPart(const std::vector<CandidateFit>& candidates, const std::vector<Effect>& kept, double min_heldout_gain) {
  int best = -1;
  for (size_t i = 0; i < candidates.size(); ++i) {
    const CandidateFit& c = candidates[i];
    const bool part = std::all_of(c.effects.begin(), c.effects.end(), [&](Effect e) {
      return std::find(kept.begin(), kept.end(), e) != kept.end();
    });
    if (c.fitted && part && c.heldout_gain > min_heldout_gain &&
        (best < 0 || c.figures.heldout_chi2 < candidates[best].figures.heldout_chi2))
      best = static_cast<int>(i);
  }
  return best;
}

int BestWithoutStopEffects(const std::vector<CandidateFit>& candidates, int stand_in, double min_heldout_gain) {
  std::vector<Effect> kept = candidates[stand_in].effects;
  std::erase_if(kept, ActsAtTheStop);
  return BestPart(candidates, kept, min_heldout_gain);
}

std::vector<Effect> EachRemovesWhatIsLeft(const std::vector<CandidateFit>& candidates, int chosen,
                                          const std::vector<Effect>& effects, const Misfit& misfit, std::string* why) {
  const auto chi2 = [&](const CandidateFit& c) { return misfit.heldout ? c.figures.heldout_chi2 : c.figures.chi2; };
  const CandidateFit& c = candidates[chosen];
  const double left = chi2(c) - misfit.expected_chi2;
  std::vector<Effect> kept;
  std::string reasons;
  for (Effect e : effects) {
    const int without = c.effects.size() > 1 ? FindFit(candidates, Without(c.effects, e)) : -1;
    const double removed = without >= 0 ? chi2(candidates[without]) - chi2(c) : left;
    if (removed >= left) {
      kept.push_back(e);
      continue;
    }
    reasons += std::string(reasons.empty() ? "" : "; ") + Info(e).id + " removes only " + Format(removed) +
               " of it beside " + candidates[without].label;
  }
  if (!reasons.empty())
    *why += (why->empty() ? "" : "; ") + c.label + " leaves " + Format(left) + " of the " +
            (misfit.heldout ? "held-out chi-square's" : "fit records' chi-square's") + " excess, and " + reasons +
            ": not named";
  return kept;
}

int NameWhatStands(const std::vector<CandidateFit>& candidates, int chosen, const FitFigures& before,
                   double min_heldout_gain, const std::function<std::optional<Misfit>(int)>& test,
                   std::string* partial, std::vector<Effect>* best_partial) {
  partial->clear();
  best_partial->clear();
  std::optional<Misfit> misfit = test(chosen);
  while (chosen >= 0 && misfit) {
    const CandidateFit& c = candidates[chosen];
    std::vector<Effect> kept = SignificantUnderMisfit(c, misfit->to_noise, partial);
    if (kept.size() == c.effects.size()) kept = EachRemovesWhatIsLeft(candidates, chosen, kept, *misfit, partial);
    if (kept.size() == c.effects.size()) break;
    if (best_partial->empty()) *best_partial = c.effects;
    chosen = BestPart(candidates, kept, min_heldout_gain);
    misfit = test(chosen);
  }
  if (chosen < 0 || !misfit) return chosen;
  const std::string why = misfit->worse_than_base.empty()
                              ? PartialExplanation(candidates[chosen], before, misfit->expected_chi2, misfit->heldout)
                              : candidates[chosen].label + " " + misfit->worse_than_base;
  if (why.empty()) return chosen;
  *partial = partial->empty() ? why : *partial + "; " + why;
  if (best_partial->empty()) *best_partial = candidates[chosen].effects;
  test(-1);
  return -1;
}

void LabelDecisions(int chosen, const std::string& partial, const std::vector<Effect>& best_partial,
                    std::vector<CandidateFit>* candidates) {
  for (size_t i = 0; i < candidates->size(); ++i) {
    CandidateFit& c = (*candidates)[i];
    if (static_cast<int>(i) == chosen) c.decision = "named";
    else if (!partial.empty() && c.decision.empty() && c.effects == best_partial) c.decision = "not named: " + partial;
    else if (c.decision.empty()) c.decision = "beats noise, but another model is better";
    else if (c.fitted) c.decision = "rejected: " + c.decision;
  }
}

}  // namespace strokelab::internal
