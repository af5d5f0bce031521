// The right-hand side of the equation of motion in model.h, shared by every engine.
//
//   m_p x'' = g u(t) - k_p x - k2 x^2 - k3 x^3 - c_p x' - F_c tanh(x'/v_s) + F_lower - F_upper
//
// and, with the coil's pole (model.h), the coil's force F_e as a third state in place of g u.
//
// Paper Eq. 2 in its continuous form (its slip at contact corrected, model.h) plus the extra terms
// of model.h.
#pragma once

#include <vector>

#include "strokelab/model/model.h"

namespace strokelab {

// The state of the equation of motion.
struct State {
  double x_m = 0.0;          // displacement [m]
  double v_m_per_s = 0.0;    // velocity [m/s]
  double coil_force_n = 0.0; // F_e [N]: the coil's force at phi = 1, a state only with the coil's pole
                             // (ActuatorModel::StateSize); ignored otherwise
};

// v_in(t) = V sin(w t + phi): the stepped-sine drive of the paper, section 3.
struct SineDrive {
  double amplitude_v = 0.0;   // V [V]
  double frequency_hz = 0.0;  // f [Hz], w = 2 pi f
  double phase_rad = 0.0;     // phi [rad]

  double AngularFrequency() const;           // [rad/s]
  double Voltage(double time_s) const;       // unclipped v_in(t) [V]
  std::optional<FieldError> IsValid() const;  // names amplitude_v / frequency_hz / phase_rad
};

// v_in(t) from a record's measured voltage: samples v_k at t_k = k / fs, k = 0 .. N-1, joined by straight
// lines (a first-order hold) and held at their ends outside [0, (N-1) / fs]. The drive of a broadband
// record (noise, multisine, sweep), whose voltage channel is the truth. The flow cuts its steps at the
// t_k, so that the drive is a polynomial within each step and the integrator keeps its order.
struct SampledDrive {
  double sample_rate_hz = 0.0;   // fs [Hz]
  std::vector<double> voltage_v;  // v_k [V]

  double Voltage(double time_s) const;        // unclipped v_in(t) [V]
  double DurationS() const;                   // (N - 1) / fs [s]
  double PeakV() const;                       // max |v_k| [V]
  std::optional<FieldError> IsValid() const;  // names sample_rate_hz / voltage_v (and the sample)
};

// Which stops currently push on the mass. A stop pushes while the penetration is positive and the
// contact force (stiffness plus damping) is positive: the clamp that keeps a damped stop from pulling.
struct ContactMode {
  bool lower = false;
  bool upper = false;
  bool operator==(const ContactMode&) const = default;
  bool Any() const { return lower || upper; }
};

// Drive voltage after the amplifier limit [V].
double ClippedVoltage(const ActuatorModel& model, double voltage_v);

// Contact force magnitude of one stop before the clamp [N]: k_s p^n + c_s p', with p the
// penetration [m] (positive inside the stop) and p' its rate [m/s]. Continuous in p through p = 0
// (a signed power for the Hertzian law), so that its zero is a clean switching surface.
double StopForceUnclamped(const ActuatorModel& model, double penetration_m, double penetration_rate_m_per_s);

// The mode a state is in, judged from the state alone (used where no mode is tracked: ode3).
ContactMode ModeFromState(const ActuatorModel& model, double x_m, double v_m_per_s);

// The mode at the start of a run where the mode is tracked from then on: ModeFromState, and a state
// exactly on a stop's surface (p = 0) moving into it counts as pushing (it would an instant later,
// and a switching function that is exactly zero at the start shows no crossing).
ContactMode StartingMode(const ActuatorModel& model, double x_m, double v_m_per_s);

// 1 + b1 x + b2 x^2: the coil's force factor at x over its value at rest (model.h).
double ForceFactorShape(const ActuatorModel& model, double x_m);

// m_p x'' [N]: the blocked force f (model.h) for a given contact mode and drive voltage.
double BlockedForce(const ActuatorModel& model, double drive_voltage_v, const State& y, ContactMode mode);

// BlockedForce with its partial derivatives in the state, for Jacobians and variational equations.
struct ForceJacobian {
  double force_n = 0.0;
  double d_dx_n_per_m = 0.0;
  double d_dv_n_s_per_m = 0.0;
  double d_dcoil = 0.0;  // d f / d F_e (phi) with the coil's pole, else 0
  // tanh(v / v_s), the smoothed friction's shape, where F_c != 0 (else 0): computed once for the force,
  // its slope and its parameter derivatives (the field's costliest term on a friction model).
  double friction_shape = 0.0;
};
ForceJacobian BlockedForceJacobian(const ActuatorModel& model, double drive_voltage_v, const State& y,
                                   ContactMode mode);

// d BlockedForce / d parameter at a fixed state, drive and mode, for a parameter named by its field in
// ActuatorModel [N per the parameter's unit]; `at` is BlockedForceJacobian there. The mass gives 0: f
// does not depend on m_p, x'' = f / m_p does.
double BlockedForceParameterDerivative(const ActuatorModel& model, double ActuatorModel::*parameter,
                                       double drive_voltage_v, const State& y, ContactMode mode,
                                       const ForceJacobian& at);

// With the coil's pole: F_e' = (g u - c_emf phi v - F_e) / tau_e [N/s] (model.h), with its partial
// derivatives. It does not depend on the contact mode, so it never jumps at a switch.
struct CoilForceRate {
  double rate_n_per_s = 0.0;
  double d_dx_n_per_m_s = 0.0;
  double d_dv_n_per_m = 0.0;
  double d_dcoil_per_s = 0.0;
  double d_dvoltage_n_per_v_s = 0.0;  // d/d(unclipped drive voltage): g / tau_e, 0 where the amplifier clips
};
CoilForceRate CoilForceRateJacobian(const ActuatorModel& model, double drive_voltage_v, const State& y);
// The coil force where F_e' = 0 at (x, v) and the drive voltage: g u - c_emf phi v [N] (model.h). F_e
// settles there within a few tau_e of any start.
double QuasiStaticCoilForceN(const ActuatorModel& model, double drive_voltage_v, const State& y);
double CoilForceRateParameterDerivative(const ActuatorModel& model, double ActuatorModel::*parameter,
                                        double drive_voltage_v, const State& y);

// d(stop force)/d(penetration) [N/m] at penetration p: k_s (linear) or 1.5 k_s |p|^(1/2) (Hertzian).
double StopStiffnessNPerM(const ActuatorModel& model, double penetration_m);
// d(stop force)/d k_s at penetration p: p (linear) or sign(p) |p|^(3/2) (Hertzian) [m or m^1.5].
double StopForcePerContactStiffness(const ActuatorModel& model, double penetration_m);

}  // namespace strokelab
