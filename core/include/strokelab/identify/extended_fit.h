// The refinement of a model extended by candidate effects (diagnose.h), with every base parameter
// free: Levenberg-Marquardt (Ceres) on the records' harmonics 1..N over their standard errors, as
// the fit's step 4 (fit.h), for any list of free parameters.
//
// Terms the closed-form engine cannot take (k2, k3, dry friction, Hertzian contact: "smooth" terms)
// would need CVODE at every evaluation, ~1000 times slower. Instead each evaluation uses the model's
// piecewise-linear stand-in (the surrogate: smooth terms removed, Hertzian contact replaced by a linear
// one) plus a defect correction refreshed once per outer pass at the pass's start theta0:
//
//   C_model(theta) = C_surrogate(theta) + [C_full(theta0) - C_surrogate(theta0)]
//                    + sum_j S_j (theta_j - theta0_j),     S_j = dC_full / dtheta_j at theta0
//
// over the smooth parameters j (forward differences on the full model). At theta = theta0 this is the
// full model's harmonics exactly, so passes are repeated until theta stops moving and the fixed point
// is a model whose own steady states (CVODE) are the prediction; the derivatives with respect to the
// base parameters are the surrogate's, which differ from the full model's by the effect's small share
// (defect correction; e.g. Deuflhard, "Newton Methods for Nonlinear Problems", Springer 2004, 1.4).
// Standard errors come from the last pass's Jacobian.
#pragma once

#include <complex>
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
  bool smooth = false;                      // a term the closed-form engine cannot take
  // Largest move of theta per defect-correction pass (smooth terms: their slope is exact only near
  // the pass's start, so the pass is a trust region around it) [theta units].
  double max_step = 1e300;
  double Value(double theta) const;
  double StandardError(double theta, double theta_variance) const;  // delta method
};

struct ExtendedProblem {
  ActuatorModel base;  // everything not free (contact law, stop sides, m_p, ...)
  std::vector<FreeParameter> parameters;
  // Linear contact stiffness of the surrogate when the model's contact is Hertzian [N/m].
  double surrogate_contact_stiffness = 0.0;
  ActuatorModel Decode(const double* theta) const;
  // The piecewise-linear stand-in of `full`: k2 = k3 = 0, no friction, linear contact.
  ActuatorModel Surrogate(const ActuatorModel& full) const;
};

struct ExtendedFitOptions {
  int orders = 10;         // harmonics N
  int max_passes = 8;      // defect-correction passes
  int max_iterations = 30; // Ceres iterations per pass
  double max_seconds = 120.0;
};

struct ExtendedFitResult {
  std::vector<double> theta;
  ActuatorModel model;
  std::vector<FitParameter> parameters;  // every free parameter with its standard error
  bool converged = false;
  int passes = 0, iterations = 0;
  double chi2 = 0.0;               // sum of squared residuals over the fit records, at the end
  size_t residuals = 0;            // M
  double residual_variance = 0.0;  // chi2 / (M - P)
  std::string report;              // why not converged
  double seconds = 0.0;
};

// Fits problem.parameters to `records` (their anchors found from the surrogate at the start).
ExtendedFitResult FitExtended(std::span<const RecordAnalysis* const> records, ResponseKind kind,
                              const ExtendedProblem& problem, const ExtendedFitOptions& options);

// sum_h |(C_h - C_h^model) / se|^2 of each record at the model `theta` of `problem` (no fitting),
// used to choose among start values. Records without a steady state count as +inf.
double Chi2At(std::span<const RecordAnalysis* const> records, ResponseKind kind, const ExtendedProblem& problem,
              const std::vector<double>& theta, int orders);

// The model's harmonics as a record's sampling sees them: the full model's steady state (started
// from the surrogate's best-matching stable orbit) plus the surrogate's sampling correction.
struct Prediction {
  ModelOrbit orbit;
  std::vector<std::complex<double>> harmonics;
};
std::optional<Prediction> Predict(const ActuatorModel& model, const ActuatorModel& surrogate,
                                  const RecordAnalysis& record, ResponseKind kind, int orders);

}  // namespace strokelab::internal
