#include "strokelab/model/dynamics.h"

#include <cmath>
#include <numbers>

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

double ClippedVoltage(const ActuatorModel& model, double voltage_v) {
  const double limit = model.amplifier_limit_v;
  return voltage_v > limit ? limit : (voltage_v < -limit ? -limit : voltage_v);
}

double StopForceUnclamped(const ActuatorModel& model, double p, double p_rate) {
  const double elastic = model.contact_law == ContactLaw::kLinear
                             ? model.contact_stiffness * p
                             : model.contact_stiffness * std::copysign(std::pow(std::abs(p), 1.5), p);
  return elastic + model.contact_damping_n_s_per_m * p_rate;
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

double BlockedForce(const ActuatorModel& m, double drive_voltage_v, double x, double v, ContactMode mode) {
  double force = m.gain_n_per_v * ClippedVoltage(m, drive_voltage_v) - m.stiffness_n_per_m * x -
                 m.damping_n_s_per_m * v;
  if (m.quadratic_stiffness_n_per_m2 != 0) force -= m.quadratic_stiffness_n_per_m2 * x * x;
  if (m.cubic_stiffness_n_per_m3 != 0) force -= m.cubic_stiffness_n_per_m3 * x * x * x;
  if (m.friction_force_n != 0) force -= m.friction_force_n * std::tanh(v / m.friction_velocity_m_per_s);
  // In a pushing mode the stop force is used unclamped: the mode switch at its zero is the clamp.
  if (mode.lower) force += StopForceUnclamped(m, m.lower_stop_m - x, -v);
  if (mode.upper) force -= StopForceUnclamped(m, x - m.upper_stop_m, v);
  return force;
}

}  // namespace strokelab
