// The defect-corrected refinement of extended_fit.h. Ceres stays in this file and fit.cc.
#include "strokelab/identify/extended_fit.h"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include "step_callback.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/parallel_for.h"

namespace strokelab::internal {
namespace {

using Complex = std::complex<double>;
constexpr double kInf = std::numeric_limits<double>::infinity();
// Relative step of Ceres' central differences in theta (as in fit.cc: ~1e-4 of each parameter).
constexpr double kNumericStep = 1e-4;
// Forward-difference step of the smooth terms' sensitivities S_j [theta units]: large enough that
// CVODE's tolerance (harmonics to ~1e-9 relative) is far below the change, small against curvature.
constexpr double kSensitivityStep = 0.02;
// Passes end when no theta moved by more than this between passes (theta ~ 1: a relative change of
// 1e-3 in a log-scaled parameter, a tenth or less of the standard errors seen in the tests; the
// fixed-point iteration's last steps shrink by ~2 per pass).
constexpr double kPassTolerance = 1e-3;
// Aitken extrapolation of the passes only for steps that shrink steadily (ratio in this range).
constexpr double kMinAitkenRatio = 0.3;
constexpr double kMaxAitkenRatio = 0.95;

// One record's target: its measured harmonics, the anchors the next evaluations start from, and the
// pass's frozen corrections.
struct Target {
  const RecordAnalysis* record = nullptr;
  double weight = 1.0;  // 1 / harmonic standard error
  Anchor surrogate_anchor, full_anchor;
  bool usable = true;                         // an orbit was found at the pass's start
  std::vector<Complex> correction;            // sampling correction + defect at theta0
  std::vector<std::vector<Complex>> slopes;   // S_j per smooth parameter (index into smooth_)
};

// Residuals (Re, Im) of w (C_h - C_model,h) for Ceres' central differences.
class DefectCost {
 public:
  DefectCost(const ExtendedProblem* problem, const std::vector<double>* theta0, const std::vector<int>* smooth,
             Target* target, ResponseKind kind, int orders)
      : problem_(problem), theta0_(theta0), smooth_(smooth), target_(target), kind_(kind), orders_(orders) {}

  bool operator()(double const* const* parameters, double* residual) const {
    const double* theta = parameters[0];
    try {
      if (!target_->usable) return false;
      const ActuatorModel surrogate = problem_->Surrogate(problem_->Decode(theta));
      const std::optional<ModelOrbit> orbit = SolveOrbit(surrogate, *target_->record, target_->surrogate_anchor,
                                                         kind_, orders_, OrbitSearch::kNearby);
      if (!orbit) return false;
      for (int h = 0; h < orders_; ++h) {
        Complex model = orbit->harmonics[h] + target_->correction[h];
        for (size_t j = 0; j < smooth_->size(); ++j) {
          const int p = (*smooth_)[j];
          model += target_->slopes[j][h] * (theta[p] - (*theta0_)[p]);
        }
        const double weight = target_->record->usable[h] ? target_->weight : 0.0;
        const Complex r = weight * (target_->record->harmonics[h] - model);
        residual[2 * h] = r.real();
        residual[2 * h + 1] = r.imag();
      }
      return true;
    } catch (const std::exception&) {
      return false;  // a model the engines refuse: Ceres rejects the step
    }
  }

 private:
  const ExtendedProblem* problem_;
  const std::vector<double>* theta0_;
  const std::vector<int>* smooth_;
  Target* target_;
  ResponseKind kind_;
  int orders_;
};

// The pass's frozen corrections at theta0 for one record (see the header's equation).
void Refresh(const ExtendedProblem& problem, const std::vector<double>& theta0, const std::vector<int>& smooth,
             ResponseKind kind, int orders, Target* t) {
  t->usable = false;
  const ActuatorModel full = problem.Decode(theta0.data());
  const ActuatorModel surrogate = problem.Surrogate(full);
  const std::optional<ModelOrbit> s =
      SolveOrbit(surrogate, *t->record, t->surrogate_anchor, kind, orders, OrbitSearch::kAttractor);
  if (!s) return;
  t->surrogate_anchor = s->anchor;
  t->correction = SamplingCorrection(surrogate, *t->record, *s, kind, orders);
  t->slopes.assign(smooth.size(), std::vector<Complex>(orders, 0.0));
  if (!smooth.empty()) {
    const std::optional<ModelOrbit> f = SolveOrbit(full, *t->record, t->full_anchor, kind, orders, OrbitSearch::kAttractor);
    if (!f) return;
    t->full_anchor = f->anchor;
    // The defect between two sampled orbits: the sampling's own error cancels.
    const std::vector<Complex> s_sampled = SampledOrbitHarmonics(surrogate, *t->record, s->anchor, kind, orders);
    for (int h = 0; h < orders; ++h) t->correction[h] += f->harmonics[h] - s_sampled[h];
    for (size_t j = 0; j < smooth.size(); ++j) {
      std::vector<double> shifted = theta0;
      shifted[smooth[j]] += kSensitivityStep;
      const ActuatorModel full_shifted = problem.Decode(shifted.data());
      const std::optional<ModelOrbit> g =
          SolveOrbit(full_shifted, *t->record, f->anchor, kind, orders, OrbitSearch::kNearby);
      if (!g) return;
      // A smooth term does not enter the surrogate: the defect's slope is the full model's.
      for (int h = 0; h < orders; ++h) t->slopes[j][h] = (g->harmonics[h] - f->harmonics[h]) / kSensitivityStep;
    }
  }
  t->usable = true;
}

}  // namespace

double FreeParameter::Value(double theta) const {
  return log_scale ? start * std::exp(theta - 1.0) : start + scale * (theta - 1.0);
}

double FreeParameter::StandardError(double theta, double theta_variance) const {
  const double se = std::sqrt(std::max(0.0, theta_variance));
  return log_scale ? std::abs(Value(theta)) * se : std::abs(scale) * se;
}

ActuatorModel ExtendedProblem::Decode(const double* theta) const {
  ActuatorModel m = base;
  for (size_t i = 0; i < parameters.size(); ++i) m.*(parameters[i].field) = parameters[i].Value(theta[i]);
  return m;
}

ActuatorModel ExtendedProblem::Surrogate(const ActuatorModel& full) const {
  ActuatorModel m = full;
  m.quadratic_stiffness_n_per_m2 = 0.0;
  m.cubic_stiffness_n_per_m3 = 0.0;
  m.friction_force_n = 0.0;
  if (m.contact_law == ContactLaw::kHertzian) {
    m.contact_law = ContactLaw::kLinear;
    m.contact_stiffness = surrogate_contact_stiffness;
  }
  return m;
}

std::optional<Prediction> Predict(const ActuatorModel& model, const ActuatorModel& surrogate,
                                  const RecordAnalysis& record, ResponseKind kind, int orders) {
  std::optional<ModelOrbit> s = BestMatchingOrbit(surrogate, record, kind, orders);
  if (!s) return std::nullopt;
  Prediction p;
  if (model.IsPiecewiseLinear()) {
    p.orbit = *s;
  } else {
    std::optional<ModelOrbit> f = SolveOrbit(model, record, s->anchor, kind, orders, OrbitSearch::kAttractor);
    if (!f) return std::nullopt;
    p.orbit = std::move(*f);
  }
  const std::vector<Complex> correction = SamplingCorrection(surrogate, record, *s, kind, orders);
  p.harmonics = p.orbit.harmonics;
  for (int h = 0; h < orders; ++h) p.harmonics[h] += correction[h];
  return p;
}

double Chi2At(std::span<const RecordAnalysis* const> records, ResponseKind kind, const ExtendedProblem& problem,
              const std::vector<double>& theta, int orders) {
  const ActuatorModel full = problem.Decode(theta.data());
  const ActuatorModel surrogate = problem.Surrogate(full);
  std::vector<double> chi2(records.size(), kInf);
  ParallelFor(records.size(), [&](size_t i) {
    try {
      if (const auto p = Predict(full, surrogate, *records[i], kind, orders))
        chi2[i] = MismatchSquared(*records[i], p->harmonics) /
                  (records[i]->harmonic_se * records[i]->harmonic_se);
    } catch (const std::exception&) {
    }
  });
  double sum = 0.0;
  for (double c : chi2) sum += c;
  return sum;
}

ExtendedFitResult FitExtended(std::span<const RecordAnalysis* const> records, ResponseKind kind,
                              const ExtendedProblem& problem, const ExtendedFitOptions& options) {
  const auto clock_start = std::chrono::steady_clock::now();
  const int p = static_cast<int>(problem.parameters.size()), orders = options.orders;
  ExtendedFitResult result;
  result.residuals = 2 * static_cast<size_t>(orders) * records.size();
  if (p == 0 || result.residuals <= static_cast<size_t>(p))
    throw InputError("records", "too few records for " + std::to_string(p) + " parameters");
  std::vector<int> smooth;  // the parameters of smooth terms, whose slopes the passes carry
  for (int i = 0; i < p; ++i)
    if (problem.parameters[i].smooth) smooth.push_back(i);

  std::vector<double> theta(p, 1.0), theta0 = theta;
  std::vector<Target> targets(records.size());
  {
    const ActuatorModel full = problem.Decode(theta.data());
    const ActuatorModel surrogate = problem.Surrogate(full);
    ParallelFor(records.size(), [&](size_t i) {
      Target& t = targets[i];
      t.record = records[i];
      t.weight = 1.0 / records[i]->harmonic_se;
      t.correction.assign(orders, 0.0);
      std::optional<ModelOrbit> s;
      try {
        s = BestMatchingOrbit(surrogate, *records[i], kind, orders);
      } catch (const std::exception&) {
      }
      if (!s) throw NumericalError("no steady state of the starting model at record " + records[i]->name);
      t.surrogate_anchor = t.full_anchor = s->anchor;
    });
  }

  ceres::Problem ceres_problem;
  for (Target& t : targets) {
    auto* cost = new ceres::DynamicNumericDiffCostFunction<DefectCost, ceres::CENTRAL>(
        new DefectCost(&problem, &theta0, &smooth, &t, kind, orders), ceres::TAKE_OWNERSHIP,
        [] {
          ceres::NumericDiffOptions diff;
          diff.relative_step_size = kNumericStep;
          return diff;
        }());
    cost->AddParameterBlock(p);
    cost->SetNumResiduals(2 * orders);
    ceres_problem.AddResidualBlock(cost, nullptr, theta.data());
  }
  for (int i = 0; i < p; ++i) {
    ceres_problem.SetParameterLowerBound(theta.data(), i, problem.parameters[i].theta_min);
    ceres_problem.SetParameterUpperBound(theta.data(), i, problem.parameters[i].theta_max);
  }

  // After each successful step the surrogate anchors move to the new iterate's orbits.
  AfterSuccessfulStep callback([&] {
    const ActuatorModel surrogate = problem.Surrogate(problem.Decode(theta.data()));
    ParallelFor(targets.size(),
                [&](size_t i) { MoveAnchor(surrogate, *targets[i].record, kind, orders, &targets[i].surrogate_anchor); });
  });
  ceres::Solver::Options solver = RefinementSolverOptions(options.max_iterations, &callback);
  const auto deadline = clock_start + std::chrono::duration<double>(options.max_seconds);

  auto refresh_all = [&] {
    theta0 = theta;
    ParallelFor(targets.size(), [&](size_t i) {
      try {
        Refresh(problem, theta0, smooth, kind, orders, &targets[i]);
      } catch (const std::exception&) {
        targets[i].usable = false;
      }
    });
  };
  // Each pass bounds the smooth parameters to their trust region around theta0.
  auto set_pass_bounds = [&] {
    for (int i = 0; i < p; ++i) {
      const FreeParameter& fp = problem.parameters[i];
      ceres_problem.SetParameterLowerBound(theta.data(), i, std::max(fp.theta_min, theta0[i] - fp.max_step));
      ceres_problem.SetParameterUpperBound(theta.data(), i, std::min(fp.theta_max, theta0[i] + fp.max_step));
    }
  };
  bool moved = true;
  std::vector<double> previous_step;
  std::vector<double> last_pass_start, last_pass_end;  // theta0 and theta of the last pass
  for (int pass = 0; pass < options.max_passes && moved; ++pass) {
    refresh_all();
    set_pass_bounds();
    const double seconds_left = std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
    if (seconds_left <= 0) {
      result.report = "time limit of " + std::to_string(options.max_seconds) + " s reached";
      break;
    }
    solver.max_solver_time_in_seconds = seconds_left;
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &ceres_problem, &summary);
    result.iterations += static_cast<int>(summary.iterations.size()) - 1;
    result.passes = pass + 1;
    result.report = summary.BriefReport();
    last_pass_start = theta0;
    last_pass_end = theta;
    double change = 0.0;
    for (int i = 0; i < p; ++i) change = std::max(change, std::abs(theta[i] - theta0[i]));
    moved = change > kPassTolerance;
    // The passes are a linear fixed-point iteration near the solution (their Jacobian is the
    // surrogate's): when successive steps shrink by a steady ratio r, jump to the limit of the
    // geometric series, theta + step r / (1 - r) (Aitken's delta-squared extrapolation).
    std::vector<double> step(p);
    for (int i = 0; i < p; ++i) step[i] = theta[i] - theta0[i];
    if (moved && !previous_step.empty()) {
      double num = 0.0, den = 0.0;
      for (int i = 0; i < p; ++i) num += step[i] * previous_step[i], den += previous_step[i] * previous_step[i];
      const double ratio = den > 0.0 ? num / den : 0.0;
      if (ratio > kMinAitkenRatio && ratio < kMaxAitkenRatio) {
        for (int i = 0; i < p; ++i) {
          const FreeParameter& fp = problem.parameters[i];
          theta[i] = std::clamp(theta[i] + step[i] * ratio / (1.0 - ratio), fp.theta_min, fp.theta_max);
        }
        step.clear();  // the next pass starts a new sequence
      }
    }
    previous_step = step;
    if (summary.termination_type == ceres::FAILURE || summary.termination_type == ceres::USER_FAILURE) break;
  }
  // The final corrections at the final theta: the prediction is then the full model's own.
  refresh_all();
  size_t unusable = static_cast<size_t>(
      std::count_if(targets.begin(), targets.end(), [](const Target& t) { return !t.usable; }));
  // The cost and whether the Jacobian can be evaluated at all: Ceres' covariance does not check
  // (a failed evaluation left it to run an SVD on an empty matrix and crash).
  double cost = 0.0;
  ceres::CRSMatrix jacobian;
  const bool evaluates =
      unusable == 0 && ceres_problem.Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, &jacobian);
  if (!evaluates) unusable = std::max<size_t>(unusable, 1);
  result.chi2 = unusable == 0 ? 2.0 * cost : kInf;
  result.residual_variance = result.chi2 / static_cast<double>(result.residuals - p);
  result.converged = !moved && unusable == 0;
  if (moved) result.report += "\nNOT CONVERGED: the parameters still moved after " + std::to_string(result.passes) + " passes";
  if (unusable > 0) result.report += "\nNOT CONVERGED: " + std::to_string(unusable) + " records without a steady state";

  Eigen::MatrixXd covariance = Eigen::MatrixXd::Constant(p, p, std::numeric_limits<double>::quiet_NaN());
  if (unusable == 0) {
    ceres::Covariance::Options covariance_options;
    covariance_options.algorithm_type = ceres::DENSE_SVD;
    ceres::Covariance cov(covariance_options);
    const double* block = theta.data();
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> c(p, p);
    if (cov.Compute(std::vector<const double*>{block}, &ceres_problem) &&
        cov.GetCovarianceBlock(block, block, c.data())) {
      covariance = result.residual_variance * Eigen::MatrixXd(c);
    } else {
      result.converged = false;
      result.report += "\nthe Jacobian is rank deficient (parameters not all identifiable)";
    }
  }
  result.theta = theta;
  result.model = problem.Decode(theta.data());
  for (int i = 0; i < p; ++i) {
    const FreeParameter& fp = problem.parameters[i];
    FitParameter out;
    out.name = fp.name;
    out.unit = fp.unit;
    out.value = fp.Value(theta[i]);
    out.standard_error = fp.StandardError(theta[i], covariance(i, i));
    if (std::abs(theta[i] - fp.theta_min) < 1e-6 || std::abs(theta[i] - fp.theta_max) < 1e-6)
      out.note = "on its bound";
    // Unconverged passes: the standard error does not hold the distance still to go, so say how far
    // the last pass moved the parameter, for the reader to set beside it.
    if (moved && !last_pass_end.empty() && std::abs(last_pass_end[i] - last_pass_start[i]) > kPassTolerance) {
      const double before = fp.Value(last_pass_start[i]), after = fp.Value(last_pass_end[i]);
      char text[120];
      int n = std::snprintf(text, sizeof text, "still moving: the last pass changed it by %+.2g %s", after - before,
                            fp.unit.c_str());
      if (before != 0.0 && n > 0 && n < static_cast<int>(sizeof text))
        std::snprintf(text + n, sizeof text - n, " (%+.2g %%)", 100.0 * (after - before) / std::abs(before));
      out.note += (out.note.empty() ? "" : "; ") + std::string(text);
    }
    result.parameters.push_back(out);
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return result;
}

}  // namespace strokelab::internal
