// Closed-form solution of one linear region of a piecewise-linear model:
//
//   m x'' + c x' + k x = a sin(w t + phi) + b        (paper Eq. 2 in each region)
//
// x(t) = x_p(t) + z(t): the particular (steady) part x_p = P_s sin(theta) + P_c cos(theta) + b/k with
// theta = w t + phi, and the homogeneous part z' = A z, A = [[0, 1], [-k/m, -c/m]], propagated by
//
//   exp(A tau) = e^(-alpha tau) [ C(tau) I + S(tau) (A + alpha I) ],   alpha = c / 2m,
//   C = cos(beta tau), S = sin(beta tau) / beta  with beta^2 = k/m - alpha^2 > 0 (underdamped),
//   cosh and sinh for beta^2 < 0, and the limit 1, tau at critical damping.
//
// (The 2x2 matrix exponential by the Cayley-Hamilton theorem; e.g. Moler & Van Loan, "Nineteen
// dubious ways to compute the exponential of a matrix", SIAM Review 45(1), 2003, method 15.)
#pragma once

#include "strokelab/engines/engine.h"

namespace strokelab {

// A 2x2 state-transition matrix acting on (x, v).
struct Transition {
  double xx = 1, xv = 0, vx = 0, vv = 1;
  State Apply(State z) const { return {xx * z.x_m + xv * z.v_m_per_s, vx * z.x_m + vv * z.v_m_per_s}; }
};

class LinearRegion {
 public:
  LinearRegion() = default;
  // mass [kg], damping [N s/m], stiffness [N/m] (> 0), sine force amplitude a [N], constant force
  // b [N], drive angular frequency w [rad/s], drive phase phi [rad].
  LinearRegion(double mass_kg, double damping_n_s_per_m, double stiffness_n_per_m, double sine_force_n,
               double constant_force_n, double omega_rad_s, double phase_rad);

  double mass_kg() const { return mass_kg_; }
  double damping() const { return damping_; }
  double stiffness() const { return stiffness_; }
  double sine_force_n() const { return sine_force_n_; }
  double constant_force_n() const { return constant_force_n_; }
  double omega() const { return omega_; }
  // Particular-solution coefficients: x_p = ps sin(theta) + pc cos(theta) + offset.
  double ps() const { return ps_; }
  double pc() const { return pc_; }
  double offset_m() const { return offset_m_; }
  double decay_rate() const { return alpha_; }    // alpha = c / 2m [1/s]
  double beta_squared() const { return beta2_; }  // k/m - alpha^2 [1/s^2]
  // Period of the free oscillation 2 pi / beta (or a decay time when overdamped) [s].
  double NaturalTimeScaleS() const;

  Transition Propagator(double tau_s) const;  // exp(A tau)
  State ParticularAt(double time_s) const;
  // The state at t0 + tau from the state at t0.
  State Propagate(State y0, double t0_s, double tau_s) const;
  // The same in two steps, for many tau from one (t0, y0): the homogeneous part z0 = y0 - x_p(t0)
  // once, then the state at t0 + tau from it (bit-identical to Propagate).
  State HomogeneousAt(State y0, double t0_s) const;
  State PropagateHomogeneous(State z0, double t0_s, double tau_s) const;
  // The state at t0 + tau (from z0 as above) and m x'' there, sharing one sin/cos of the drive phase.
  struct Motion {
    State y;
    double force_n;  // m x'' = a sin(theta) + b - k x - c v
    double sin_theta, cos_theta;  // of the drive phase theta = w t + phi
  };
  Motion MotionAt(State z0, double t0_s, double tau_s) const;
  // m x'' [N] at a state and time: a sin(theta) + b - k x - c v.
  double Force(State y, double time_s) const;

 private:
  double mass_kg_ = 1, damping_ = 0, stiffness_ = 1, sine_force_n_ = 0, constant_force_n_ = 0;
  double omega_ = 0, phase_ = 0;
  double ps_ = 0, pc_ = 0, offset_m_ = 0;
  double alpha_ = 0;   // c / 2m [1/s]
  double beta2_ = 0;   // k/m - alpha^2 [1/s^2]
  double beta_ = 0;    // sqrt(|beta2|) [1/s]
  double omega0_sq_ = 0;  // k/m
};

}  // namespace strokelab
