// Step 4 of the fit (fit.h), the joint refinement: Levenberg-Marquardt (Ceres) on every record's
// harmonics, with sampling corrections, branch switches and the covariance (checked by secants:
// secant_covariance.h). Ceres stays in this file.
#include <ceres/ceres.h>

#include <Eigen/Core>
#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <complex>
#include <exception>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "fit_internal.h"
#include "linearised_correction.h"
#include "step_callback.h"
#include "strokelab/base/cancel.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/parallel_for.h"
#include "strokelab/identify/fit.h"
#include "strokelab/identify/fit_orbit.h"
#include "strokelab/identify/secant_covariance.h"
#include "strokelab/identify/sparse_covariance.h"

namespace strokelab {
namespace fit_internal {
namespace {

using internal::Anchor;
using internal::ModelOrbit;
using internal::OrbitSearch;
using internal::SolveOrbit;

constexpr int kMaxCorrectionPasses = 4;        // refinement passes with refreshed sampling corrections
constexpr double kCorrectionTolerance = 1e-3;  // their change [standard errors] that ends the passes
// A record moves to another coexisting orbit between passes when that one's mismatch is below this
// fraction of its anchor orbit's (a clear win, not noise between two near-identical orbits).
constexpr double kBranchSwitchRatio = 0.5;
constexpr double kParameterRange = 3.0;  // refinement bounds: staged estimate times or over this (k_p, c_p, g, d)
constexpr double kContactRange = 30.0;   // ... and this for k_s, c_s
// Relative step of the central differences in theta = 1 + ln(p / p0): a relative change of about
// 1e-4 in each parameter, far above the steady state's accuracy (shooting to 1e-11 of |d|) and small
// against the curvature of the harmonics (1e-5 gives the same standard errors to 1 %).
constexpr double kNumericStep = 1e-4;

// One record of the refinement: its measured harmonics and the orbit the next evaluation starts from.
struct RecordTarget {
  const RecordAnalysis* record = nullptr;
  double weight = 1.0;  // 1 / harmonic standard error [1 / response units]
  Anchor anchor;
  internal::LinearisedCorrection correction;  // at the last outer pass, with its slopes in theta
};

// Residuals (Re, Im) of (C_h - C_h^model) / se, h = 1..N, for Ceres' central differences.
class HarmonicCost {
 public:
  HarmonicCost(const ParameterLayout* layout, RecordTarget* target, ResponseKind kind, int orders)
      : layout_(layout), target_(target), kind_(kind), orders_(orders) {}

  bool operator()(const double* theta, double* residual) const {
    try {
      const ActuatorModel model = layout_->Decode(theta);
      const std::optional<ModelOrbit> orbit =
          SolveOrbit(model, *target_->record, target_->anchor, kind_, orders_, OrbitSearch::kNearby);
      if (!orbit) return false;
      for (int h = 0; h < orders_; ++h) {
        const double weight = target_->record->usable[h] ? target_->weight : 0.0;
        const Complex r =
            weight * (target_->record->harmonics[h] - orbit->harmonics[h] - target_->correction.At(h, theta));
        residual[2 * h] = r.real();
        residual[2 * h + 1] = r.imag();
      }
      return true;
    } catch (const std::exception&) {
      return false;  // a model the engines refuse (Validate) or a solver failure: Ceres rejects the step
    }
  }

 private:
  const ParameterLayout* layout_;
  RecordTarget* target_;
  ResponseKind kind_;
  int orders_;
};

template <int kParameters>
ceres::CostFunction* MakeCost(const ParameterLayout* layout, RecordTarget* target, ResponseKind kind, int orders) {
  ceres::NumericDiffOptions diff;
  diff.relative_step_size = kNumericStep;
  return new ceres::NumericDiffCostFunction<HarmonicCost, ceres::CENTRAL, ceres::DYNAMIC, kParameters>(
      new HarmonicCost(layout, target, kind, orders), ceres::TAKE_OWNERSHIP, 2 * orders, diff);
}

ceres::CostFunction* MakeCost(int parameters, const ParameterLayout* layout, RecordTarget* target, ResponseKind kind,
                              int orders) {
  switch (parameters) {
    case 3:
      return MakeCost<3>(layout, target, kind, orders);
    case 5:
      return MakeCost<5>(layout, target, kind, orders);
    default:
      return MakeCost<6>(layout, target, kind, orders);
  }
}

}  // namespace
}  // namespace fit_internal

// ---- Step 4 ----------------------------------------------------------------------------------------

void RefineParameters(std::span<const RecordAnalysis> analyses, ResponseKind kind, const ActuatorModel& start,
                      const std::vector<size_t>& used, const FitOptions& options, FitResult* result) {
  using fit_internal::Complex, fit_internal::Format, fit_internal::kBranchSwitchRatio, fit_internal::kContactRange,
      fit_internal::kContactStiffness, fit_internal::kCorrectionTolerance,
      fit_internal::kMaxCorrectionPasses, fit_internal::kNaN, fit_internal::kParameterNames,
      fit_internal::kParameterRange, fit_internal::kStop, fit_internal::MakeCost, fit_internal::MakeLayout,
      fit_internal::ParameterLayout, fit_internal::RecordTarget, fit_internal::ReportParameters;
  using internal::AfterSuccessfulStep, internal::BestMatchingOrbit, internal::ErrorsFromJacobian,
      internal::ParameterErrors, internal::MismatchSquared, internal::ModelOrbit,
      internal::OrbitSearch, internal::PowerOf, internal::SamplingCorrection, internal::SolveOrbit;
  Validate(options);
  const auto clock_start = std::chrono::steady_clock::now();
  const int orders = options.harmonic_orders;
  const ParameterLayout layout = MakeLayout(start, options.fit_contact_damping);
  const int p = layout.size();
  std::vector<double> theta(p, 1.0);

  // Anchors at the start: the stable orbit matching each record best.
  std::vector<RecordTarget> all(analyses.size());
  std::vector<RecordFit>& fits = result->records;
  fits.assign(analyses.size(), RecordFit{});
  const ActuatorModel start_model = layout.Decode(theta.data());
  for (size_t i = 0; i < analyses.size(); ++i) {
    const RecordAnalysis& a = analyses[i];
    all[i].record = &a;
    all[i].weight = 1.0 / a.harmonic_se;
    const std::optional<ModelOrbit> orbit = BestMatchingOrbit(start_model, a, kind, orders);
    if (!orbit) throw NumericalError("no steady state of the starting model at record " + a.name);
    all[i].anchor = orbit->anchor;
    fits[i].nrmse_initial = std::sqrt(MismatchSquared(a, orbit->harmonics) / PowerOf(a));
  }
  std::vector<RecordTarget> targets;
  for (size_t i : used) targets.push_back(all[i]);

  ceres::Problem problem;
  for (RecordTarget& t : targets)
    problem.AddResidualBlock(MakeCost(p, &layout, &t, kind, orders), nullptr, theta.data());
  // Bounds: a factor kParameterRange around the staged estimates (kContactRange for the contact's
  // parameters, which the staged estimate knows least). They keep a model that cannot fit the data
  // from wandering to values where an evaluation costs minutes (a stiff contact takes ever shorter
  // steps); an estimate on its bound is reported.
  for (int i = 0; i < p; ++i) {
    const double range = i >= kContactStiffness ? kContactRange : kParameterRange;
    problem.SetParameterLowerBound(theta.data(), i, 1.0 - std::log(range));
    problem.SetParameterUpperBound(theta.data(), i, 1.0 + std::log(range));
  }

  RefinementSummary& summary = result->refinement;
  summary.parameters = static_cast<size_t>(p);
  summary.residuals = 0;
  for (const RecordTarget& t : targets) summary.residuals += internal::FittedResiduals(*t.record, orders);
  if (summary.residuals <= summary.parameters) throw InputError("records", "too few records to fit the parameters");

  // The sampling corrections at the current iterate, with their slopes; returns their largest change
  // in standard errors.
  auto update_corrections = [&](bool slopes) {
    const ActuatorModel model = layout.Decode(theta.data());
    const auto decode = [&](const double* at) { return layout.Decode(at); };
    double change = 0.0;
    for (RecordTarget& t : targets) {
      try {
        if (const std::optional<ModelOrbit> orbit =
                SolveOrbit(model, *t.record, t.anchor, kind, orders, OrbitSearch::kAttractor))
          t.anchor = orbit->anchor;
      } catch (const std::exception&) {
        // keep the anchor: the evaluation itself will fail and say so
      }
      internal::LinearisedCorrection next =
          internal::LineariseCorrection(decode, theta, *t.record, t.anchor, kind, orders, slopes);
      for (int h = 0; h < orders; ++h)
        change = std::max(change, t.weight * std::abs(next.at[h] - (t.correction.at.empty() ? Complex(0.0)
                                                                                            : t.correction.at[h])));
      t.correction = std::move(next);
    }
    return change;
  };

  // Records whose best-matching stable orbit at the current iterate is another one than their anchor's
  // (a bistable record the start model put on the other branch: the contacting branch may not exist
  // at the start model) move to it; returns how many moved.
  auto reselect_branches = [&] {
    const ActuatorModel model = layout.Decode(theta.data());
    size_t moved = 0;
    for (RecordTarget& t : targets) {
      try {
        const std::optional<ModelOrbit> best = BestMatchingOrbit(model, *t.record, kind, orders);
        if (!best) continue;
        const std::optional<ModelOrbit> current =
            SolveOrbit(model, *t.record, t.anchor, kind, orders, OrbitSearch::kNearby);
        const double now = current ? MismatchSquared(*t.record, current->harmonics) : kInf;
        if (MismatchSquared(*t.record, best->harmonics) < kBranchSwitchRatio * now) {
          t.anchor = best->anchor;
          ++moved;
        }
      } catch (const std::exception&) {
        // keep the anchor
      }
    }
    return moved;
  };

  bool solved = true;
  bool slopes_taken = false;  // the corrections' last update took their slopes
  update_corrections(false);
  if (options.refine) {
    // After each successful step every record's anchor moves to its orbit at the new iterate.
    AfterSuccessfulStep callback([&] {
      const ActuatorModel model = layout.Decode(theta.data());
      for (RecordTarget& t : targets) internal::MoveAnchor(model, *t.record, kind, orders, &t.anchor);
    });
    ceres::Solver::Options solver = internal::RefinementSolverOptions(options.max_iterations, &callback);
    const auto deadline = clock_start + std::chrono::duration<double>(options.max_refinement_seconds);
    // Outer passes: solve with the corrections frozen, recompute them at the solution, and solve
    // again while they moved by more than kCorrectionTolerance standard errors; then solves with their
    // slopes (linearised_correction.h), keeping the end of least chi-square.
    summary.ran = true;
    auto cost_now = [&] {
      double cost = 0.0;
      problem.Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, nullptr);
      return cost;
    };
    auto run_passes = [&](bool slopes) {
      std::vector<double> best = theta;
      double best_cost = slopes ? cost_now() : kInf;
      for (int pass = 0; pass < (slopes ? internal::kSlopeSolves : kMaxCorrectionPasses); ++pass) {
        solver.max_solver_time_in_seconds =
            std::max(1.0, std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count());
        ceres::Solver::Summary ceres_summary;
        ceres::Solve(solver, &problem, &ceres_summary);
        if (summary.correction_passes++ == 0) summary.initial_cost = ceres_summary.initial_cost;
        summary.iterations += static_cast<int>(ceres_summary.iterations.size()) - 1;
        summary.report = ceres_summary.BriefReport();
        solved = ceres_summary.termination_type == ceres::CONVERGENCE;
        const size_t switched = reselect_branches();
        summary.branch_switches += switched;
        const double change = update_corrections(slopes);
        if (slopes) {
          const double cost = solved ? cost_now() : kInf;
          solved = true;  // the frozen passes' end is kept where these do no better
          const bool better = 2.0 * (best_cost - cost) > internal::kSlopeChi2Tolerance;
          if (cost < best_cost) best_cost = cost, best = theta;
          if (!better) break;
        } else if (!solved) {
          return;
        }
        if (change < kCorrectionTolerance && switched == 0) break;
      }
      if (slopes && best != theta) {
        theta = best;
        update_corrections(true);
      }
    };
    run_passes(false);
    if (solved && options.sampling_slopes) {
      update_corrections(true);
      run_passes(true);
      slopes_taken = true;
    }
    if (!solved) {
      summary.report += "\nNOT CONVERGED: Ceres stopped without convergence";
      if (std::chrono::steady_clock::now() >= deadline)
        summary.report += " (time limit of " + Format(options.max_refinement_seconds) + " s)";
    }
    double cost = 0.0;  // at the final corrections
    problem.Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, nullptr);
    summary.final_cost = cost;
  } else {
    double cost = 0.0;
    problem.Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, nullptr);
    summary.initial_cost = summary.final_cost = cost;
    summary.report = "refinement not run: staged estimates, standard errors at them";
  }
  summary.residual_variance = 2.0 * summary.final_cost / static_cast<double>(summary.residuals - summary.parameters);

  // Covariance of theta: (J^T J)^-1 s^2, J with the corrections' slopes (they matter for k_s, which
  // the impacts' high harmonics carry: frozen corrections left its standard error about 30 % too small).
  if (!slopes_taken) update_corrections(true);
  // Ceres' own Covariance (DENSE_SVD) does not check that the Jacobian evaluated: a record without a
  // steady state there, or a cancel (cancel.h), left it empty and Eigen's SVD segfaulted. The same
  // computation here, on a Jacobian known to be whole: J = U S V^T, (J^T J)^-1 = V S^-2 V^T, rank
  // deficient when a squared singular value ratio falls below Ceres' min_reciprocal_condition_number.
  Eigen::MatrixXd covariance = Eigen::MatrixXd::Constant(p, p, kNaN);
  bool stop_held = false;  // the stop's parameters are undetermined, the others have their errors
  std::string held_stop_warning;
  ceres::CRSMatrix crs;
  const bool evaluates = problem.Evaluate(ceres::Problem::EvaluateOptions(), nullptr, nullptr, nullptr, &crs);
  ThrowIfCancelled();
  if (!evaluates) {
    solved = false;
    summary.report += "\nNOT CONVERGED: a record has no steady state at the end";
  } else {
    Eigen::MatrixXd j = Eigen::MatrixXd::Zero(crs.num_rows, p);
    for (int r = 0; r < crs.num_rows; ++r)
      for (int k = crs.rows[r]; k < crs.rows[r + 1]; ++k) j(r, crs.cols[k]) = crs.values[k];
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(j, Eigen::ComputeThinV);
    const Eigen::VectorXd& sigma = svd.singularValues();
    constexpr double kMinReciprocalCondition = 1e-14;  // ceres::Covariance::Options' default
    if (sigma.size() == p && sigma(0) > 0.0 && sigma(p - 1) * sigma(p - 1) >= kMinReciprocalCondition * sigma(0) * sigma(0)) {
      const Eigen::VectorXd inverse_squares = sigma.array().square().inverse();
      covariance = summary.residual_variance * svd.matrixV() * inverse_squares.asDiagonal() * svd.matrixV().transpose();
    } else {
      // Which parameters the records leave undetermined (a stop no orbit reaches: d and k_s), and
      // the others' errors with those held: a rank-deficient covariance is no error of 0.
      const ParameterErrors errors = ErrorsFromJacobian(j, summary.residual_variance);
      covariance = errors.covariance;
      std::string names;
      bool stop_only = true;           // only the stop's parameters (d, k_s, c_s) are undetermined
      bool others_have_errors = true;  // and every other parameter has its error
      for (int i = 0; i < p; ++i) {
        if (errors.identifiable[i]) {
          others_have_errors = others_have_errors && std::isfinite(covariance(i, i));
          continue;
        }
        summary.unidentified.push_back(kParameterNames[i]);
        names += (names.empty() ? "" : ", ") + std::string(kParameterNames[i]);
        stop_only = stop_only && i >= kStop;
      }
      // A stop the records do not determine leaves the linear fit whole: the fit converges on the
      // others, as the broadband base fit leaves out a stop that earns nothing, and says what it left.
      stop_held = stop_only && !names.empty() && others_have_errors;
      if (stop_held) {
        const std::string why = "the stop's parameters (" + names +
                                ") are not identifiable from these records (no record's orbit depends on them): they"
                                " keep their staged values, which are not estimates";
        summary.report += "\n" + why;
        held_stop_warning = why;  // with the bound the orbits set on |d|, below
      } else {
        solved = false;
        summary.report += "\nNOT CONVERGED: the Jacobian is rank deficient (" +
                          (names.empty() ? std::string("parameters not all identifiable")
                                         : "not identifiable from these records: " + names) +
                          ")";
      }
    }
  }
  if (covariance.allFinite()) {
    // The chi-square as the fit defines it at theta', its corrections taken there (secant_covariance.h).
    const auto decode = [&](const double* at) { return layout.Decode(at); };
    auto chi2_at = [&](const std::vector<double>& at) -> std::optional<double> {
      const ActuatorModel model = layout.Decode(at.data());
      std::vector<double> chi2(targets.size(), kNaN);
      ParallelFor(targets.size(), [&](size_t i) {
        const RecordTarget& t = targets[i];
        try {
          const std::optional<ModelOrbit> orbit =
              SolveOrbit(model, *t.record, t.anchor, kind, orders, OrbitSearch::kNearby);
          if (!orbit) return;
          const internal::LinearisedCorrection correction =
              internal::LineariseCorrection(decode, at, *t.record, orbit->anchor, kind, orders, false);
          double sum = 0.0;
          for (int h = 0; h < orders; ++h)
            if (t.record->usable[h])
              sum += std::norm(t.weight * (t.record->harmonics[h] - orbit->harmonics[h] - correction.at[h]));
          chi2[i] = sum;
        } catch (const std::exception&) {
          // no steady state there: NaN
        }
      });
      double total = 0.0;
      for (double c : chi2) total += c;
      return std::isfinite(total) ? std::optional<double>(total) : std::nullopt;
    };
    const internal::SecantCovariance checked =
        internal::CheckCovarianceBySecants(covariance, summary.residual_variance, theta, chi2_at);
    covariance = checked.covariance;
    summary.secant_ratios = checked.ratios;
  }
  summary.converged = solved && (covariance.allFinite() || stop_held);

  result->model = layout.Decode(theta.data());
  for (int i = 0; i < p; ++i) {
    const double range = std::log(i >= kContactStiffness ? kContactRange : kParameterRange);
    if (std::abs(theta[i] - 1.0) > 0.999 * range) {
      summary.ended_on_bound = true;
      result->warnings.push_back(std::string(kParameterNames[i]) + " ended on its bound (a factor " +
                                 Format(std::exp(range)) +
                                 " from the staged estimate): the model does not fit these records");
    }
  }
  result->parameters =
      ReportParameters(layout, theta, covariance, result->model_kind, kind, result->absolute_scale,
                       evaluates ? "not identifiable from these records"
                                 : "no error: a record has no steady state at the end");

  // Every record at the fitted model, from its (updated) anchor, as its sampling sees it.
  for (size_t k = 0; k < used.size(); ++k) all[used[k]].anchor = targets[k].anchor;
  double mismatch_initial = 0.0, mismatch = 0.0, power = 0.0;
  for (size_t i = 0; i < analyses.size(); ++i) {
    const RecordAnalysis& a = analyses[i];
    RecordFit& f = fits[i];
    f.name = a.name;
    f.frequency_hz = a.drive.frequency_hz;
    f.amplitude_v = a.drive.amplitude_v;
    f.phase_rad = a.drive.phase_rad;
    f.nominal_frequency_hz = a.nominal_frequency_hz;
    f.nominal_amplitude_v = a.nominal_amplitude_v;
    f.clear = a.clear;
    f.spikes = a.spikes.size();
    double total = 0.0;
    for (const Spike& s : a.spikes) total += s.ContactTimeS();
    f.contact_time_s = a.spikes.empty() ? kNaN : total / static_cast<double>(a.spikes.size());
    f.distortion = a.distortion;
    f.noise_rms = a.noise_rms;
    f.hum_frequency_hz = a.hum_frequency_hz;
    f.hum_amplitude = a.hum_amplitude;
    f.response_periods = a.response_periods;
    f.frf = a.frf;
    f.used_refinement = std::find(used.begin(), used.end(), i) != used.end();
    std::optional<ModelOrbit> orbit;
    try {
      orbit = SolveOrbit(result->model, a, all[i].anchor, kind, orders, OrbitSearch::kAttractor);
    } catch (const NumericalError&) {
    }
    if (!orbit) {
      f.nrmse = f.chi2 = kNaN;
      result->warnings.push_back("record " + a.name + ": no steady state of the fitted model");
      continue;
    }
    std::vector<Complex> model_harmonics = orbit->harmonics;
    double variance = a.harmonic_se * a.harmonic_se;
    try {
      const internal::SampledCorrection correction = SamplingCorrection(result->model, a, *orbit, kind, orders);
      for (int h = 0; h < orders; ++h) model_harmonics[h] += correction.harmonics[h];
      variance = internal::HarmonicVariance(a, correction);
    } catch (const std::exception&) {
    }
    const double power_i = PowerOf(a), mismatch_i = MismatchSquared(a, model_harmonics);
    f.nrmse = std::sqrt(mismatch_i / power_i);
    f.chi2 = mismatch_i / variance / (2.0 * orders);
    f.model_period = orbit->anchor.period;
    f.model_contacts_per_period = orbit->contacts_per_period;
    f.model_harmonics = std::move(model_harmonics);
    if (stop_held && f.used_refinement) {
      // How far toward the held stop the record's fitted orbit goes, sampled on its own grid.
      for (double x : internal::OrbitOnRecordGrid(result->model, a, *orbit, ResponseKind::kDisplacement)) {
        const double toward_stop = result->model.HasLowerStop() ? -x : x;
        summary.largest_excursion_m = std::fmax(summary.largest_excursion_m, toward_stop);  // NaN until the first
      }
    }
    mismatch += mismatch_i;
    mismatch_initial += f.nrmse_initial * f.nrmse_initial * power_i;
    power += power_i;
  }
  if (stop_held) {
    // Any stop beyond the orbits leaves them as they are: the records bound |d| from below only.
    if (summary.largest_excursion_m > 0.0)
      held_stop_warning += "; the fitted orbits reach " + Format(summary.largest_excursion_m) +
                           " m toward the stop, so |d| is above that";
    result->warnings.push_back(held_stop_warning);
  }
  result->nrmse = std::sqrt(mismatch / power);
  result->nrmse_initial = std::sqrt(mismatch_initial / power);
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
}

}  // namespace strokelab
