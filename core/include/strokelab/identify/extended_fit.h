// The refinement of a model extended by candidate effects (diagnose.h), with every base parameter
// free: Levenberg-Marquardt (Ceres) on the records' harmonics 1..N over their standard errors, as
// the fit's step 4 (fit.h), for any list of free parameters.
//
// Every evaluation solves each record's periodic steady state of the full model (Newton from the
// record's anchor on the period map, engines/variational_flow.h for models that are not piecewise
// linear) and takes the residuals' Jacobian from the flow's exact sensitivities (fit_orbit.h,
// OrbitHarmonicSlopes): one nonlinear least-squares problem, converged when Ceres' own convergence
// test holds, with standard errors from the true Jacobian at the solution. The records' sampling
// correction (fit_orbit.h, SamplingCorrection: what a record's sampling makes of the model's response)
// is frozen during a solve and refreshed between solves, until the parameters stay or, for a model
// whose chi-square the records reject (beyond chi-square(M - P)'s 1e-3 upper tail), those passes are
// seen not to converge (PassesNotContracting); a model within noise whose last two solves moved it by
// no more than the corrections' jitter (JitterAllowance) has converged too. A converged fit the
// records reject may hold a record on the wrong one of two coexisting orbits (anchors are chosen at
// the starting model): records whose best-matching orbit of the fitted model matches them better by
// more than their own residual count in chi-square move there, and the passes go on.
#pragma once

#include <complex>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "strokelab/identify/fit_orbit.h"
#include "strokelab/identify/fit.h"
#include "strokelab/model/model.h"

namespace strokelab::internal {

// One free parameter. theta = 1 at `start`; value = start exp(theta - 1) on a log scale (the sign
// of start kept), start + scale (theta - 1) on a linear one.
struct FreeParameter {
  std::string name;  // as reported: "k_p", "k3", ...
  std::string unit;
  double ActuatorModel::*field = nullptr;
  bool log_scale = true;
  double start = 0.0;
  double scale = 1.0;                       // linear scale: [unit] per unit of theta
  double theta_min = 0.0, theta_max = 2.0;  // bounds on theta
  double Value(double theta) const;
  double ValuePerTheta(double theta) const;  // d Value / d theta
  double StandardError(double theta, double theta_variance) const;  // delta method
  // Its name, unit, value and standard error (NaN: not identifiable) at theta.
  FitParameter Reported(double theta, double theta_variance) const;
};

// Log-scaled from `start`, within a factor `range` either way.
FreeParameter LogParameter(std::string name, std::string unit, double ActuatorModel::*field, double start,
                           double range);
// value = start + scale (theta - 1), theta in [1 + low, 1 + high].
FreeParameter LinearParameter(std::string name, std::string unit, double ActuatorModel::*field, double start,
                              double scale, double low, double high);

struct ExtendedProblem {
  ActuatorModel base;  // everything not free (contact law, stop sides, m_p, ...)
  std::vector<FreeParameter> parameters;
  ActuatorModel Decode(const double* theta) const;
};

struct ExtendedFitOptions {
  int orders = 10;         // harmonics N
  int max_passes = 8;      // solves, each with the sampling corrections refreshed at its start
  int max_iterations = 100; // Ceres iterations per solve (the cubic fits of campaign-a and a 72-record campaign need 20-60)
  double max_seconds = 120.0;
  // Reporting only: called at the start of each solve (iteration 0) and after each successful Ceres
  // step within it (iteration 1, 2, ...), from the calling thread; may be empty.
  std::function<void(int solve, int iteration)> progress;
  // A parameter whose lower bound is a floor of the search rather than of the physics (the coil's
  // tau_e: below it the flow's steps follow tau_e): the fit first looks at the model with it on that
  // bound, and where a Gauss-Newton step from there (every parameter free) lowers it further, the
  // records ask for less of it than the floor, and the fit stops there (ExtendedFitResult::floored).
  // -1: none.
  int floor_probe = -1;
};

struct ExtendedFitResult {
  std::vector<double> theta;
  ActuatorModel model;
  std::vector<FitParameter> parameters;  // every free parameter with its standard error
  // Covariance of their values (row-major, P x P, units of the two parameters): the standard errors'
  // matrix. NaN in the rows and columns of a parameter held at a bound or not identifiable.
  std::vector<double> covariance;
  bool converged = false;
  int passes = 0, iterations = 0;
  double chi2 = 0.0;               // sum of squared residuals over the fit records, at the end
  size_t residuals = 0;            // M
  double residual_variance = 0.0;  // chi2 / (M - P)
  std::string report;              // why not converged
  // Converged with the sampling corrections' jitter (JitterAllowance): the last moves; else empty.
  std::string jitter;
  // Stopped at the floor of options.floor_probe (not converged, that parameter held there): why, with
  // the Gauss-Newton step's target; else empty.
  std::string floored;
  double seconds = 0.0;
};

// Whether refreshing the sampling corrections between solves is a contraction that can bring the
// parameters' move below FitExtended's tolerance (0.01 standard errors) within `passes_left` more
// solves. It is the divergence test of the simplified Newton iterations in E. Hairer and G. Wanner,
// "Solving Ordinary Differential Equations II", 2nd ed., Springer 1996, Sec. IV.8 (stopping criterion), with
// theta = move / last_move the ratio of successive moves (each the largest over the identifiable
// parameters, in their standard errors): moves that grow (theta >= 1), or that shrink too slowly to
// fall below the tolerance in the solves left (theta^left / (1 - theta) move > tolerance), will not
// converge. A candidate whose orbits jump between attractors as its parameters move (physics the
// records do not show) behaves so, and more solves only shuffle it. A model within noise can show one
// such jump near its optimum (a record's orbit switching) and still converge after it, so the test is
// applied to models beyond noise only. Empty when the passes may go on;
// otherwise why they stop, with the two moves.
std::string PassesNotContracting(double move, double last_move, int passes_left);

// The largest move between solves, in standard errors, that is jitter of the sampling corrections
// rather than a fit still on its way, for a model within noise whose passes all ran: a parameter that
// jitters by delta standard errors has the error sqrt(1 + delta^2) of one, and delta is allowed while
// that excess stays below the standard error's own relative uncertainty from `dof` degrees of freedom,
// 1 / sqrt(2 dof) (the chi-square's: a variance estimate from dof residuals): delta = sqrt((1 +
// 1 / sqrt(2 dof))^2 - 1), 0.28 at dof 350.
double JitterAllowance(size_t dof);

// Whether a fit's chi-square of `dof` = M - P degrees of freedom is beyond noise (upper-tail
// probability below 1e-3): the records reject the model. Such a fit's passes may stop once they stop
// converging.
bool BeyondNoise(double chi2, size_t dof);

// Fits problem.parameters to `records` (their anchors: each record's best-matching orbit at the start).
ExtendedFitResult FitExtended(std::span<const RecordAnalysis* const> records, ResponseKind kind,
                              const ExtendedProblem& problem, const ExtendedFitOptions& options);

// sum_h |(C_h - C_h^model) / se|^2 of each record at the model `theta` of `problem` (no fitting),
// used to choose among start values. Records without a steady state count as +inf.
double Chi2At(std::span<const RecordAnalysis* const> records, ResponseKind kind, const ExtendedProblem& problem,
              const std::vector<double>& theta, int orders);

// The model's harmonics as a record's sampling sees them: the model's best-matching stable orbit
// (fit_orbit.h, BestMatchingOrbit) plus its sampling correction.
struct Prediction {
  ModelOrbit orbit;
  std::vector<std::complex<double>> harmonics;
  double variance = 0.0;  // of Re and Im of each harmonic: the record's noise and the sampling's jitter
};
std::optional<Prediction> Predict(const ActuatorModel& model, const RecordAnalysis& record, ResponseKind kind,
                                  int orders);

}  // namespace strokelab::internal
