#include "strokelab/model/dynamics.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

namespace strokelab {

double SineDrive::AngularFrequency() const { return 2.0 * std::numbers::pi * frequency_hz; }

double SineDrive::Voltage(double time_s) const {
  return amplitude_v * std::sin(AngularFrequency() * time_s + phase_rad);
}

std::optional<FieldError> SineDrive::IsValid() const {
  if (!std::isfinite(amplitude_v) || amplitude_v < 0)
    return FieldError{"amplitude_v", "must be a finite number >= 0"};
  if (!std::isfinite(frequency_hz) || frequency_hz <= 0)
    return FieldError{"frequency_hz", "must be a finite number > 0"};
  if (!std::isfinite(phase_rad)) return FieldError{"phase_rad", "must be finite"};
  return std::nullopt;
}

double SampledDrive::Voltage(double time_s) const {
  const double position = time_s * sample_rate_hz;
  if (!(position > 0.0)) return voltage_v.front();
  const size_t last = voltage_v.size() - 1;
  if (position >= static_cast<double>(last)) return voltage_v.back();
  const size_t k = static_cast<size_t>(position);
  const double fraction = position - static_cast<double>(k);
  return voltage_v[k] + fraction * (voltage_v[k + 1] - voltage_v[k]);
}

double SampledDrive::DurationS() const {
  return voltage_v.empty() ? 0.0 : static_cast<double>(voltage_v.size() - 1) / sample_rate_hz;
}

double SampledDrive::PeakV() const {
  double peak = 0.0;
  for (double v : voltage_v) peak = std::max(peak, std::abs(v));
  return peak;
}

std::optional<FieldError> SampledDrive::IsValid() const {
  if (!std::isfinite(sample_rate_hz) || sample_rate_hz <= 0)
    return FieldError{"sample_rate_hz", "must be a finite number > 0"};
  if (voltage_v.size() < 2) return FieldError{"voltage_v", "needs at least 2 samples"};
  for (size_t k = 0; k < voltage_v.size(); ++k)
    if (!std::isfinite(voltage_v[k])) return FieldError{"voltage_v", "sample " + std::to_string(k) + " is not finite"};
  return std::nullopt;
}

double ClippedVoltage(const ActuatorModel& model, double voltage_v) {
  const double limit = model.amplifier_limit_v;
  return voltage_v > limit ? limit : (voltage_v < -limit ? -limit : voltage_v);
}

double StopForcePerContactStiffness(const ActuatorModel& model, double p) {
  return model.contact_law == ContactLaw::kLinear ? p : std::copysign(std::abs(p) * std::sqrt(std::abs(p)), p);
}

double StopForceUnclamped(const ActuatorModel& model, double p, double p_rate) {
  return model.contact_stiffness * StopForcePerContactStiffness(model, p) + model.contact_damping_n_s_per_m * p_rate;
}

double StopStiffnessNPerM(const ActuatorModel& model, double p) {
  if (model.contact_law == ContactLaw::kLinear) return model.contact_stiffness;
  return 1.5 * model.contact_stiffness * std::sqrt(std::abs(p));
}

ContactMode ModeFromState(const ActuatorModel& model, double x, double v) {
  ContactMode mode;
  if (model.HasLowerStop()) {
    const double p = model.lower_stop_m - x;
    mode.lower = p > 0 && StopForceUnclamped(model, p, -v) > 0;
  }
  if (model.HasUpperStop()) {
    const double p = x - model.upper_stop_m;
    mode.upper = p > 0 && StopForceUnclamped(model, p, v) > 0;
  }
  return mode;
}

ContactMode StartingMode(const ActuatorModel& model, double x, double v) {
  ContactMode mode = ModeFromState(model, x, v);
  if (model.HasLowerStop() && model.lower_stop_m - x == 0.0 && v < 0) mode.lower = true;
  if (model.HasUpperStop() && x - model.upper_stop_m == 0.0 && v > 0) mode.upper = true;
  return mode;
}

double ForceFactorShape(const ActuatorModel& m, double x) {
  return 1.0 + (m.force_factor_b1_per_m + m.force_factor_b2_per_m2 * x) * x;
}

namespace {
// dF/dphi [N]: how the coil's force changes with the force factor's shape: g phi u - c_emf phi^2 v
// without the coil's pole, phi F_e with it.
double ForcePerForceFactorShape(const ActuatorModel& m, double drive_voltage_v, const State& y) {
  if (m.HasCoilPole()) return y.coil_force_n;
  return m.gain_n_per_v * ClippedVoltage(m, drive_voltage_v) -
         2.0 * m.back_emf_damping_n_s_per_m * ForceFactorShape(m, y.x_m) * y.v_m_per_s;
}

double ForceFactorSlope(const ActuatorModel& m, double x) {
  return m.force_factor_b1_per_m + 2.0 * m.force_factor_b2_per_m2 * x;
}

// d(clipped voltage)/d(amplifier limit): +-1 where the amplifier clips, else 0.
double ClippedVoltagePerLimit(const ActuatorModel& m, double drive_voltage_v) {
  if (drive_voltage_v > m.amplifier_limit_v) return 1.0;
  if (drive_voltage_v < -m.amplifier_limit_v) return -1.0;
  return 0.0;
}
}  // namespace

namespace {
// tanh(v / v_s) where F_c != 0, else 0 (ForceJacobian::friction_shape).
double FrictionShape(const ActuatorModel& m, double v) {
  return m.friction_force_n != 0 ? std::tanh(v / m.friction_velocity_m_per_s) : 0.0;
}

// BlockedForce with the friction's shape given.
double BlockedForceWith(const ActuatorModel& m, double drive_voltage_v, const State& y, ContactMode mode,
                        double friction_shape) {
  const double x = y.x_m, v = y.v_m_per_s;
  const double phi = ForceFactorShape(m, x);
  double force;
  if (m.HasCoilPole()) {
    // The coil's force phi F_e, and c_p v less the coil's part c_emf v, which F_e carries (model.h).
    force = phi * y.coil_force_n - m.stiffness_n_per_m * x - m.damping_n_s_per_m * v + m.back_emf_damping_n_s_per_m * v;
  } else {
    // The coil's force g phi u - c_emf phi^2 v, written as the rest's g u - c_emf v (the latter inside
    // c_p v) plus what the force factor changes (model.h).
    force = m.gain_n_per_v * phi * ClippedVoltage(m, drive_voltage_v) - m.stiffness_n_per_m * x - m.damping_n_s_per_m * v;
    if (m.back_emf_damping_n_s_per_m != 0) force -= m.back_emf_damping_n_s_per_m * (phi * phi - 1.0) * v;
  }
  if (m.quadratic_stiffness_n_per_m2 != 0) force -= m.quadratic_stiffness_n_per_m2 * x * x;
  if (m.cubic_stiffness_n_per_m3 != 0) force -= m.cubic_stiffness_n_per_m3 * x * x * x;
  if (m.friction_force_n != 0) force -= m.friction_force_n * friction_shape;
  if (m.quadratic_damping_n_s2_per_m2 != 0) force -= m.quadratic_damping_n_s2_per_m2 * v * std::abs(v);
  // In a pushing mode the stop force is used unclamped: the mode switch at its zero is the clamp.
  if (mode.lower) force += StopForceUnclamped(m, m.lower_stop_m - x, -v);
  if (mode.upper) force -= StopForceUnclamped(m, x - m.upper_stop_m, v);
  return force;
}
}  // namespace

double BlockedForce(const ActuatorModel& m, double drive_voltage_v, const State& y, ContactMode mode) {
  return BlockedForceWith(m, drive_voltage_v, y, mode, FrictionShape(m, y.v_m_per_s));
}

ForceJacobian BlockedForceJacobian(const ActuatorModel& m, double drive_voltage_v, const State& y,
                                   ContactMode mode) {
  const double x = y.x_m, v = y.v_m_per_s;
  ForceJacobian j;
  j.friction_shape = FrictionShape(m, v);
  j.force_n = BlockedForceWith(m, drive_voltage_v, y, mode, j.friction_shape);
  const double phi = ForceFactorShape(m, x);
  j.d_dx_n_per_m = -m.stiffness_n_per_m - 2.0 * m.quadratic_stiffness_n_per_m2 * x - 3.0 * m.cubic_stiffness_n_per_m3 * x * x +
                   ForcePerForceFactorShape(m, drive_voltage_v, y) * ForceFactorSlope(m, x);
  if (m.HasCoilPole()) {
    j.d_dv_n_s_per_m = -m.damping_n_s_per_m + m.back_emf_damping_n_s_per_m;
    j.d_dcoil = phi;
  } else {
    j.d_dv_n_s_per_m = -m.damping_n_s_per_m - m.back_emf_damping_n_s_per_m * (phi * phi - 1.0);
  }
  if (m.friction_force_n != 0) {
    const double th = j.friction_shape;
    j.d_dv_n_s_per_m -= m.friction_force_n / m.friction_velocity_m_per_s * (1.0 - th * th);
  }
  j.d_dv_n_s_per_m -= 2.0 * m.quadratic_damping_n_s2_per_m2 * std::abs(v);  // d(v|v|)/dv = 2|v|
  // Both stops oppose the displacement into them: d/dx and d/dv of the stop term are negative.
  if (mode.lower) {
    j.d_dx_n_per_m -= StopStiffnessNPerM(m, m.lower_stop_m - x);
    j.d_dv_n_s_per_m -= m.contact_damping_n_s_per_m;
  }
  if (mode.upper) {
    j.d_dx_n_per_m -= StopStiffnessNPerM(m, x - m.upper_stop_m);
    j.d_dv_n_s_per_m -= m.contact_damping_n_s_per_m;
  }
  return j;
}

double BlockedForceParameterDerivative(const ActuatorModel& m, double ActuatorModel::*parameter,
                                       double drive_voltage_v, const State& y, ContactMode mode,
                                       const ForceJacobian& at) {
  using M = ActuatorModel;
  const double x = y.x_m, v = y.v_m_per_s;
  const bool pole = m.HasCoilPole();
  // Each stop term enters with its sign: + F_lower(p = d - x, p' = -v), - F_upper(p = x - d_upper, p' = v).
  const double p_lower = m.lower_stop_m - x, p_upper = x - m.upper_stop_m;
  if (parameter == &M::damping_n_s_per_m) return -v;
  if (parameter == &M::stiffness_n_per_m) return -x;
  if (parameter == &M::quadratic_stiffness_n_per_m2) return -x * x;
  if (parameter == &M::cubic_stiffness_n_per_m3) return -x * x * x;
  // With the coil's pole, g and the amplifier's limit act through F_e (CoilForceRateParameterDerivative).
  if (parameter == &M::gain_n_per_v) return pole ? 0.0 : ForceFactorShape(m, x) * ClippedVoltage(m, drive_voltage_v);
  if (parameter == &M::force_factor_b1_per_m || parameter == &M::force_factor_b2_per_m2) {
    const double dphi = parameter == &M::force_factor_b1_per_m ? x : x * x;  // d phi / d b
    return ForcePerForceFactorShape(m, drive_voltage_v, y) * dphi;
  }
  if (parameter == &M::back_emf_damping_n_s_per_m) {
    if (pole) return v;
    const double phi = ForceFactorShape(m, x);
    return -(phi * phi - 1.0) * v;
  }
  // (At F_c = 0 the Jacobian holds no shape: d f / d F_c is -tanh(v / v_s) all the same.)
  const auto friction_shape = [&] {
    return m.friction_force_n != 0 ? at.friction_shape : std::tanh(v / m.friction_velocity_m_per_s);
  };
  if (parameter == &M::friction_force_n) return -friction_shape();
  if (parameter == &M::quadratic_damping_n_s2_per_m2) return -v * std::abs(v);
  if (parameter == &M::friction_velocity_m_per_s) {
    const double vs = m.friction_velocity_m_per_s, th = friction_shape();
    return m.friction_force_n * (1.0 - th * th) * v / (vs * vs);
  }
  if (parameter == &M::amplifier_limit_v)
    return pole ? 0.0 : m.gain_n_per_v * ForceFactorShape(m, x) * ClippedVoltagePerLimit(m, drive_voltage_v);
  if (parameter == &M::lower_stop_m) return mode.lower ? StopStiffnessNPerM(m, p_lower) : 0.0;
  if (parameter == &M::upper_stop_m) return mode.upper ? StopStiffnessNPerM(m, p_upper) : 0.0;
  if (parameter == &M::contact_stiffness)
    return (mode.lower ? StopForcePerContactStiffness(m, p_lower) : 0.0) -
           (mode.upper ? StopForcePerContactStiffness(m, p_upper) : 0.0);
  if (parameter == &M::contact_damping_n_s_per_m) return (mode.lower ? -v : 0.0) - (mode.upper ? v : 0.0);
  return 0.0;  // the mass (see the header), tau_e (it acts through F_e) and fields that are not forces
}

double QuasiStaticCoilForceN(const ActuatorModel& m, double drive_voltage_v, const State& y) {
  return m.gain_n_per_v * ClippedVoltage(m, drive_voltage_v) -
         m.back_emf_damping_n_s_per_m * ForceFactorShape(m, y.x_m) * y.v_m_per_s;
}

CoilForceRate CoilForceRateJacobian(const ActuatorModel& m, double drive_voltage_v, const State& y) {
  const double tau = m.coil_time_constant_s, x = y.x_m, v = y.v_m_per_s;
  const double phi = ForceFactorShape(m, x), c_emf = m.back_emf_damping_n_s_per_m;
  CoilForceRate r;
  r.rate_n_per_s = (QuasiStaticCoilForceN(m, drive_voltage_v, y) - y.coil_force_n) / tau;
  r.d_dx_n_per_m_s = -c_emf * ForceFactorSlope(m, x) * v / tau;
  r.d_dv_n_per_m = -c_emf * phi / tau;
  r.d_dcoil_per_s = -1.0 / tau;
  r.d_dvoltage_n_per_v_s = std::abs(drive_voltage_v) <= m.amplifier_limit_v ? m.gain_n_per_v / tau : 0.0;
  return r;
}

double CoilForceRateParameterDerivative(const ActuatorModel& m, double ActuatorModel::*parameter,
                                        double drive_voltage_v, const State& y) {
  using M = ActuatorModel;
  const double tau = m.coil_time_constant_s, x = y.x_m, v = y.v_m_per_s;
  const double c_emf = m.back_emf_damping_n_s_per_m;
  if (parameter == &M::gain_n_per_v) return ClippedVoltage(m, drive_voltage_v) / tau;
  if (parameter == &M::back_emf_damping_n_s_per_m) return -ForceFactorShape(m, x) * v / tau;
  if (parameter == &M::force_factor_b1_per_m) return -c_emf * x * v / tau;
  if (parameter == &M::force_factor_b2_per_m2) return -c_emf * x * x * v / tau;
  if (parameter == &M::coil_time_constant_s) return -CoilForceRateJacobian(m, drive_voltage_v, y).rate_n_per_s / tau;
  if (parameter == &M::amplifier_limit_v) return m.gain_n_per_v * ClippedVoltagePerLimit(m, drive_voltage_v) / tau;
  return 0.0;
}

}  // namespace strokelab
