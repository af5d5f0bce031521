// The diagnosis (diagnose.h): split, base fit, signatures, candidate fits, choice.
#include "strokelab/diagnose/diagnose.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <numbers>
#include <numeric>
#include <optional>
#include <sstream>

#include "diagnose_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/nan.h"
#include "strokelab/base/parallel_for.h"
#include "strokelab/diagnose/effect_curves.h"
#include "strokelab/steady/steady_state.h"

namespace strokelab {
namespace {

using internal::EffectContext;
using internal::ExtendedFitOptions;
using internal::ExtendedFitResult;
using internal::ExtendedProblem;
// Grid points per axis of the report's maps: a smooth model's sweep costs ~0.1 s per point today.
constexpr int kMaxMapPoints = 400;

std::string Format(double value, int digits = 4) {
  std::ostringstream out;
  out.precision(digits);
  out << value;
  return out.str();
}

// Every record matched by `model` on its best-matching orbit.
std::vector<RecordMatch> MatchAll(const ActuatorModel& model, std::span<const RecordAnalysis> analyses,
                                  const std::vector<bool>& heldout, ResponseKind kind, int orders) {
  std::vector<RecordMatch> matches(analyses.size());
  ParallelFor(analyses.size(), [&](size_t i) {
    const RecordAnalysis& a = analyses[i];
    RecordMatch& m = matches[i];
    m.name = a.name;
    m.frequency_hz = a.drive.frequency_hz;
    m.amplitude_v = a.drive.amplitude_v;
    m.heldout = heldout[i];
    m.clear = a.clear;
    m.measured = a.harmonics;
    m.nrmse = m.chi2 = m.noise_chi2 = kInf;
    std::optional<internal::Prediction> p;
    try {
      p = internal::Predict(model, a, kind, orders);
    } catch (const std::exception&) {
    }
    if (!p) return;
    m.model = p->harmonics;
    const double mismatch = internal::MismatchSquared(a, p->harmonics);
    m.power = internal::PowerOf(a);
    m.nrmse = std::sqrt(mismatch / m.power);
    m.chi2 = mismatch / p->variance;
    m.noise_chi2 = mismatch / (a.harmonic_se * a.harmonic_se);
    m.harmonic_chi2.assign(a.harmonics.size(), 0.0);
    for (size_t h = 0; h < a.harmonics.size(); ++h) {
      if (!a.usable.empty() && !a.usable[h]) continue;
      m.harmonic_chi2[h] = std::norm(a.harmonics[h] - p->harmonics[h]) / p->variance;
      m.residuals += 2;
    }
    m.model_period = p->orbit.anchor.period;
    m.model_start = p->orbit.anchor.start;
    m.variance = p->variance;
    try {
      m.model_mean_x_m = internal::OrbitMeanDisplacement(
          model, SineDrive{a.drive.amplitude_v, a.drive.frequency_hz, 0.0}, p->orbit.anchor);
    } catch (const std::exception&) {
      // the surface (missing_force.cc) then takes the mean as 0
    }
    m.model_contacts_per_period = p->orbit.contacts_per_period;
  });
  return matches;
}

FitFigures Figures(const std::vector<RecordMatch>& matches, size_t parameters) {
  FitFigures f;
  double mismatch = 0, power = 0, mismatch_ho = 0, power_ho = 0;
  size_t residuals = 0;
  for (const RecordMatch& m : matches) {
    const double p = m.power;
    const double mis = m.nrmse * m.nrmse * p;
    mismatch += mis;
    power += p;
    if (m.heldout) {
      mismatch_ho += mis, power_ho += p;
      f.heldout_chi2 += m.noise_chi2;
    } else {
      f.chi2 += m.noise_chi2;
      residuals += m.residuals;
    }
  }
  f.nrmse = std::sqrt(mismatch / power);
  f.heldout_nrmse = power_ho > 0 ? std::sqrt(mismatch_ho / power_ho) : kNaN;
  f.residual_variance = residuals > parameters ? f.chi2 / static_cast<double>(residuals - parameters) : kNaN;
  f.dof = residuals > parameters ? residuals - parameters : 0;
  f.beyond_noise = internal::BeyondNoise(f.chi2, f.dof);
  return f;
}

EffectContext Context(const FitResult& base, std::span<const RecordAnalysis> analyses) {
  EffectContext c;
  const ActuatorModel& m = base.model;
  c.stop_distance_m = LengthScaleM(m);
  c.min_amplitude_v = kInf;
  c.min_frequency_hz = kInf;
  std::vector<double> penetrations;
  for (const RecordAnalysis& a : analyses) {
    const double nyquist_rad_per_s = std::numbers::pi * a.sample_rate_hz;  // 2 pi (fs / 2)
    c.max_contact_stiffness_n_per_m = std::min(c.max_contact_stiffness_n_per_m, m.mass_kg * nyquist_rad_per_s * nyquist_rad_per_s);
    c.min_amplitude_v = std::min(c.min_amplitude_v, a.drive.amplitude_v);
    c.max_amplitude_v = std::max(c.max_amplitude_v, a.drive.amplitude_v);
    c.min_frequency_hz = std::min(c.min_frequency_hz, a.drive.frequency_hz);
    c.max_frequency_hz = std::max(c.max_frequency_hz, a.drive.frequency_hz);
    try {
      const PeriodMap map(m, a.drive.frequency_hz, a.drive.amplitude_v);
      const SteadyState s = SolveAttractor(map, map.ClippedLinearStart());
      c.min_displacement_m = std::min(c.min_displacement_m, s.figures.min_displacement_m);
      c.max_displacement_m = std::max(c.max_displacement_m, s.figures.max_displacement_m);
      c.max_velocity_m_per_s =
          std::max(c.max_velocity_m_per_s, std::numbers::pi * a.drive.frequency_hz *
                                               (s.figures.max_displacement_m - s.figures.min_displacement_m));
      if (m.HasLowerStop() && s.figures.min_displacement_m < m.lower_stop_m)
        penetrations.push_back(m.lower_stop_m - s.figures.min_displacement_m);
    } catch (const std::exception&) {
    }
  }
  c.contacts = !penetrations.empty() || !base.contact.records.empty();
  // A stop whose d or k_s the base fit could not identify (no orbit reaches it, though records far below
  // resonance count as not clear of it: gen2's coil campaign 10019) is held by every candidate, as the
  // broadband diagnosis holds it: freeing it, and the back-EMF's c_emf with it, left the coil's fit rank
  // deficient, NOT converged, with every base parameter's error undefined.
  c.stop_identified = std::ranges::none_of(base.refinement.unidentified,
                                           [](const std::string& name) { return name == "d" || name == "k_s"; });
  if (!penetrations.empty()) {
    c.max_penetration_m = *std::max_element(penetrations.begin(), penetrations.end());
    std::nth_element(penetrations.begin(), penetrations.begin() + penetrations.size() / 2, penetrations.end());
    c.penetration_m = penetrations[penetrations.size() / 2];
  } else {
    c.penetration_m = 1e-2 * c.stop_distance_m;
  }
  return c;
}

struct Split {
  std::vector<bool> heldout;            // per analysis
  std::vector<size_t> heldout_indices;  // into the analyses
  std::vector<RecordAnalysis> fit;      // the fit records' analyses
  std::vector<const RecordAnalysis*> fit_pointers;  // into `fit` (a move of the Split keeps them valid)
};

// Step 1 (HeldOutRecords).
Split SplitRecords(std::span<const RecordAnalysis> analyses, int heldout_every) {
  Split split;
  split.heldout = HeldOutRecords(analyses, heldout_every);
  for (size_t i = 0; i < analyses.size(); ++i) {
    if (split.heldout[i]) {
      split.heldout_indices.push_back(i);
    } else {
      split.fit.push_back(analyses[i]);
    }
  }
  for (const RecordAnalysis& a : split.fit) split.fit_pointers.push_back(&a);
  return split;
}

// Step 2: the base fit on the fit records, the scales it gives the effects, and the base model on
// every record.
struct BaseStage {
  FitResult fit;
  EffectContext context;
  std::vector<RecordMatch> matches;
  FitFigures figures;
};
BaseStage FitBase(std::span<const RecordAnalysis> analyses, const Split& split, ResponseKind kind,
                  bool absolute_scale, const DiagnoseOptions& options) {
  BaseStage b;
  // Without the sampling correction's slopes, as the candidates' extended fits: a base fit with them
  // and candidates without named force_factor on a synth control (4014, held-out chi-square 12.8
  // residual variances below the base's) and flagged another (4020, 1.25 times the noise).
  FitOptions base_options = options.fit;
  base_options.sampling_slopes = false;
  b.fit = FitAnalysed(split.fit, kind, absolute_scale, base_options);
  b.context = Context(b.fit, split.fit);
  const ExtendedProblem base_problem = internal::BuildProblem(b.fit.model, options.fit.model, {}, b.context, 0);
  b.matches = MatchAll(b.fit.model, analyses, split.heldout, kind, options.fit.harmonic_orders);
  b.figures = Figures(b.matches, base_problem.parameters.size());
  return b;
}

// The base model as `fit` estimates it, with the sampling correction's slopes (FitOptions::sampling_slopes);
// nothing when that fit fails. The selection compares fits with the correction frozen, one estimator
// for all; a misfit is called unexplained only at the better estimate. Where every drive period is a
// whole number of samples, the frozen fit left k_s 16 standard errors off (gen2's control 9706).
std::optional<FitResult> RefitBaseWithSlopes(const Split& split, ResponseKind kind, bool absolute_scale,
                                             const DiagnoseOptions& options) {
  FitOptions refit_options = options.fit;
  refit_options.sampling_slopes = true;
  try {
    return FitAnalysed(split.fit, kind, absolute_scale, refit_options);
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

// The residual's ringing after impacts in the worst places' records (FindRinging), and in words.
void RingingOfWorstPlaces(const Campaign& campaign, std::span<const RecordAnalysis> analyses,
                          const ActuatorModel& model, ResponseKind kind, int orders, Unexplained* u) {
  for (size_t i = 0; i < u->places.size() && i < internal::kRingPlaces; ++i) {
    Unexplained::Place& place = u->places[i];
    const auto analysis = std::find_if(analyses.begin(), analyses.end(), [&](const auto& a) { return a.name == place.record; });
    const auto record = std::find_if(campaign.records.begin(), campaign.records.end(),
                                     [&](const Recording& r) { return r.name == place.record; });
    if (analysis == analyses.end() || record == campaign.records.end()) continue;
    try {
      internal::FindRinging(*record, *analysis, model, kind, orders, &place);
    } catch (const std::exception&) {
      // no ringing figures for this record
    }
  }
  u->description += internal::DescribeRinging(*u, kind, internal::kRingPlaces);
}

// The diagnosis's progress stages as planned with `effects` candidate effects (DiagnoseOptions::progress),
// before the selection revises its plan.
int PlannedStages(size_t effects, const DiagnoseOptions& options) {
  return 3 + internal::SelectionFitsPlanned(effects, options) + internal::MapStages(options);
}

// Where a candidate's fit starts: a model, and the effects' scales from its orbits.
struct CandidateStart {
  ActuatorModel model;
  EffectContext context;
};

// Fits one candidate from `from`: the best start variant (chi-square on the fit records), then the
// refinement. `step` (may be empty) hears where the fit is: the start values, each solve and Ceres
// iteration.
CandidateFit RunCandidate(const std::vector<Effect>& effects, const CandidateStart& from,
                          const DiagnoseOptions& options, const Split& split, std::span<const RecordAnalysis> analyses,
                          ResponseKind kind, const FitFigures& base_figures, double seconds_left,
                          const std::function<void(const std::string&)>& step = {}) {
  const auto clock_start = std::chrono::steady_clock::now();
  const ActuatorModel& start = from.model;
  const EffectContext& context = from.context;
  CandidateFit c;
  c.effects = effects;
  c.label = internal::Label(effects);
  const int orders = options.fit.harmonic_orders;
  int best_variant = 0;
  const int variants = internal::StartVariants(effects, context);
  if (variants > 1) {
    double best = kInf;
    for (int v = 0; v < variants; ++v) {
      if (step) step("start value " + std::to_string(v + 1) + " of " + std::to_string(variants));
      const ExtendedProblem problem = internal::BuildProblem(start, options.fit.model, effects, context, v);
      const double chi2 = internal::Chi2At(split.fit_pointers, kind, problem,
                                           std::vector<double>(problem.parameters.size(), 1.0), orders);
      if (chi2 < best) best = chi2, best_variant = v;
    }
  }
  const ExtendedProblem problem = internal::BuildProblem(start, options.fit.model, effects, context, best_variant);
  ExtendedFitOptions fit_options;
  fit_options.orders = orders;
  fit_options.max_passes = options.max_passes;
  fit_options.max_seconds = std::max(1.0, seconds_left);
  // The coil's tau_e has a floor set by the fit's cost (effects.cc): where the coil is the effect
  // added, one evaluation at the floor finds a coil the records do not show, not iterations at the
  // floor's short steps. (From a start with a fitted coil the floor is far from the optimum, and a
  // step from there tells nothing.)
  for (size_t i = 0; i < problem.parameters.size(); ++i)
    if (problem.parameters[i].field == &ActuatorModel::coil_time_constant_s && !start.HasCoilPole())
      fit_options.floor_probe = static_cast<int>(i);
  if (step)
    fit_options.progress = [&](int solve, int iteration) {
      step("solve " + std::to_string(solve) + " (at most " + std::to_string(options.max_passes) + "), iteration " +
           std::to_string(iteration));
    };
  ExtendedFitResult r;
  try {
    r = internal::FitExtended(split.fit_pointers, kind, problem, fit_options);
  } catch (const std::exception& e) {
    c.note = std::string("fit failed: ") + e.what();
    return c;
  }
  c.fitted = true;
  c.converged = r.converged;
  c.passes = r.passes;
  if (!r.converged) c.note = r.report;
  else if (!r.jitter.empty()) c.note = "converged: " + r.jitter;
  c.model = r.model;
  c.parameters = r.parameters;
  c.covariance = r.covariance;
  internal::ChargeHeldBackEmf(effects, problem, c.model, &c.parameters, &c.covariance);
  c.effect_parameters = internal::EffectParameters(effects, c.parameters);
  c.max_drive_v = context.max_amplitude_v;
  if (step) step("every record at the fitted model");
  const std::vector<RecordMatch> matches =
      MatchAll(r.model, analyses, split.heldout, kind, orders);
  c.figures = Figures(matches, problem.parameters.size());
  const double variance = std::max(1.0, c.figures.residual_variance);
  c.heldout_gain = (base_figures.heldout_chi2 - c.figures.heldout_chi2) / variance;
  c.fit_gain = (base_figures.chi2 - c.figures.chi2) / variance;
  c.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return c;
}

// The diagnosis's end (diagnose.h, step 6 on): the misfit left described from the data, the
// candidates' decisions labelled, and the answer: the diagnosed model, its effects' curves and the
// conclusion. `refit` (may be null) is the base refitted with the sampling slopes where the answer
// stands on it; `partial` says why the best candidate, `best_partial`, was not named (empty: it was
// not so).
void Conclude(const Campaign& campaign, std::span<const RecordAnalysis> analyses, const EffectContext& context,
              const FitResult* refit, size_t chosen_parameters, const std::string& partial,
              const std::vector<Effect>& best_partial, const DiagnoseOptions& options, Diagnosis* d) {
  const ResponseKind kind = campaign.response;
  const int orders = options.fit.harmonic_orders;
  if (d->unexplained && !partial.empty()) d->unexplained->description += "; " + partial;
  const ActuatorModel& base_model = refit ? refit->model : d->base.model;
  if (d->unexplained) {
    const ActuatorModel& diagnosed = d->chosen >= 0 ? d->candidates[d->chosen].model : base_model;
    d->unexplained->missing_force = internal::EstimateMissingForce(diagnosed, d->after, kind);
    RingingOfWorstPlaces(campaign, analyses, diagnosed, kind, orders, &*d->unexplained);
    // (Where only the ring above the harmonics is unexplained, the surface from the harmonics is noise.)
    if (d->unexplained->p_value < internal::kUnexplainedP)
      d->unexplained->description += internal::DescribeMissingForce(d->unexplained->missing_force);
  }
  internal::LabelDecisions(d->chosen, partial, best_partial, &d->candidates);

  if (d->chosen >= 0) {
    const CandidateFit& c = d->candidates[d->chosen];
    d->missing_physics = c.effects;
    d->curves = EffectCurves(c, d->base.model,
                             {context.min_displacement_m, context.max_displacement_m, context.max_velocity_m_per_s,
                              context.max_penetration_m, context.max_amplitude_v, context.min_frequency_hz,
                              context.max_frequency_hz,
                              "reached by the base model's orbits on the fit records"});
    d->fit_after = c.figures;
    d->model = c.model;
    d->model_note = "the base model extended by " + c.label + ", every parameter as fitted with it" +
                    (c.converged ? "" : " (that fit did NOT converge: the parameters may still be off)");
    std::ostringstream text;
    text << "missing physics: " << c.label << (c.converged ? "" : " (its fit did NOT converge)")
         << " (held-out chi-square down by " << Format(c.heldout_gain)
         << " residual variances; normalised RMS error " << Format(d->fit_before.nrmse) << " -> "
         << Format(d->fit_after.nrmse) << ", held out " << Format(d->fit_before.heldout_nrmse) << " -> "
         << Format(d->fit_after.heldout_nrmse) << ")";
    if (d->unexplained) text << "; more is missing that no library effect explains: " << d->unexplained->description;
    d->conclusion = text.str();
  } else {
    d->fit_after = refit ? Figures(d->after, chosen_parameters) : d->fit_before;
    d->model = base_model;
    d->model_note = std::string("nothing named: the base fit's model (") + ToString(options.fit.model) + ")" +
                    (refit ? ", refitted with the sampling correction's slopes (as `fit` does)" : "");
    d->conclusion = d->unexplained
                        ? "unexplained: the model misses something no library effect explains; " +
                              d->unexplained->description
                        : "nothing missing: no candidate effect lowers the held-out chi-square by more than " +
                              Format(options.min_heldout_gain) +
                              " residual variances, and what the base model leaves on the held-out records is noise";
  }
}

}  // namespace

std::vector<bool> HeldOutRecords(std::span<const RecordAnalysis> analyses, int heldout_every) {
  std::vector<bool> heldout(analyses.size(), false);
  if (heldout_every <= 0) return heldout;
  auto amplitude = [&](size_t i) { return analyses[i].nominal_amplitude_v; };
  auto frequency = [&](size_t i) { return analyses[i].nominal_frequency_hz; };
  std::vector<size_t> order(analyses.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return amplitude(a) < amplitude(b); });
  const size_t n = static_cast<size_t>(heldout_every);
  size_t count = 0;
  for (auto level = order.begin(); level != order.end();) {
    const double level_amplitude_v = amplitude(*level);
    const auto end = std::find_if(level, order.end(), [&](size_t i) {
      return std::abs(amplitude(i) - level_amplitude_v) > 0.01 * std::abs(level_amplitude_v);
    });
    std::stable_sort(level, end, [&](size_t a, size_t b) { return frequency(a) < frequency(b); });
    for (auto i = level; i != end; ++i) heldout[*i] = ++count % n == 0;
    if ((end - level) % n == 0) ++count;
    level = end;
  }
  return heldout;
}

std::optional<FieldError> DiagnoseOptions::IsValid() const {
  if (std::optional<FieldError> error = fit.IsValid()) return error;
  if (heldout_every < 2) return FieldError{"heldout_every", "must be >= 2, got " + std::to_string(heldout_every)};
  if (!std::isfinite(min_heldout_gain) || min_heldout_gain < 0)
    return FieldError{"min_heldout_gain", "must be a finite number >= 0"};
  if (max_passes < 1) return FieldError{"max_passes", "must be >= 1, got " + std::to_string(max_passes)};
  if (!(max_seconds > 0)) return FieldError{"max_seconds", "must be > 0"};
  if (map_frequency_points != 0 && (map_frequency_points < 2 || map_frequency_points > kMaxMapPoints))
    return FieldError{"map_frequency_points", "must be 0 (no maps) or 2 .. " + std::to_string(kMaxMapPoints) +
                                                  ", got " + std::to_string(map_frequency_points)};
  if (map_amplitude_points != 0 && (map_amplitude_points < 2 || map_amplitude_points > kMaxMapPoints))
    return FieldError{"map_amplitude_points", "must be 0 (no maps) or 2 .. " + std::to_string(kMaxMapPoints) +
                                                  ", got " + std::to_string(map_amplitude_points)};
  return std::nullopt;
}

const std::vector<OptionInfo<DiagnoseOptions>>& DiagnoseOptionFields() {
  static const std::vector<OptionInfo<DiagnoseOptions>> kFields = {
      {"heldout_every", "heldout_every", "--heldout-every", &DiagnoseOptions::heldout_every},
      {"min_heldout_gain", "min_heldout_gain", "--min-gain", &DiagnoseOptions::min_heldout_gain},
      {"max_seconds", "max_seconds", "--max-seconds", &DiagnoseOptions::max_seconds},
      {"pairs", "pairs", "--no-pairs", &DiagnoseOptions::pairs, true},
      {"coil_inductance", "coil_inductance", "--coil-inductance", &DiagnoseOptions::coil_inductance},
      {"coil_when_unexplained", "coil_when_unexplained", "--no-coil-when-unexplained",
       &DiagnoseOptions::coil_when_unexplained, true},
      {"max_passes", "max_passes", nullptr, &DiagnoseOptions::max_passes},
      {"map_frequency_points", "map_frequency_points", "--map-frequency-points", &DiagnoseOptions::map_frequency_points},
      {"map_amplitude_points", "map_amplitude_points", "--map-amplitude-points", &DiagnoseOptions::map_amplitude_points},
  };
  return kFields;
}

Diagnosis DiagnoseCampaign(const Campaign& campaign, const DiagnoseOptions& options) {
  Validate(options);
  const auto clock_start = std::chrono::steady_clock::now();
  auto seconds_left = [&] {
    return options.max_seconds -
           std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  };
  const ResponseKind kind = campaign.response;
  const int orders = options.fit.harmonic_orders;
  // Progress: stage k of `stages` (diagnose.h); every effect is planned until the base fit says which apply.
  // `reached` is the last stage reported.
  int stages = PlannedStages(std::count_if(EffectLibrary().begin(), EffectLibrary().end(),
                                           [&](const EffectInfo& info) { return internal::Requested(info, options); }),
                             options),
      reached = 0;
  auto progress = [&](int stage, const std::string& name, const std::string& step = {}) {
    reached = std::max(reached, stage);
    if (options.progress) options.progress({stage, stages, name, step});
  };
  Diagnosis d;
  std::vector<std::string> warnings;
  progress(1, "analysing " + std::to_string(campaign.records.size()) + " records");
  const std::vector<RecordAnalysis> analyses = AnalyseCampaign(campaign, options.fit, &warnings);

  // 1. The split.
  const Split split = SplitRecords(analyses, options.heldout_every);
  d.heldout = split.heldout_indices;
  if (d.heldout.empty()) throw InputError("records", "too few records to hold any out (heldout_every " +
                                                         std::to_string(options.heldout_every) + ")");

  // 2. The base fit on the fit records, evaluated on all.
  progress(2, "base fit on " + std::to_string(split.fit.size()) + " records, " + std::to_string(d.heldout.size()) +
                  " held out");
  BaseStage base = FitBase(analyses, split, kind, campaign.absolute_scale, options);
  d.base = std::move(base.fit);
  d.base.warnings.insert(d.base.warnings.begin(), warnings.begin(), warnings.end());
  const EffectContext& context = base.context;
  d.before = std::move(base.matches);
  d.fit_before = base.figures;

  // 3. Signatures.
  std::vector<const EffectInfo*> applicable;
  for (const EffectInfo& info : EffectLibrary())
    if (internal::Applicable(info.effect, options.fit.model, context) && internal::Requested(info, options))
      applicable.push_back(&info);
  stages = PlannedStages(applicable.size(), options);
  progress(3, "signatures of the base model's mismatch");
  d.signatures = internal::MeasureSignatures(campaign, analyses, d.before, d.base.model, kind, options.fit);

  // 4. Single effects, then forward selection.
  std::vector<Effect> singles;
  for (const EffectInfo* info : applicable) singles.push_back(info->effect);
  const CandidateStart from_base{d.base.model, context};
  std::optional<CandidateStart> from_staged;  // the second round's
  // Every fit so far, by its effects and start model: a later round (from the staged estimates, or
  // with the coil's inductance) fits again only what it has not fitted.
  std::map<std::string, CandidateFit> done;
  int first_stage = 4;  // of the current round
  auto fit = [&](const std::vector<Effect>& effects, const ActuatorModel& start, const std::vector<Effect>& from,
                 const internal::SelectionStep& step, const std::string& label) {
    const int stage = first_stage + step.index;
    stages = first_stage - 1 + step.planned + internal::MapStages(options);
    const std::string name = from_staged && from.empty() ? label + ", also from the staged estimates" : label;
    progress(stage, name);
    auto fit_from = [&](const CandidateStart& s) {
      const std::string key = internal::FitKey(effects, s.model);
      if (const auto it = done.find(key); it != done.end()) return it->second;
      return done[key] = RunCandidate(effects, s, options, split, analyses, kind, d.fit_before, seconds_left(),
                                      [&](const std::string& step) { progress(stage, name, step); });
    };
    if (!from.empty()) return fit_from({start, context});
    if (!from_staged) return fit_from(from_base);
    // The second round: the better (chi-square on the fit records) of the single's two fits.
    const CandidateFit first = fit_from(from_base);
    CandidateFit second = fit_from(*from_staged);
    const double seconds = first.seconds + second.seconds;
    const bool first_better = first.fitted && (!second.fitted || first.figures.chi2 <= second.figures.chi2);
    CandidateFit kept = first_better ? first : std::move(second);
    kept.seconds = seconds;
    return kept;
  };
  auto select = [&] {
    d.candidates.clear();
    return internal::SelectEffects(singles, d.fit_before, d.base.model, options, seconds_left, fit, &d.candidates);
  };
  d.chosen = select();
  // A base fit that ended with a parameter on its bound is a poor start for the effect it lacks: a
  // concealed second stop drove k_s to a thirtieth of what the contact times say, and the second
  // stop's fit from there stayed below the stop. Where no candidate then fits the fit records within
  // noise, the selection runs again with each single also fitted from the staged estimates (with the
  // scales of their orbits), the better of its two fits counting.
  const bool any_within_noise = std::any_of(d.candidates.begin(), d.candidates.end(), [](const CandidateFit& c) {
    return c.fitted && !c.figures.beyond_noise;
  });
  if (d.base.refinement.ended_on_bound && d.fit_before.beyond_noise && !any_within_noise) {
    FitResult staged = d.base;
    staged.model = d.base.staged;
    from_staged = CandidateStart{d.base.staged, Context(staged, split.fit)};
    d.selection_rounds = 2;
    first_stage = reached + 1;
    d.chosen = select();
  }

  // 5. The answer, and what it leaves (the open-world test).
  size_t chosen_parameters = 0;  // fitted parameters of the chosen model
  std::string partial;
  std::vector<Effect> best_partial;
  std::optional<FitResult> slopes_refit;  // RefitBaseWithSlopes, once it was needed
  bool slopes_refit_tried = false;
  const FitResult* refit = nullptr;       // slopes_refit, where the answer stands on it
  // The open-world test of `model` (the base extended by `effects`) on its matches in d.after, its
  // parameters' error counted record by record. Counting it only lowers the chi-square, so where the
  // plain one passes without it, so does the test, and the slopes are not computed.
  auto test_after = [&](const ActuatorModel& model, const std::vector<Effect>& effects) {
    const ExtendedProblem problem = internal::BuildProblem(model, options.fit.model, effects, context, 0);
    chosen_parameters = problem.parameters.size();
    std::optional<internal::HeldOutLeverage> leverage;
    if (!internal::HeldOutWithinNoise(d.after)) {
      std::vector<double ActuatorModel::*> fields;
      for (const internal::FreeParameter& p : problem.parameters) fields.push_back(p.field);
      leverage = internal::MeasureHeldOutLeverage(model, fields, d.after, analyses, kind, orders);
    }
    d.unexplained = internal::FindUnexplained(d.after, analyses, chosen_parameters, leverage ? &*leverage : nullptr);
  };
  auto judge = [&](int index) -> std::optional<internal::Misfit> {  // the open-world test of candidates[index]
    d.chosen = index;
    const ActuatorModel& model = d.chosen >= 0 ? d.candidates[d.chosen].model : d.base.model;
    d.after = d.chosen >= 0 ? MatchAll(model, analyses, split.heldout, kind, orders) : d.before;
    test_after(model, d.chosen >= 0 ? d.candidates[d.chosen].effects : std::vector<Effect>{});
    if (!d.unexplained) return std::nullopt;
    return internal::Misfit{d.unexplained->misfit_to_noise, d.unexplained->expected_chi2, true,
                            index >= 0 ? internal::WorseThanTheBase(d.before, d.after) : ""};
  };
  auto answer = [&] {
    refit = nullptr;
    d.chosen =
        internal::NameWhatStands(d.candidates, d.chosen, d.fit_before, options.min_heldout_gain, judge, &partial,
                                 &best_partial);
    if (d.chosen >= 0 || !partial.empty() || !d.unexplained || seconds_left() <= 0) return;
    if (!slopes_refit_tried) {
      progress(reached, "the open-world test",
               "the base model refitted as `fit` does, before calling its misfit unexplained");
      slopes_refit = RefitBaseWithSlopes(split, kind, campaign.absolute_scale, options);
      slopes_refit_tried = true;
    }
    if (!slopes_refit) return;
    refit = &*slopes_refit;
    d.after = MatchAll(refit->model, analyses, split.heldout, kind, orders);
    test_after(refit->model, {});
  };
  answer();
  // The coil's inductance, where the library without it leaves the misfit unexplained: the selection
  // again with it among the singles (only its own fits are new). A gen2 coil campaign (9951) was
  // "unexplained" at 34 times the noise without it; its control (9952) took 1.7 s, 30 s with the coil.
  if (d.unexplained && !options.coil_inductance && options.coil_when_unexplained && seconds_left() > 0 &&
      internal::Applicable(Effect::kCoilInductance, options.fit.model, context)) {
    first_stage = reached + 1;
    singles.push_back(Effect::kCoilInductance);
    d.coil_round = true;
    d.chosen = select();
    answer();
  }
  // Above the fitted harmonics: the model may miss a mode that the impacts make ring, within noise on
  // the harmonics or not. That is physics at the stop that no library effect holds, and an effect at
  // the stop fitted beside it may only stand in for it (gen2's stop on a flexure: contact damping fitted
  // the harmonics within noise), so such effects are not named: the model without them answers.
  auto diagnosed = [&]() -> const ActuatorModel& {
    return d.chosen >= 0 ? d.candidates[d.chosen].model : (refit ? refit->model : d.base.model);
  };
  std::optional<Unexplained> ring =
      internal::FindRingAboveHarmonics(campaign.records, analyses, d.after, diagnosed(), kind, orders, chosen_parameters);
  const int stand_in = ring ? d.chosen : -1;
  if (stand_in >= 0 && std::ranges::any_of(d.candidates[stand_in].effects, internal::ActsAtTheStop)) {
    const std::string why = d.candidates[stand_in].label +
                            " fits the harmonics, but the impacts excite a mode that no library effect holds, "
                            "for which an effect at the stop may stand in: it is not named";
    d.chosen = internal::BestWithoutStopEffects(d.candidates, stand_in, options.min_heldout_gain);
    answer();
    if (!d.unexplained)
      ring = internal::FindRingAboveHarmonics(campaign.records, analyses, d.after, diagnosed(), kind, orders,
                                              chosen_parameters);
    partial = partial.empty() ? why : partial + "; " + why;
    if (best_partial.empty()) best_partial = d.candidates[stand_in].effects;
  }
  const bool heldout_misfit = d.unexplained.has_value();  // on the held-out records' harmonics
  if (!d.unexplained) d.unexplained = std::move(ring);
  if (d.chosen < 0 && heldout_misfit && !refit)
    if (const std::string unseen = internal::UnseenInFitRecords(d.candidates, d.fit_before,
                                                                d.unexplained->expected_chi2, options.min_heldout_gain);
        !unseen.empty())
      partial = partial.empty() ? unseen : partial + "; " + unseen;
  Conclude(campaign, analyses, context, refit, chosen_parameters, partial, best_partial, options, &d);
  d.progress_stages = reached + internal::MapStages(options);
  d.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return d;
}

CandidateFit FitCandidate(const Campaign& campaign, std::span<const Effect> effects, const DiagnoseOptions& options) {
  Validate(options);
  const auto clock_start = std::chrono::steady_clock::now();
  const std::vector<RecordAnalysis> analyses = AnalyseCampaign(campaign, options.fit, nullptr);
  const Split split = SplitRecords(analyses, 0);
  const BaseStage base = FitBase(analyses, split, campaign.response, campaign.absolute_scale, options);
  for (Effect e : effects)
    if (!internal::Applicable(e, options.fit.model, base.context))
      throw InputError("effects", std::string(Info(e).id) + " cannot show in this campaign (" +
                                      (options.fit.model == FitModelKind::kPaper ? "no record reaches the stop"
                                                                                 : "the base model has no stop") +
                                      ")");
  const double seconds_left =
      options.max_seconds - std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return RunCandidate(std::vector<Effect>(effects.begin(), effects.end()), {base.fit.model, base.context}, options,
                      split, analyses, campaign.response, base.figures, seconds_left);
}

}  // namespace strokelab
