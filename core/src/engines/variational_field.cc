#include "variational_field.h"

#include <cmath>
#include <numbers>

namespace strokelab::variational {

Layout::Layout(const FlowRequest& request, int d)
    : state_size(d),
      state_columns(request.monodromy ? d : 0),
      parameter_columns(static_cast<int>(request.parameters.size())),
      harmonics(request.harmonics),
      harmonic_sensitivities(request.harmonic_sensitivities) {
  columns = state_columns + parameter_columns;
  if (request.drive_amplitude) amplitude_column = columns++;
  if (request.drive_frequency) frequency_column = columns++;
  size = d * (1 + columns) + 2 * harmonics + (harmonic_sensitivities ? 2 * columns * harmonics : 0);
}

std::string Drive::Describe() const {
  if (sampled) return "sampled at " + std::to_string(sampled->sample_rate_hz) + " Hz";
  return std::to_string(sine.frequency_hz) + " Hz, " + std::to_string(sine.amplitude_v) + " V";
}

Field::Field(const ActuatorModel& model, const Drive& drive, const FlowRequest& request)
    : model_(model),
      drive_(drive),
      parameters_(request.parameters),
      layout_(request, model.StateSize()),
      inverse_mass_per_kg_(1.0 / model.mass_kg),
      omega_rad_per_s_(drive.AngularFrequency()),
      cos_phase_(std::cos(drive.sine.phase_rad)),
      sin_phase_(std::sin(drive.sine.phase_rad)) {}

State StateOf(const double* y, int state_size) { return {y[0], y[1], state_size > 2 ? y[2] : 0.0}; }

double Field::Force(double t_s, const double* y, ContactMode mode) const {
  return BlockedForce(model_, drive_.Voltage(t_s), StateOf(y, layout_.state_size), mode);
}

void SmallAngleCosSin(double theta, double* cos_theta, double* sin_theta) {
  const double t2 = theta * theta;
  double c = 1.0 / 6402373705728000.0, s = 1.0 / 355687428096000.0;  // 1/18!, 1/17!
  // Horner in theta^2 over the factorials (2k)! and (2k+1)!, k = 8 .. 0.
  constexpr double kEven[] = {1.0 / 20922789888000.0, 1.0 / 87178291200.0, 1.0 / 479001600.0, 1.0 / 3628800.0,
                              1.0 / 40320.0,          1.0 / 720.0,         1.0 / 24.0,        1.0 / 2.0,
                              1.0};
  constexpr double kOdd[] = {1.0 / 1307674368000.0, 1.0 / 6227020800.0, 1.0 / 39916800.0, 1.0 / 362880.0,
                             1.0 / 5040.0,          1.0 / 120.0,        1.0 / 6.0,        1.0};
  c = -c * t2 + kEven[0];  // 1/16! - theta^2/18!
  for (int k = 1; k < 9; ++k) c = -c * t2 + kEven[k];
  for (int k = 0; k < 8; ++k) s = -s * t2 + kOdd[k];
  *cos_theta = c;
  *sin_theta = s * theta;
}

double Field::Evaluate(double t_s, const double* y, double* dy, ContactMode mode) const {
  return Evaluate(t_s, std::cos(omega_rad_per_s_ * t_s), std::sin(omega_rad_per_s_ * t_s), y, dy, mode, true);
}

double Field::Evaluate(double t_s, double cos_wt, double sin_wt, const double* y, double* dy, ContactMode mode,
                       bool quadratures) const {
  return layout_.state_size > 2 ? EvaluateWith<true>(t_s, cos_wt, sin_wt, y, dy, mode, quadratures)
                                : EvaluateWith<false>(t_s, cos_wt, sin_wt, y, dy, mode, quadratures);
}

template <bool kCoilPole>
double Field::EvaluateWith(double t_s, double cos_wt, double sin_wt, const double* y, double* dy, ContactMode mode,
                           bool quadratures) const {
  const Layout& l = layout_;
  const State state{y[0], y[1], kCoilPole ? y[2] : 0.0};
  const double x = state.x_m;
  // sin/cos of w t serve the drive (angle addition with its phase) and the quadratures.
  const double sin_drive = sin_wt * cos_phase_ + cos_wt * sin_phase_;  // sin(wt + phi)
  const double voltage_v = drive_.sampled ? drive_.sampled->Voltage(t_s) : drive_.sine.amplitude_v * sin_drive;
  const double m = inverse_mass_per_kg_;
  double force_n;
  CoilForceRate coil;
  if constexpr (kCoilPole) coil = CoilForceRateJacobian(model_, voltage_v, state);
  if (l.columns == 0) {
    force_n = BlockedForce(model_, voltage_v, state, mode);
  } else {
    const ForceJacobian j = BlockedForceJacobian(model_, voltage_v, state, mode);
    force_n = j.force_n;
    for (int c = 0; c < l.columns; ++c) {
      const int i = l.Column(c);
      const double sx = y[i], sv = y[i + 1], se = kCoilPole ? y[i + 2] : 0.0;
      dy[i] = sv;
      double force_rate = j.d_dx_n_per_m * sx + j.d_dv_n_s_per_m * sv;
      if constexpr (kCoilPole) force_rate += j.d_dcoil * se;
      double acceleration = force_rate * m;
      double coil_rate = kCoilPole ? coil.d_dx_n_per_m_s * sx + coil.d_dv_n_per_m * sv + coil.d_dcoil_per_s * se : 0.0;
      if (c == l.amplitude_column || c == l.frequency_column) {
        // The drive enters as g phi u, or through F_e' with the coil's pole, with u = V sin(wt + phi)
        // while the amplifier does not clip it: du/dV = sin(wt + phi), du/df = V 2 pi t cos(wt + phi).
        if (std::abs(voltage_v) <= model_.amplifier_limit_v) {
          const double cos_drive = cos_wt * cos_phase_ - sin_wt * sin_phase_;
          const double du = c == l.amplitude_column ? sin_drive
                                                    : drive_.sine.amplitude_v * 2.0 * std::numbers::pi * t_s * cos_drive;
          if constexpr (kCoilPole) coil_rate += coil.d_dvoltage_n_per_v_s * du;
          else acceleration += model_.gain_n_per_v * ForceFactorShape(model_, x) * m * du;
        }
      } else if (c >= l.state_columns) {
        double ActuatorModel::*p = parameters_[c - l.state_columns];
        // x'' = f / m_p: the mass enters through 1 / m_p (d/dm_p = -f / m_p^2), the rest through f.
        acceleration += p == &ActuatorModel::mass_kg
                            ? -force_n * m * m
                            : BlockedForceParameterDerivative(model_, p, voltage_v, state, mode, j) * m;
        if constexpr (kCoilPole) coil_rate += CoilForceRateParameterDerivative(model_, p, voltage_v, state);
      }
      dy[i + 1] = acceleration;
      if constexpr (kCoilPole) dy[i + 2] = coil_rate;
    }
  }
  dy[0] = state.v_m_per_s;
  dy[1] = force_n * m;
  if constexpr (kCoilPole) dy[2] = coil.rate_n_per_s;
  if (!quadratures) return force_n;
  // e^{-jhwt} by repeated multiplication with e^{-jwt}.
  double re = 1.0, im = 0.0;
  for (int k = 0; k < l.harmonics; ++k) {
    const double next_re = re * cos_wt + im * sin_wt;
    im = im * cos_wt - re * sin_wt;
    re = next_re;
    dy[l.Quadrature(k)] = x * re;
    dy[l.Quadrature(k) + 1] = x * im;
    if (!l.harmonic_sensitivities) continue;
    for (int c = 0; c < l.columns; ++c) {
      const double sx = y[l.Column(c)];
      dy[l.QuadratureSensitivity(c, k)] = sx * re;
      dy[l.QuadratureSensitivity(c, k) + 1] = sx * im;
    }
  }
  return force_n;
}

// Lower stop: p = d - x, p' = -v; upper stop: p = x - d_upper, p' = v (dynamics.h).
double StopSurface::Value(const ActuatorModel& m, double x, double v) const {
  const double p = upper ? x - m.upper_stop_m : m.lower_stop_m - x;
  if (!force) return p;
  return StopForceUnclamped(m, p, upper ? v : -v);
}

void StopSurface::Gradient(const ActuatorModel& m, double x, double /*v*/, double* dh_dx, double* dh_dv) const {
  const double dp_dx = upper ? 1.0 : -1.0;  // and dp'/dv the same
  if (!force) {
    *dh_dx = dp_dx;
    *dh_dv = 0.0;
    return;
  }
  const double p = upper ? x - m.upper_stop_m : m.lower_stop_m - x;
  *dh_dx = StopStiffnessNPerM(m, p) * dp_dx;
  *dh_dv = m.contact_damping_n_s_per_m * dp_dx;
}

double StopSurface::ParameterDerivative(const ActuatorModel& m, double ActuatorModel::*parameter, double x,
                                    double v) const {
  const double p = upper ? x - m.upper_stop_m : m.lower_stop_m - x;
  // dp/d(stop position): +1 for the lower stop's d, -1 for the upper stop's.
  double dp = 0.0;
  if (!upper && parameter == &ActuatorModel::lower_stop_m) dp = 1.0;
  if (upper && parameter == &ActuatorModel::upper_stop_m) dp = -1.0;
  if (!force) return dp;
  if (parameter == &ActuatorModel::contact_stiffness) return StopForcePerContactStiffness(m, p);
  if (parameter == &ActuatorModel::contact_damping_n_s_per_m) return upper ? v : -v;
  return StopStiffnessNPerM(m, p) * dp;
}

}  // namespace strokelab::variational
