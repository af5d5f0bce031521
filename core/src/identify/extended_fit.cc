// The refinement of extended_fit.h: one Ceres problem over every record's harmonics, with the
// residuals' Jacobian from the variational flow's exact sensitivities. Ceres stays in this file and fit.cc.
#include "strokelab/identify/extended_fit.h"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include "orbit_cost.h"
#include "step_callback.h"
#include "strokelab/base/chi_square.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/nan.h"
#include "strokelab/base/parallel_for.h"
#include "strokelab/identify/sparse_covariance.h"
#include "strokelab/steady/steady_state.h"

namespace strokelab::internal {

bool BeyondNoise(double chi2, size_t dof) {
  // Beyond this upper-tail probability of chi-square(dof) the residuals are not noise.
  constexpr double kBeyondNoiseP = 1e-3;
  return chi2 > ChiSquareQuantile(kBeyondNoiseP, static_cast<double>(dof));
}

namespace {

using Complex = std::complex<double>;

// Moves the anchor of each record whose best-matching orbit at `model` (BestMatchingOrbit) matches it
// better than its anchor's orbit by more than the record's own expected chi-square (its residual
// count): a difference noise does not make. Returns how many moved.
size_t ReAnchor(const ActuatorModel& model, std::vector<OrbitTarget>& targets, ResponseKind kind, int orders) {
  std::atomic<size_t> moved = 0;
  ParallelFor(targets.size(), [&](size_t i) {
    OrbitTarget& t = targets[i];
    try {
      const std::optional<ModelOrbit> now = SolveOrbit(model, *t.record, t.anchor, kind, orders, OrbitSearch::kNearby);
      const std::optional<ModelOrbit> best = BestMatchingOrbit(model, *t.record, kind, orders);
      if (!now || !best) return;
      const double gain_chi2 =
          (MismatchSquared(*t.record, now->harmonics) - MismatchSquared(*t.record, best->harmonics)) * t.weight * t.weight;
      if (gain_chi2 > static_cast<double>(FittedResiduals(*t.record, orders))) {
        t.anchor = best->anchor;
        ++moved;
      }
    } catch (const std::exception&) {
      // keep the anchor
    }
  });
  return moved;
}

bool OnBound(const FreeParameter& p, double theta) {
  return std::abs(theta - p.theta_min) < 1e-6 || std::abs(theta - p.theta_max) < 1e-6;
}

// Ceres' Jacobian in every parameter. Ceres gives it in the free parameters only (a held one's column
// is left out): the columns not held, in order; a held one's column is zero here.
Eigen::MatrixXd DenseColumns(const ceres::CRSMatrix& crs, const std::vector<bool>& held) {
  std::vector<int> column;
  for (size_t i = 0; i < held.size(); ++i)
    if (!held[i]) column.push_back(static_cast<int>(i));
  Eigen::MatrixXd j = Eigen::MatrixXd::Zero(crs.num_rows, static_cast<Eigen::Index>(held.size()));
  for (int r = 0; r < crs.num_rows; ++r)
    for (int k = crs.rows[r]; k < crs.rows[r + 1]; ++k) j(r, column[crs.cols[k]]) = crs.values[k];
  return j;
}

// The Jacobian in every parameter with a zero column for each one held or on a bound (the errors of
// the others are then those with it fixed there).
Eigen::MatrixXd DenseJacobian(const ceres::CRSMatrix& crs, const std::vector<bool>& held, const ExtendedProblem& problem,
                              const std::vector<double>& theta) {
  Eigen::MatrixXd j = DenseColumns(crs, held);
  for (size_t i = 0; i < held.size(); ++i)
    if (OnBound(problem.parameters[i], theta[i])) j.col(static_cast<Eigen::Index>(i)).setZero();
  return j;
}

// Where a Gauss-Newton step from `theta`, every parameter free, takes parameter i: -J^+ r, the
// minimum-norm least-squares step of the column-scaled Jacobian (a column of zeros stays zero), from
// the residuals r and their Jacobian J at theta.
double GaussNewtonTarget(const std::vector<double>& residuals, const ceres::CRSMatrix& crs,
                         const std::vector<double>& theta, int i) {
  Eigen::MatrixXd j = DenseColumns(crs, std::vector<bool>(theta.size(), false));  // nothing held yet
  const Eigen::VectorXd norms = j.colwise().norm();
  for (Eigen::Index c = 0; c < j.cols(); ++c)
    if (norms(c) > 0.0) j.col(c) /= norms(c);
  const Eigen::Map<const Eigen::VectorXd> r(residuals.data(), static_cast<Eigen::Index>(residuals.size()));
  const Eigen::VectorXd step = j.completeOrthogonalDecomposition().solve(-r);
  return theta[i] + (norms(i) > 0.0 ? step(i) / norms(i) : 0.0);
}

}  // namespace

FreeParameter LogParameter(std::string name, std::string unit, double ActuatorModel::*field, double start,
                           double range) {
  FreeParameter p;
  p.name = std::move(name);
  p.unit = std::move(unit);
  p.field = field;
  p.log_scale = true;
  p.start = start;
  p.theta_min = 1.0 - std::log(range);
  p.theta_max = 1.0 + std::log(range);
  return p;
}

FreeParameter LinearParameter(std::string name, std::string unit, double ActuatorModel::*field, double start,
                              double scale, double low, double high) {
  FreeParameter p;
  p.name = std::move(name);
  p.unit = std::move(unit);
  p.field = field;
  p.log_scale = false;
  p.start = start;
  p.scale = scale;
  p.theta_min = 1.0 + low;
  p.theta_max = 1.0 + high;
  return p;
}

FitParameter FreeParameter::Reported(double theta, double theta_variance) const {
  FitParameter out;
  out.name = name;
  out.unit = unit;
  out.value = Value(theta);
  out.standard_error = StandardError(theta, theta_variance);
  return out;
}

double FreeParameter::Value(double theta) const {
  return log_scale ? start * std::exp(theta - 1.0) : start + scale * (theta - 1.0);
}

double FreeParameter::ValuePerTheta(double theta) const { return log_scale ? Value(theta) : scale; }

double FreeParameter::StandardError(double theta, double theta_variance) const {
  if (!(theta_variance >= 0.0)) return std::numeric_limits<double>::quiet_NaN();  // not identifiable
  const double se = std::sqrt(theta_variance);
  return log_scale ? std::abs(Value(theta)) * se : std::abs(scale) * se;
}

// Hairer & Wanner's test of a simplified Newton iteration (extended_fit.h), with the solves' moves.
std::string PassesNotContracting(double move, double last_move, int passes_left) {
  const double ratio = move / last_move;
  char moves[96];
  std::snprintf(moves, sizeof moves, "(moves of %.3g then %.3g standard errors)", last_move, move);
  if (ratio >= 1.0) return std::string("the passes stopped: they do not contract ") + moves;
  if (std::pow(ratio, passes_left) / (1.0 - ratio) * move > kSolveTolerancePerError)
    return "the passes stopped: they contract too slowly to settle in the " + std::to_string(passes_left) +
           " solves left " + moves;
  return "";
}

double JitterAllowance(size_t dof) {
  const double excess = 1.0 / std::sqrt(2.0 * static_cast<double>(std::max<size_t>(dof, 1)));
  return std::sqrt((1.0 + excess) * (1.0 + excess) - 1.0);
}

ActuatorModel ExtendedProblem::Decode(const double* theta) const {
  ActuatorModel m = base;
  for (size_t i = 0; i < parameters.size(); ++i) m.*(parameters[i].field) = parameters[i].Value(theta[i]);
  return m;
}

std::optional<Prediction> Predict(const ActuatorModel& model, const RecordAnalysis& record, ResponseKind kind,
                                  int orders) {
  std::optional<ModelOrbit> orbit = BestMatchingOrbit(model, record, kind, orders);
  if (!orbit) return std::nullopt;
  Prediction p;
  p.orbit = std::move(*orbit);
  const SampledCorrection correction = SamplingCorrection(model, record, p.orbit, kind, orders);
  p.harmonics = p.orbit.harmonics;
  for (int h = 0; h < orders; ++h) p.harmonics[h] += correction.harmonics[h];
  p.variance = HarmonicVariance(record, correction);
  return p;
}

double Chi2At(std::span<const RecordAnalysis* const> records, ResponseKind kind, const ExtendedProblem& problem,
              const std::vector<double>& theta, int orders) {
  const ActuatorModel full = problem.Decode(theta.data());
  std::vector<double> chi2(records.size(), kInf);
  ParallelFor(records.size(), [&](size_t i) {
    try {
      if (const auto p = Predict(full, *records[i], kind, orders))
        chi2[i] = MismatchSquared(*records[i], p->harmonics) / (records[i]->harmonic_se * records[i]->harmonic_se);
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
  result.residuals = 0;
  for (const RecordAnalysis* r : records) result.residuals += FittedResiduals(*r, orders);
  if (p == 0 || result.residuals <= static_cast<size_t>(p))
    throw InputError("records", "too few records for " + std::to_string(p) + " parameters");

  std::vector<double> theta(p, 1.0);
  std::vector<OrbitTarget> targets(records.size());
  // Anchors: the orbit that matches each record best among the attractors of the model at theta.
  auto anchor = [&] {
    const ActuatorModel model = problem.Decode(theta.data());
    ParallelFor(records.size(), [&](size_t i) {
      OrbitTarget& t = targets[i];
      t.record = records[i];
      t.weight = 1.0 / records[i]->harmonic_se;
      std::optional<ModelOrbit> s;
      try {
        s = BestMatchingOrbit(model, *records[i], kind, orders);
      } catch (const std::exception&) {
      }
      if (!s) throw NumericalError("no steady state of the starting model at record " + records[i]->name);
      t.anchor = s->anchor;
    });
  };

  ceres::Problem ceres_problem;
  for (OrbitTarget& t : targets) ceres_problem.AddResidualBlock(new OrbitCost(&problem, &t, kind, orders), nullptr, theta.data());
  for (int i = 0; i < p; ++i) {
    ceres_problem.SetParameterLowerBound(theta.data(), i, problem.parameters[i].theta_min);
    ceres_problem.SetParameterUpperBound(theta.data(), i, problem.parameters[i].theta_max);
  }
  double probe_cost = 0.0;  // at the probe, which is the end where the fit stops there
  ceres::CRSMatrix probe_jacobian;
  bool probe_evaluates = false;
  if (options.floor_probe >= 0) {
    const int i = options.floor_probe;
    const FreeParameter& fp = problem.parameters[i];
    theta[i] = fp.theta_min;
    anchor();
    RefreshCorrections(problem.Decode(theta.data()), targets, kind, orders);
    std::vector<double> residuals;
    probe_evaluates = ceres_problem.Evaluate(ceres::Problem::EvaluateOptions(), &probe_cost, &residuals, nullptr,
                                             &probe_jacobian);
    const double target = probe_evaluates ? GaussNewtonTarget(residuals, probe_jacobian, theta, i) : kNaN;
    if (target < fp.theta_min) {
      char values[160];
      std::snprintf(values, sizeof values,
                    "at its floor, %.3g %s, a Gauss-Newton step (every parameter free) takes it to %.3g %s",
                    fp.Value(fp.theta_min), fp.unit.c_str(), fp.Value(target), fp.unit.c_str());
      result.floored = "the records ask for less " + fp.name + " than its floor (" + values + "): not fitted beyond it";
    } else {
      theta[i] = 1.0;
    }
  }
  if (result.floored.empty()) anchor();
  // After each successful step the anchors move to the new iterate's orbits (and stay on each
  // record's branch).
  int solve_now = 0, steps_now = 0;  // for options.progress
  AfterSuccessfulStep callback([&] {
    const ActuatorModel model = problem.Decode(theta.data());
    ParallelFor(targets.size(), [&](size_t i) { MoveAnchor(model, *targets[i].record, kind, orders, &targets[i].anchor); });
    if (options.progress) options.progress(solve_now, ++steps_now);
  });
  ceres::Solver::Options solver = RefinementSolverOptions(options.max_iterations, &callback);
  const auto deadline = clock_start + std::chrono::duration<double>(options.max_seconds);

  // The sampling corrections depend on theta a little; they are frozen during a solve (its objective
  // stays one function for Ceres' convergence test) and refreshed between solves until theta stays.
  // A parameter the records push against its bound is held there: Ceres projects its steps onto the
  // bounds, so its quadratic model keeps predicting a descent the projection takes away, and the
  // trust region shrinks to crawl along the bound until the iterations run out (an amplifier limit
  // or a contact stiffness at the edge of its range). A solve that runs out of iterations holds the
  // parameters it left on a bound and is followed by another solve.
  std::vector<bool> held(p, false);
  bool ceres_converged = false, moved = true;
  double last_move = kInf;  // the previous solve's move (infinite before a comparable one)
  double move_before_last = kInf;  // the one before it
  double last_chi2 = kInf;  // the last solve's chi-square (its sampling corrections frozen)
  std::string not_contracting;
  auto run_passes = [&] {
    moved = true;
    last_move = move_before_last = kInf;
    for (int solve = result.passes; solve < options.max_passes && moved; ++solve) {
      RefreshCorrections(problem.Decode(theta.data()), targets, kind, orders);
      const double seconds_left = std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
      if (seconds_left <= 0) {
        result.report = "time limit of " + std::to_string(options.max_seconds) + " s reached";
        ceres_converged = false;
        break;
      }
      solver.max_solver_time_in_seconds = seconds_left;
      solve_now = solve + 1, steps_now = 0;
      if (options.progress) options.progress(solve_now, 0);
      const std::vector<double> before = theta;
      ceres::Solver::Summary summary;
      ceres::Solve(solver, &ceres_problem, &summary);
      result.iterations += static_cast<int>(summary.iterations.size()) - 1;
      result.passes = solve + 1;
      result.report = summary.BriefReport();
      ceres_converged = summary.termination_type == ceres::CONVERGENCE;
      if (summary.termination_type == ceres::NO_CONVERGENCE) {
        std::vector<int> constant;
        bool newly_held = false;
        for (int i = 0; i < p; ++i) {
          if (!held[i] && OnBound(problem.parameters[i], theta[i])) held[i] = newly_held = true;
          if (held[i]) constant.push_back(i);
        }
        if (!newly_held || constant.size() == static_cast<size_t>(p)) break;
        ceres_problem.SetManifold(theta.data(), new ceres::SubsetManifold(p, constant));
        last_move = move_before_last = kInf;  // another problem: its moves are not compared with this one's
        continue;
      }
      if (!ceres_converged) break;
      ceres::CRSMatrix jacobian;
      double cost = 0.0;
      if (!ceres_problem.Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, &jacobian)) break;
      const double variance = 2.0 * cost / static_cast<double>(result.residuals - p);
      const ParameterErrors errors = ErrorsFromJacobian(DenseJacobian(jacobian, held, problem, theta), variance);
      double move = 0.0;  // the largest move of an identifiable theta, in its standard errors
      for (int i = 0; i < p; ++i)
        if (errors.identifiable[i])
          move = std::max(move, std::abs(theta[i] - before[i]) / std::sqrt(errors.covariance(i, i)));
      moved = move > kSolveTolerancePerError;
      // Only a model the records reject may be given up on: where the chi-square is noise's, the
      // parameters and their standard errors are the answer, and every pass is run for them.
      last_chi2 = 2.0 * summary.final_cost;
      if (moved && BeyondNoise(last_chi2, result.residuals - p) && std::isfinite(last_move)) {
        const std::string why = PassesNotContracting(move, last_move, options.max_passes - (solve + 1));
        if (!why.empty()) {
          not_contracting = why;
          break;
        }
      }
      move_before_last = last_move;
      last_move = move;
    }
  };
  if (result.floored.empty()) run_passes();
  // A converged fit the records still reject may hold a record on the wrong one of two coexisting
  // orbits (its anchor was chosen at the starting model): records move to a better-matching orbit of
  // the fitted model, and the passes go on from there.
  if (ceres_converged && !moved && BeyondNoise(last_chi2, result.residuals - p)) {
    if (const size_t moved_anchors = ReAnchor(problem.Decode(theta.data()), targets, kind, orders)) {
      run_passes();  // it rewrites the report with its last solve's
      result.report += "\n" + std::to_string(moved_anchors) +
                       " record(s) moved to an orbit of the fitted model that matches them better";
    }
  }
  // A model within noise runs every pass; where its last two solves still moved the parameters, but
  // by no more than the corrections' jitter (JitterAllowance), it has converged as far as its errors
  // can tell (gen2 9906: moves of 0.031 then 0.055 standard errors after 8 solves).
  const size_t dof = result.residuals - static_cast<size_t>(p);
  if (ceres_converged && moved && not_contracting.empty() && !BeyondNoise(last_chi2, dof) &&
      std::max(last_move, move_before_last) <= JitterAllowance(dof)) {
    moved = false;
    char moves[160];
    std::snprintf(moves, sizeof moves, "moves of %.3g then %.3g standard errors, within the jitter of %.3g",
                  move_before_last, last_move, JitterAllowance(dof));
    result.jitter = "the sampling corrections still moved the parameters after " + std::to_string(result.passes) +
                    " solves, by no more than their jitter (" + moves + ")";
  }
  // The cost and the Jacobian at the end (a record without a steady state leaves neither).
  double cost = probe_cost;
  ceres::CRSMatrix jacobian = probe_jacobian;
  const bool evaluates = result.floored.empty() ? ceres_problem.Evaluate(ceres::Problem::EvaluateOptions(), &cost,
                                                                         nullptr, nullptr, &jacobian)
                                                : probe_evaluates;
  result.chi2 = evaluates ? 2.0 * cost : kInf;
  result.residual_variance = result.chi2 / static_cast<double>(result.residuals - p);
  result.converged = ceres_converged && !moved && evaluates;
  if (!result.floored.empty()) result.report = "NOT FITTED: " + result.floored;
  else if (!ceres_converged) result.report += "\nNOT CONVERGED: Ceres did not meet its convergence test";
  else if (moved) result.report += "\nNOT CONVERGED: the sampling corrections still moved the parameters after " +
                                   std::to_string(result.passes) + " solves" +
                                   (not_contracting.empty() ? "" : "; " + not_contracting);
  if (!evaluates) result.report += "\nNOT CONVERGED: a record has no steady state at the end";

  ParameterErrors errors{Eigen::MatrixXd::Constant(p, p, std::numeric_limits<double>::quiet_NaN()),
                         std::vector<bool>(p, false)};
  if (evaluates) errors = ErrorsFromJacobian(DenseJacobian(jacobian, held, problem, theta), result.residual_variance);
  // A parameter the solve left on a bound is reported as held there, as one the loop held.
  for (int i = 0; i < p; ++i) held[i] = held[i] || OnBound(problem.parameters[i], theta[i]);
  std::string unidentified, on_bound;
  for (int i = 0; i < p; ++i) {
    if (held[i]) on_bound += (on_bound.empty() ? "" : ", ") + problem.parameters[i].name;
    else if (evaluates && !errors.identifiable[i]) unidentified += (unidentified.empty() ? "" : ", ") + problem.parameters[i].name;
  }
  if (!on_bound.empty()) result.report += "\nheld at a bound of its range (the records push it beyond): " + on_bound;
  if (!unidentified.empty()) {
    result.converged = false;
    result.report += "\nNOT IDENTIFIABLE from these records: " + unidentified;
  }
  result.theta = theta;
  result.model = problem.Decode(theta.data());
  for (int i = 0; i < p; ++i) {
    const FreeParameter& fp = problem.parameters[i];
    FitParameter out = fp.Reported(theta[i], errors.covariance(i, i));
    out.identifiable = errors.identifiable[i] && !held[i];
    if (held[i]) out.note = "held at a bound of its range (the records push it beyond): no standard error";
    else if (!out.identifiable) out.note = "not identifiable from these records";
    result.parameters.push_back(out);
  }
  result.covariance.assign(static_cast<size_t>(p) * p, std::numeric_limits<double>::quiet_NaN());
  for (int i = 0; i < p; ++i)
    for (int j = 0; j < p; ++j)
      if (result.parameters[i].identifiable && result.parameters[j].identifiable)
        result.covariance[static_cast<size_t>(i) * p + j] = problem.parameters[i].ValuePerTheta(theta[i]) *
                                                            problem.parameters[j].ValuePerTheta(theta[j]) *
                                                            errors.covariance(i, j);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return result;
}

}  // namespace strokelab::internal
