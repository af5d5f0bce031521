// The named effects' characteristics with their standard errors (diagnose.h, EffectCurve). Each
// curve is a force law of model.h (its header gives the equation of motion) written as the
// quantity a transducer analyser reports, with its gradient in the fitted parameters for the delta
// method: var y = g^T C g (C: the chosen fit's covariance of the parameters' values).
#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <numbers>
#include <string>

#include "strokelab/diagnose/effect_curves.h"
#include "strokelab/model/dynamics.h"

namespace strokelab {
namespace {

constexpr int kCurvePoints = 101;

// y and dy/d(parameter) by the names of CandidateFit::parameters (a name not fitted counts as fixed).
struct CurvePoint {
  double y = 0.0;
  std::map<std::string, double> gradient;
};
using CurveLaw = std::function<CurvePoint(const ActuatorModel&, double x)>;

// Uniform samples of [lo, hi] (one point when the range is empty).
std::vector<double> Grid(double lo, double hi) {
  if (!(hi > lo)) return {lo};
  std::vector<double> x(kCurvePoints);
  for (int i = 0; i < kCurvePoints; ++i) x[i] = lo + (hi - lo) * i / (kCurvePoints - 1);
  return x;
}

// The standard error of y from the gradient over the fitted parameters and their covariance.
double StandardError(const CurvePoint& point, const CandidateFit& fit) {
  const size_t p = fit.parameters.size();
  if (fit.covariance.size() != p * p) return NAN;
  std::vector<double> g(p, 0.0);
  for (size_t i = 0; i < p; ++i) {
    const auto it = point.gradient.find(fit.parameters[i].name);
    if (it != point.gradient.end()) g[i] = it->second;
  }
  double variance = 0.0;
  for (size_t i = 0; i < p; ++i)
    for (size_t j = 0; j < p; ++j)
      if (g[i] != 0.0 && g[j] != 0.0) variance += g[i] * fit.covariance[i * p + j] * g[j];
  return variance >= 0.0 ? std::sqrt(variance) : NAN;  // NaN also when a needed parameter has none
}

EffectCurve MakeCurve(Effect effect, std::string id, std::string title, std::string x_label, std::string y_label,
                      std::vector<double> x, std::string range, const CurveLaw& law, const CandidateFit& fit,
                      const ActuatorModel& base) {
  EffectCurve c{effect, std::move(id), std::move(title), std::move(x_label), std::move(y_label), std::move(x), {}, {}, {},
                std::move(range)};
  for (double x : c.x) {
    const CurvePoint point = law(fit.model, x);
    c.y.push_back(point.y);
    c.y_se.push_back(StandardError(point, fit));
    c.base_y.push_back(law(base, x).y);
  }
  return c;
}

// The stop force at penetration p >= 0, k_s p^n (n = 1 linear, 3/2 Hertzian; dynamics.h).
double StopForce(const ActuatorModel& m, double p) { return m.contact_stiffness * StopForcePerContactStiffness(m, p); }

}  // namespace

std::vector<EffectCurve> EffectCurves(const CandidateFit& chosen, const ActuatorModel& base, const CurveRanges& ranges) {
  const std::string& orbits = ranges.source;
  const double x_lo = std::min(ranges.min_displacement_m, 0.0), x_hi = std::max(ranges.max_displacement_m, 0.0);
  const double v_max = ranges.max_velocity_m_per_s;
  std::vector<EffectCurve> curves;
  bool stiffness_drawn = false;
  for (Effect effect : chosen.effects) {
    switch (effect) {
      case Effect::kCubicStiffness:
      case Effect::kQuadraticStiffness: {
        if (stiffness_drawn) break;  // one K(x) for both terms
        stiffness_drawn = true;
        // Suspension force k_p x + k2 x^2 + k3 x^3 over x (model.h).
        curves.push_back(MakeCurve(
            effect, "stiffness", "K(x) = k_p + k2 x + k3 x^2: the suspension's force over displacement", "x [m]",
            "K [N/m]", Grid(x_lo, x_hi), "displacements " + orbits,
            [](const ActuatorModel& m, double x) {
              return CurvePoint{m.stiffness_n_per_m + m.quadratic_stiffness_n_per_m2 * x + m.cubic_stiffness_n_per_m3 * x * x,
                                {{"k_p", 1.0}, {"k2", x}, {"k3", x * x}}};
            },
            chosen, base));
        break;
      }
      case Effect::kForceFactor:
        // Drive force g (1 + b1 x + b2 x^2) u (model.h, ForceFactorShape).
        curves.push_back(MakeCurve(
            effect, "force_factor", "g(x) = g (1 + b1 x + b2 x^2): the force factor over displacement (Bl(x))", "x [m]",
            "g [N/V]", Grid(x_lo, x_hi), "displacements " + orbits,
            [](const ActuatorModel& m, double x) {
              const double g = m.gain_n_per_v, shape = 1.0 + m.force_factor_b1_per_m * x + m.force_factor_b2_per_m2 * x * x;
              return CurvePoint{g * shape, {{"g", shape}, {"b1", g * x}, {"b2", g * x * x}}};
            },
            chosen, base));
        break;
      case Effect::kQuadraticDamping:
        // Damping force c_p v + c2 v|v| (model.h) over v: R(v) = c_p + c2 |v|.
        curves.push_back(MakeCurve(
            effect, "resistance", "R(v) = c_p + c2 |v|: the mechanical resistance (damping force / velocity)",
            "|v| [m/s]", "R [N s/m]", Grid(0.0, v_max), "velocities " + orbits,
            [](const ActuatorModel& m, double v) {
              return CurvePoint{m.damping_n_s_per_m + m.quadratic_damping_n_s2_per_m2 * v, {{"c_p", 1.0}, {"c2", v}}};
            },
            chosen, base));
        break;
      case Effect::kDryFriction:
        // F_c tanh(v / v_s) (model.h).
        curves.push_back(MakeCurve(
            effect, "friction", "F(v) = F_c tanh(v / v_s): the friction force over velocity", "v [m/s]", "F [N]",
            Grid(-v_max, v_max), "velocities " + orbits,
            [](const ActuatorModel& m, double v) {
              const double shape = std::tanh(v / m.friction_velocity_m_per_s);
              return CurvePoint{m.friction_force_n * shape, {{"friction_n", shape}}};
            },
            chosen, base));
        break;
      case Effect::kHertzianContact:
        curves.push_back(MakeCurve(
            effect, "stop_force", "F(p) = k_s p^n: the stop's force over penetration (n = 3/2 Hertzian, 1 linear)",
            "p [m]", "F [N]", Grid(0.0, ranges.max_penetration_m), "penetrations " + orbits,
            [](const ActuatorModel& m, double p) {
              return CurvePoint{StopForce(m, p), {{"k_s", StopForcePerContactStiffness(m, p)}}};
            },
            chosen, base));
        break;
      case Effect::kContactDamping:
        curves.push_back(MakeCurve(
            effect, "contact_damping", "F(w) = c_s w: the stop's damping force over penetration rate w", "w [m/s]",
            "F [N]", Grid(0.0, v_max), "velocities " + orbits,
            [](const ActuatorModel& m, double w) { return CurvePoint{m.contact_damping_n_s_per_m * w, {{"c_s", w}}}; },
            chosen, base));
        break;
      case Effect::kSecondStop:
        // The upper stop pushes with the lower stop's law at penetration x - d_upper.
        curves.push_back(MakeCurve(
            effect, "upper_stop_force", "F(x) = k_s (x - d_upper)^n for x > d_upper: the upper stop's force",
            "x [m]", "F [N]", Grid(0.0, x_hi), "displacements " + orbits,
            [](const ActuatorModel& m, double x) {
              if (!m.HasUpperStop() || x <= m.upper_stop_m) return CurvePoint{0.0, {}};
              const double p = x - m.upper_stop_m;
              return CurvePoint{StopForce(m, p),
                                {{"k_s", StopForcePerContactStiffness(m, p)}, {"d_upper", -StopStiffnessNPerM(m, p)}}};
            },
            chosen, base));
        break;
      case Effect::kAmplifierSaturation:
        curves.push_back(MakeCurve(
            effect, "drive", "u(V) = min(V, limit): the voltage the coil gets over the drive amplitude", "V [V]",
            "u [V]", Grid(0.0, ranges.max_amplitude_v), "the campaign's drive amplitudes",
            [](const ActuatorModel& m, double v) {
              if (!m.HasAmplifierLimit() || v <= m.amplifier_limit_v) return CurvePoint{v, {}};
              return CurvePoint{m.amplifier_limit_v, {{"amplifier_limit_v", 1.0}}};
            },
            chosen, base));
        break;
      case Effect::kCoilInductance:
        // The drive force's lag behind the voltage through the coil's pole at rest (v = 0; model.h):
        // F_e = g u / (1 + j w tau_e), arg = -atan(w tau_e).
        curves.push_back(MakeCurve(
            effect, "coil_lag", "lag(f) = atan(2 pi f tau_e): the drive force's phase lag behind the voltage (coil pole)",
            "f [Hz]", "lag [deg]", Grid(ranges.min_frequency_hz, ranges.max_frequency_hz), "the campaign's drive frequencies",
            [](const ActuatorModel& m, double f) {
              const double w = 2.0 * std::numbers::pi * f, degrees = 180.0 / std::numbers::pi;
              const double wt = w * m.coil_time_constant_s;
              return CurvePoint{std::atan(wt) * degrees, {{"tau_e", degrees * w / (1.0 + wt * wt)}}};
            },
            chosen, base));
        break;
    }
  }
  return curves;
}

}  // namespace strokelab
