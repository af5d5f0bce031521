// The force the diagnosed model lacks, over the state (x, v): a restoring-force surface from the
// records' harmonics (diagnose.h, MissingForceSurface).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <complex>
#include <functional>
#include <limits>
#include <numbers>

#include "diagnose_internal.h"
#include "strokelab/identify/fit_orbit.h"
#include "strokelab/model/dynamics.h"

namespace strokelab::internal {
namespace {

using Complex = std::complex<double>;
constexpr double kEmptyBin = std::numeric_limits<double>::quiet_NaN();
constexpr int kSurfacePhases = 256;          // drive phases per record
constexpr int kSurfaceBins = 12;             // per axis of the surface
constexpr double kStopMargin = 0.05;  // of the stop distance: phases this near a stop are left out
constexpr size_t kMinSamples = 32;    // fewer phases clear of the stops: no surface

// X_h from the response's C_h: ResponseHarmonic (fit_orbit.h) is C_h = k(h) X_h, so X_h = C_h / k(h).
Complex DisplacementHarmonic(Complex c, int h, double omega, ResponseKind kind, double mass_kg) {
  return c / ResponseHarmonic(1.0, h, omega, kind, mass_kg);
}

struct Motion {
  double x_m = 0, v_m_per_s = 0, a_m_per_s2 = 0;
};

// x, x', x'' at drive phase theta from displacement harmonics: x = mean + sum_h Re(X_h e^{j h theta}).
Motion MotionAt(const std::vector<Complex>& x_h, double mean_x_m, double omega, double theta) {
  Motion m;
  m.x_m = mean_x_m;
  for (size_t k = 0; k < x_h.size(); ++k) {
    const double h = static_cast<double>(k + 1), w = h * omega;
    const Complex z = x_h[k] * std::polar(1.0, h * theta);
    m.x_m += z.real();
    m.v_m_per_s += -w * z.imag();  // Re(j w z)
    m.a_m_per_s2 += -w * w * z.real();
  }
  return m;
}

// m_p x'' - F(u, x, v): the force on the mass that the model's blocked force does not account for.
double ForceNotInModel(const ActuatorModel& model, const Motion& m, double voltage_v) {
  return model.mass_kg * m.a_m_per_s2 - BlockedForce(model, voltage_v, State{m.x_m, m.v_m_per_s}, ContactMode{});
}

bool NearStop(const ActuatorModel& model, double x_m) {
  const bool lower = model.HasLowerStop() && x_m < model.lower_stop_m + kStopMargin * std::abs(model.lower_stop_m);
  const bool upper = model.HasUpperStop() && x_m > model.upper_stop_m - kStopMargin * std::abs(model.upper_stop_m);
  return lower || upper;
}

struct Term {
  const char* name;
  const char* unit;
  std::function<double(double x, double v)> g;
};

const std::vector<Term>& Terms() {
  static const std::vector<Term> terms = {
      {"x^2", "N/m^2", [](double x, double) { return x * x; }},
      {"x v", "N s/m^2", [](double x, double v) { return x * v; }},
      {"v^2", "N s^2/m^2", [](double, double v) { return v * v; }},
      {"x^3", "N/m^3", [](double x, double) { return x * x * x; }},
      {"x^2 v", "N s/m^3", [](double x, double v) { return x * x * v; }},
      {"x v^2", "N s^2/m^3", [](double x, double v) { return x * v * v; }},
      {"v^3", "N s^3/m^3", [](double, double v) { return v * v * v; }},
      {"x|x|", "N/m^2", [](double x, double) { return x * std::abs(x); }},
      {"v|v|", "N s^2/m^2", [](double, double v) { return v * std::abs(v); }},
      {"sign v", "N", [](double, double v) { return v > 0 ? 1.0 : v < 0 ? -1.0 : 0.0; }},
  };
  return terms;
}

// Least squares of r on the columns of `a` (scaled to unit norm for conditioning): the fraction of
// r's variance about its mean explained, and the coefficients.
double ExplainedVariance(const Eigen::MatrixXd& a, const Eigen::VectorXd& r, Eigen::VectorXd* coefficients) {
  const Eigen::VectorXd norms = a.colwise().norm();
  Eigen::MatrixXd scaled = a;
  for (Eigen::Index c = 0; c < a.cols(); ++c) scaled.col(c) /= norms(c) > 0 ? norms(c) : 1.0;
  const Eigen::VectorXd beta = scaled.colPivHouseholderQr().solve(r);
  const double total = (r.array() - r.mean()).square().sum();
  const double left = (r - scaled * beta).squaredNorm();
  *coefficients = beta;
  for (Eigen::Index c = 0; c < a.cols(); ++c) (*coefficients)(c) /= norms(c) > 0 ? norms(c) : 1.0;
  return total > 0 ? 1.0 - left / total : 0.0;
}

void FitShape(const std::vector<double>& xs, const std::vector<double>& vs, const std::vector<double>& rs,
              MissingForceSurface* s) {
  const Eigen::Index n = static_cast<Eigen::Index>(rs.size());
  const Eigen::VectorXd r = Eigen::Map<const Eigen::VectorXd>(rs.data(), n);
  Eigen::MatrixXd a(n, 4);
  for (Eigen::Index i = 0; i < n; ++i) a.row(i) << 1.0, xs[i], vs[i], 0.0;
  Eigen::VectorXd beta;
  s->linear_r2 = ExplainedVariance(a.leftCols(3), r, &beta);
  s->term_r2 = -1.0;
  for (const Term& t : Terms()) {
    for (Eigen::Index i = 0; i < n; ++i) a(i, 3) = t.g(xs[i], vs[i]);
    const double r2 = ExplainedVariance(a, r, &beta);
    if (r2 > s->term_r2) s->term_r2 = r2, s->term = t.name, s->term_unit = t.unit, s->term_coefficient = beta(3);
  }
}

}  // namespace

MissingForceSurface EstimateMissingForce(const ActuatorModel& model, const std::vector<RecordMatch>& matches,
                                         ResponseKind kind) {
  MissingForceSurface s;
  if (model.HasCoilPole()) {
    s.note = "the model's coil force is a state of its own, which no record measures";
    return s;
  }
  std::vector<double> xs, vs, rs;
  for (const RecordMatch& m : matches) {
    // A period-2 orbit's harmonics at the drive frequency do not give its state.
    if (m.model.empty() || m.model_period != 1 || m.measured.size() != m.model.size()) continue;
    const double omega = 2.0 * std::numbers::pi * m.frequency_hz;
    std::vector<Complex> measured_x(m.model.size()), model_x(m.model.size());
    for (size_t k = 0; k < m.model.size(); ++k) {
      const int h = static_cast<int>(k + 1);
      // A harmonic left out of the fit (under mains hum) is taken as the model's.
      const bool usable = k < m.harmonic_chi2.size() && m.harmonic_chi2[k] > 0;
      measured_x[k] = DisplacementHarmonic(usable ? m.measured[k] : m.model[k], h, omega, kind, model.mass_kg);
      model_x[k] = DisplacementHarmonic(m.model[k], h, omega, kind, model.mass_kg);
    }
    for (int i = 0; i < kSurfacePhases; ++i) {
      // Harmonics are relative to the drive's phase: u = V sin(theta) (fit.h, RecordAnalysis).
      const double theta = 2.0 * std::numbers::pi * i / kSurfacePhases, voltage_v = m.amplitude_v * std::sin(theta);
      const Motion seen = MotionAt(measured_x, m.model_mean_x_m, omega, theta);
      const Motion modelled = MotionAt(model_x, m.model_mean_x_m, omega, theta);
      if (NearStop(model, seen.x_m) || NearStop(model, modelled.x_m)) continue;
      xs.push_back(seen.x_m);
      vs.push_back(seen.v_m_per_s);
      rs.push_back(ForceNotInModel(model, seen, voltage_v) - ForceNotInModel(model, modelled, voltage_v));
    }
  }
  if (rs.size() < kMinSamples) {
    s.note = "fewer than " + std::to_string(kMinSamples) + " drive phases of period-1 orbits clear of the stops";
    return s;
  }
  const auto [x_lo, x_hi] = std::minmax_element(xs.begin(), xs.end());
  const auto [v_lo, v_hi] = std::minmax_element(vs.begin(), vs.end());
  const double x0 = *x_lo, dx = (*x_hi - *x_lo) / kSurfaceBins, v0 = *v_lo, dv = (*v_hi - *v_lo) / kSurfaceBins;
  for (int b = 0; b < kSurfaceBins; ++b) {
    s.x_m.push_back(x0 + (b + 0.5) * dx);
    s.v_m_per_s.push_back(v0 + (b + 0.5) * dv);
  }
  std::vector<double> sum(kSurfaceBins * kSurfaceBins, 0.0), sum2(kSurfaceBins * kSurfaceBins, 0.0);
  s.samples.assign(kSurfaceBins * kSurfaceBins, 0);
  auto index = [](double value, double start, double width) {
    return width > 0 ? std::clamp(static_cast<int>((value - start) / width), 0, kSurfaceBins - 1) : 0;
  };
  double square_sum = 0.0;
  for (size_t i = 0; i < rs.size(); ++i) {
    const int b = index(xs[i], x0, dx) * kSurfaceBins + index(vs[i], v0, dv);
    sum[b] += rs[i], sum2[b] += rs[i] * rs[i], ++s.samples[b];
    square_sum += rs[i] * rs[i];
  }
  s.rms_n = std::sqrt(square_sum / static_cast<double>(rs.size()));
  for (int b = 0; b < kSurfaceBins * kSurfaceBins; ++b) {
    const double n = s.samples[b];
    if (n < 2) {
      s.force_n.push_back(kEmptyBin), s.standard_error_n.push_back(kEmptyBin);
      continue;
    }
    const double mean = sum[b] / n, variance = std::max(0.0, (sum2[b] - n * mean * mean) / (n - 1));
    s.force_n.push_back(mean);
    s.standard_error_n.push_back(std::sqrt(variance / n));
  }
  FitShape(xs, vs, rs, &s);
  return s;
}

std::string DescribeMissingForce(const MissingForceSurface& s) {
  if (s.force_n.empty()) return "; no missing-force surface: " + s.note;
  return "; the force the model lacks, estimated over (x, v) from the records' harmonics (a restoring-force "
         "surface, RMS " + FormatFigure(s.rms_n) + " N), is closest to " + s.term + " (" + FormatFigure(s.term_coefficient) +
         " " + s.term_unit + " " + s.term + "; with 1, x and v it explains " + FormatFigure(100.0 * s.term_r2, 2) +
         " % of its variance, against " + FormatFigure(100.0 * s.linear_r2, 2) + " % for 1, x and v alone)";
}

}  // namespace strokelab::internal
