// Least-squares fit of paper Eq. 3 to a first-order force-voltage FRF, with Ceres.
//
//   H_mod(w) = -g w^2 / (w_p^2 + j 2 zeta_p w_p w - w^2)                        (paper Eq. 3)
//
// Properties of Eq. 3 used below (for g > 0):
//   - low frequency:  H -> -g w^2 / w_p^2 (phase 180 deg); high frequency: H -> +g (phase 0).
//   - at w = w_p:     H = j g / (2 zeta_p), purely imaginary (phase +90 deg), and
//                     Re H = -g w^2 (w_p^2 - w^2) / |D|^2 changes sign exactly at w_p,
//                     whatever the damping.
//   - H is linear in g for fixed (w_p, zeta_p), and H D = -g w^2 is linear in
//     (w_p^2, 2 zeta_p w_p, g): both give closed-form starting values.
//
// The fitted parameters are theta = (ln w_p, ln zeta_p, g): the logarithms keep w_p and zeta_p
// positive without bounds, and make the problem better scaled (w_p ~ 1e2, zeta_p ~ 1e-1).
#include "strokelab/identify/frf_fit.h"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <sstream>
#include <vector>

#include "strokelab/base/errors.h"

namespace strokelab {
namespace {

constexpr int kNumParameters = 3;  // ln w_p, ln zeta_p, g
enum FrfParameter { kFrfLogNaturalFrequency = 0, kFrfLogDampingRatio = 1, kFrfGain = 2 };

std::string FormatDouble(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

// One sample in the units the fit uses.
struct Point {
  double omega_rad_s;
  std::complex<double> h;  // [N/V]
  double weight;           // 1/|H_meas| for relative residuals, else 1 [V/N or dimensionless]
};

std::vector<Point> ValidatedPoints(std::span<const FrfSample> samples, const FrfFitOptions& options) {
  if (samples.size() < kNumParameters)
    throw InputError("samples", "need at least 3 samples to fit w_p, zeta_p and g, got " +
                                    std::to_string(samples.size()));
  std::vector<Point> points;
  points.reserve(samples.size());
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const FrfSample& s = samples[i];
    const std::string field = "samples[" + std::to_string(i) + "]";
    if (!std::isfinite(s.frequency_hz) || s.frequency_hz <= 0)
      throw InputError(field + ".frequency_hz", "must be a finite number > 0, got " + FormatDouble(s.frequency_hz));
    if (!std::isfinite(s.h.real()) || !std::isfinite(s.h.imag()))
      throw InputError(field + ".h", "must be finite, got (" + FormatDouble(s.h.real()) + ", " +
                                         FormatDouble(s.h.imag()) + ")");
    if (std::abs(s.h) == 0) throw InputError(field + ".h", "must be non-zero (no response measured?)");
    const double weight = options.relative_residuals ? 1.0 / std::abs(s.h) : 1.0;
    points.push_back({2 * std::numbers::pi * s.frequency_hz, s.h, weight});
  }
  return points;
}

// Paper Eq. 3 in real arithmetic, for doubles and Ceres jets alike.
template <typename T>
void ModelEq3(const T& natural_frequency_rad_s, const T& damping_ratio, const T& gain_n_per_v, double omega_rad_s,
              T* re, T* im) {
  const double w2 = omega_rad_s * omega_rad_s;
  const T d_re = natural_frequency_rad_s * natural_frequency_rad_s - w2;
  const T d_im = 2.0 * damping_ratio * natural_frequency_rad_s * omega_rad_s;
  const T numerator = -gain_n_per_v * w2;
  const T d_abs2 = d_re * d_re + d_im * d_im;
  // N / D = N conj(D) / |D|^2
  *re = numerator * d_re / d_abs2;
  *im = -numerator * d_im / d_abs2;
}

// Two residuals per sample: real and imaginary parts of weight * (H_meas - H_mod).
struct Eq3Residual {
  Point point;

  template <typename T>
  bool operator()(const T* theta, T* residual) const {
    const T natural_frequency_rad_s = exp(theta[kFrfLogNaturalFrequency]);
    const T damping_ratio = exp(theta[kFrfLogDampingRatio]);
    T re, im;
    ModelEq3(natural_frequency_rad_s, damping_ratio, theta[kFrfGain], point.omega_rad_s, &re, &im);
    residual[0] = point.weight * (point.h.real() - re);
    residual[1] = point.weight * (point.h.imag() - im);
    return true;
  }
};

struct Estimate {
  double natural_frequency_rad_s;
  double damping_ratio;
  double gain_n_per_v;
};

// Sum of squared (weighted) residuals of Eq. 3 at one estimate.
double SumOfSquares(const std::vector<Point>& points, const Estimate& e) {
  double ssr = 0;
  for (const Point& p : points) {
    double re, im;
    ModelEq3(e.natural_frequency_rad_s, e.damping_ratio, e.gain_n_per_v, p.omega_rad_s, &re, &im);
    ssr += std::norm(p.weight * (p.h - std::complex<double>(re, im)));
  }
  return ssr;
}

// For fixed (w_p, zeta_p), Eq. 3 is H = g S(w) with S = -w^2 / D: the weighted least-squares g
// is sum wt^2 Re(conj(S) H) / sum wt^2 |S|^2.
double BestGain(const std::vector<Point>& points, double natural_frequency_rad_s, double damping_ratio) {
  double num = 0, den = 0;
  for (const Point& p : points) {
    double re, im;
    ModelEq3(natural_frequency_rad_s, damping_ratio, 1.0, p.omega_rad_s, &re, &im);
    const std::complex<double> shape(re, im);
    const double wt2 = p.weight * p.weight;
    num += wt2 * (std::conj(shape) * p.h).real();
    den += wt2 * std::norm(shape);
  }
  return num / den;
}

bool IsPhysical(const Estimate& e) {
  return std::isfinite(e.natural_frequency_rad_s) && e.natural_frequency_rad_s > 0 && std::isfinite(e.damping_ratio) &&
         e.damping_ratio > 0 && std::isfinite(e.gain_n_per_v) && e.gain_n_per_v != 0;
}

// Start 1: Eq. 3 multiplied out, H (a + j w b) + g w^2 = H w^2 with a = w_p^2, b = 2 zeta_p w_p,
// is linear in (a, b, g) (Levy's method). Each equation is divided by w^2 |H| and, after the
// first pass, by |D| of the previous pass (Sanathanan-Koerner), so that it approximates the
// relative residual of Eq. 3. Exact for noise-free data.
std::optional<Estimate> LinearisedStart(const std::vector<Point>& points) {
  const int n = static_cast<int>(points.size());
  std::optional<Estimate> estimate;
  std::vector<double> d_abs(points.size(), 1.0);  // |D| / w_p^2 of the previous pass, dimensionless; 1 at first
  for (int pass = 0; pass < 3; ++pass) {
    Eigen::MatrixXd a(2 * n, kNumParameters);
    Eigen::VectorXd rhs(2 * n);
    for (int i = 0; i < n; ++i) {
      const Point& p = points[i];
      const double w = p.omega_rad_s, w2 = w * w;
      const double scale = 1.0 / (w2 * std::abs(p.h) * d_abs[i]);
      const double hr = p.h.real(), hi = p.h.imag();
      a.row(2 * i) << hr * scale, -w * hi * scale, w2 * scale;
      a.row(2 * i + 1) << hi * scale, w * hr * scale, 0.0;
      rhs(2 * i) = hr * w2 * scale;
      rhs(2 * i + 1) = hi * w2 * scale;
    }
    const Eigen::Vector3d x = a.colPivHouseholderQr().solve(rhs);
    if (!(x(0) > 0) || !(x(1) > 0)) break;
    const double w_p = std::sqrt(x(0));
    estimate = Estimate{w_p, x(1) / (2 * w_p), x(2)};
    if (!IsPhysical(*estimate)) return std::nullopt;
    for (int i = 0; i < n; ++i) {
      const double w = points[i].omega_rad_s;
      d_abs[i] = std::abs(std::complex<double>(x(0) - w * w, x(1) * w)) / x(0);  // normalised to 1 at w = 0
    }
  }
  return estimate;
}

// Candidate w_p from the shape of the data: where Re H changes sign (exactly w_p in Eq. 3,
// interpolated in log frequency), and where |H_p| = |H| / (m w^2) peaks (w_p sqrt(1 - 2 zeta^2)).
std::vector<double> NaturalFrequencyCandidates(std::vector<Point> points) {
  std::sort(points.begin(), points.end(), [](const Point& x, const Point& y) { return x.omega_rad_s < y.omega_rad_s; });
  std::vector<double> candidates;
  for (std::size_t i = 1; i < points.size(); ++i) {
    const double r0 = points[i - 1].h.real(), r1 = points[i].h.real();
    if ((r0 < 0) == (r1 < 0)) continue;
    const double t = r0 / (r0 - r1);
    const double l0 = std::log(points[i - 1].omega_rad_s), l1 = std::log(points[i].omega_rad_s);
    candidates.push_back(std::exp(l0 + t * (l1 - l0)));
  }
  const auto peak = std::max_element(points.begin(), points.end(), [](const Point& x, const Point& y) {
    return std::abs(x.h) / (x.omega_rad_s * x.omega_rad_s) < std::abs(y.h) / (y.omega_rad_s * y.omega_rad_s);
  });
  candidates.push_back(peak->omega_rad_s);
  return candidates;
}

// Start 2, robust where the linearised fit is not (heavy noise, distorted FRFs): each candidate
// w_p against a logarithmic grid of zeta_p, g in closed form; the lowest cost wins.
std::optional<Estimate> ShapeStart(const std::vector<Point>& points) {
  std::optional<Estimate> best;
  double best_ssr = std::numeric_limits<double>::infinity();
  for (double w_p : NaturalFrequencyCandidates(points)) {
    for (double zeta = 0.01; zeta < 3.0; zeta *= 1.5) {
      const Estimate e{w_p, zeta, BestGain(points, w_p, zeta)};
      const double ssr = SumOfSquares(points, e);
      if (IsPhysical(e) && ssr < best_ssr) best = e, best_ssr = ssr;
    }
  }
  return best;
}

struct Start {
  Estimate estimate;
  std::string description;  // which start, with its values, for the report
};

// The better (lower cost) of the two starts, or nothing if neither is physical.
std::optional<Start> StartingValue(const std::vector<Point>& points) {
  const std::optional<Estimate> shape = ShapeStart(points);
  const std::optional<Estimate> linearised = LinearisedStart(points);
  const bool use_linearised =
      linearised && (!shape || SumOfSquares(points, *linearised) <= SumOfSquares(points, *shape));
  if (!use_linearised && !shape) return std::nullopt;
  const Estimate& e = use_linearised ? *linearised : *shape;
  const std::string name = use_linearised ? "linearised Eq. 3" : "Re(H) sign change / |H_p| peak";
  return Start{e, "start: " + name + " (w_p " + FormatDouble(e.natural_frequency_rad_s) + " rad/s, zeta " +
                      FormatDouble(e.damping_ratio) + ", g " + FormatDouble(e.gain_n_per_v) + " N/V)"};
}

ceres::Solver::Options SolverOptions(const FrfFitOptions& options) {
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.max_num_iterations = options.max_iterations;
  solver.logging_type = ceres::SILENT;
  // Tight tolerances: with noise-free data the cost goes to ~0 and the fit should return the
  // parameters to ~1e-10. Stopping tests (Ceres): |d cost| / cost < function_tolerance,
  // |d theta| < parameter_tolerance (|theta| + parameter_tolerance), max |gradient| < gradient_tolerance.
  solver.function_tolerance = 1e-14;
  solver.parameter_tolerance = 1e-14;
  solver.gradient_tolerance = 1e-16;
  return solver;
}

// Covariance of theta = (ln w_p, ln zeta_p, g) under unit residual variance, (J^T J)^-1, or
// nothing if the Jacobian is (numerically) rank deficient.
std::optional<Eigen::Matrix3d> UnitCovariance(ceres::Problem* problem, const double* theta) {
  ceres::Covariance::Options covariance_options;
  covariance_options.algorithm_type = ceres::DENSE_SVD;  // 3 parameters: dense is cheap and rank-safe
  ceres::Covariance covariance(covariance_options);
  if (!covariance.Compute(std::vector<const double*>{theta}, problem)) return std::nullopt;
  Eigen::Matrix<double, 3, 3, Eigen::RowMajor> c;
  if (!covariance.GetCovarianceBlock(theta, theta, c.data())) return std::nullopt;
  return Eigen::Matrix3d(c);
}

// Standard errors of (w_p, zeta_p, g, k_p, c_p) by the delta method.
// Ceres' covariance assumes residuals of unit variance; ours have an unknown common variance,
// estimated by s^2 = SSR / (2n - 3) (2n real residuals, 3 parameters), so Cov(theta) = s^2 (J^T J)^-1.
// Then with J_x = d(w_p, zeta, g)/d theta = diag(w_p, zeta, 1) and, from k_p = m w_p^2 and
// c_p = 2 zeta m w_p, J_k = d(k_p, c_p)/d(w_p, zeta, g) = [2 m w_p, 0, 0; 2 m zeta, 2 m w_p, 0],
// Cov(y) = J Cov(theta) J^T; the w_p-zeta covariance enters the standard error of c_p.
void FillStandardErrors(const Eigen::Matrix3d& unit_covariance, double residual_variance, double mass_kg,
                        FrfFitSummary* s) {
  const double w_p = s->natural_frequency_rad_s, zeta = s->damping_ratio;
  const Eigen::Matrix3d jx = Eigen::Vector3d(w_p, zeta, 1.0).asDiagonal();
  Eigen::Matrix<double, 5, 3> j_y_of_x = Eigen::Matrix<double, 5, 3>::Zero();
  j_y_of_x.topRows<3>().setIdentity();
  j_y_of_x.row(3) << 2 * mass_kg * w_p, 0, 0;
  j_y_of_x.row(4) << 2 * mass_kg * zeta, 2 * mass_kg * w_p, 0;
  const Eigen::Matrix<double, 5, 3> j = j_y_of_x * jx;
  const Eigen::Matrix<double, 5, 5> cov = residual_variance * j * unit_covariance * j.transpose();
  const Eigen::Matrix<double, 5, 1> se = cov.diagonal().cwiseMax(0.0).cwiseSqrt();
  s->natural_frequency_se = se(0);
  s->damping_ratio_se = se(1);
  s->gain_se = se(2);
  s->stiffness_se = se(3);
  s->damping_se = se(4);
}

bool AllFinite(const FrfFitSummary& s) {
  for (double v : {s.natural_frequency_rad_s, s.natural_frequency_se, s.damping_ratio, s.damping_ratio_se,
                   s.gain_n_per_v, s.gain_se, s.stiffness_n_per_m, s.stiffness_se, s.damping_n_s_per_m,
                   s.damping_se, s.rms_residual})
    if (!std::isfinite(v)) return false;
  return true;
}

// Marks a fit as failed, with the reason. Finite estimates stay (they may help to diagnose);
// non-finite ones are cleared, never passed on.
FrfFitSummary Failure(FrfFitSummary s, const std::string& reason) {
  if (!AllFinite(s)) {
    FrfFitSummary cleared;
    cleared.iterations = s.iterations;
    cleared.report = s.report;
    s = cleared;
  }
  s.converged = false;
  s.report += (s.report.empty() ? "" : "\n") + std::string("NOT CONVERGED: ") + reason;
  return s;
}

}  // namespace

std::optional<FieldError> FrfFitOptions::IsValid() const {
  if (!std::isfinite(mass_kg) || mass_kg <= 0)
    return FieldError{"mass_kg", "must be a finite number > 0, got " + FormatDouble(mass_kg)};
  if (max_iterations < 1) return FieldError{"max_iterations", "must be >= 1, got " + std::to_string(max_iterations)};
  return std::nullopt;
}

FrfFitSummary FitLinearFrf(std::span<const FrfSample> samples, const FrfFitOptions& options) {
  Validate(options);
  const std::vector<Point> points = ValidatedPoints(samples, options);

  const std::optional<Start> start = StartingValue(points);
  if (!start) return Failure(FrfFitSummary{}, "no starting value with w_p > 0, zeta_p > 0 and g != 0 fits these samples");
  std::array<double, kNumParameters> theta = {std::log(start->estimate.natural_frequency_rad_s),
                                              std::log(start->estimate.damping_ratio), start->estimate.gain_n_per_v};

  ceres::Problem problem;
  for (const Point& p : points) {
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Eq3Residual, 2, kNumParameters>(new Eq3Residual{p}),
                             nullptr, theta.data());
  }
  ceres::Solver::Summary solver_summary;
  ceres::Solve(SolverOptions(options), &problem, &solver_summary);

  FrfFitSummary s;
  s.iterations = solver_summary.num_successful_steps + solver_summary.num_unsuccessful_steps;
  s.report = start->description + "\n" + solver_summary.BriefReport();
  s.natural_frequency_rad_s = std::exp(theta[kFrfLogNaturalFrequency]);
  s.damping_ratio = std::exp(theta[kFrfLogDampingRatio]);
  s.gain_n_per_v = theta[kFrfGain];
  s.stiffness_n_per_m = options.mass_kg * s.natural_frequency_rad_s * s.natural_frequency_rad_s;
  s.damping_n_s_per_m = 2 * s.damping_ratio * options.mass_kg * s.natural_frequency_rad_s;
  const double ssr = 2 * solver_summary.final_cost;  // Ceres' cost is SSR / 2
  const int num_residuals = 2 * static_cast<int>(points.size());
  s.rms_residual = std::sqrt(ssr / num_residuals);
  if (solver_summary.termination_type != ceres::CONVERGENCE) return Failure(s, "Ceres did not converge");
  if (!AllFinite(s)) return Failure(s, "non-finite estimate");

  const std::optional<Eigen::Matrix3d> unit_covariance = UnitCovariance(&problem, theta.data());
  if (!unit_covariance)
    return Failure(s, "the Jacobian is rank deficient: w_p, zeta_p and g are not all identifiable from these samples");
  FillStandardErrors(*unit_covariance, ssr / (num_residuals - kNumParameters), options.mass_kg, &s);
  if (!AllFinite(s)) return Failure(s, "non-finite standard error");

  s.converged = true;
  return s;
}

}  // namespace strokelab
