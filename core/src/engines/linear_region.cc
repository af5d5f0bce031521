#include "strokelab/engines/linear_region.h"

#include <cmath>
#include <numbers>

#include "strokelab/base/sincos.h"

namespace strokelab {

LinearRegion::LinearRegion(double mass_kg, double damping, double stiffness, double sine_force_n,
                           double constant_force_n, double omega, double phase)
    : mass_kg_(mass_kg),
      damping_(damping),
      stiffness_(stiffness),
      sine_force_n_(sine_force_n),
      constant_force_n_(constant_force_n),
      omega_(omega),
      phase_(phase) {
  // Particular solution: (k - m w^2) P_s - c w P_c = a and c w P_s + (k - m w^2) P_c = 0.
  const double real = stiffness - mass_kg * omega * omega;
  const double imag = damping * omega;
  const double denominator = real * real + imag * imag;
  ps_ = sine_force_n * real / denominator;
  pc_ = -sine_force_n * imag / denominator;
  offset_m_ = constant_force_n / stiffness;
  alpha_ = damping / (2.0 * mass_kg);
  omega0_sq_ = stiffness / mass_kg;
  beta2_ = omega0_sq_ - alpha_ * alpha_;
  beta_ = std::sqrt(std::abs(beta2_));
}

double LinearRegion::NaturalTimeScaleS() const {
  if (beta2_ > 0) return 2.0 * std::numbers::pi / beta_;
  return 2.0 * std::numbers::pi / std::sqrt(omega0_sq_);
}

Transition LinearRegion::Propagator(double tau) const {
  // C(tau) and S(tau) of the header; a two-term series where beta tau is tiny keeps the critically
  // damped limit continuous.
  double c_part, s_part;
  const double bt2 = beta2_ * tau * tau;
  if (std::abs(bt2) < 1e-8) {
    c_part = 1.0 - 0.5 * bt2;
    s_part = tau * (1.0 - bt2 / 6.0);
  } else if (beta2_ > 0) {
    const SinCos beta_tau = SinCosOf(beta_ * tau);
    c_part = beta_tau.cos;
    s_part = beta_tau.sin / beta_;
  } else {
    c_part = std::cosh(beta_ * tau);
    s_part = std::sinh(beta_ * tau) / beta_;
  }
  const double decay = std::exp(-alpha_ * tau);
  Transition t;
  t.xx = decay * (c_part + alpha_ * s_part);
  t.xv = decay * s_part;
  t.vx = -decay * omega0_sq_ * s_part;
  t.vv = decay * (c_part - alpha_ * s_part);
  return t;
}

State LinearRegion::ParticularAt(double time_s) const {
  const auto [s, c] = SinCosOf(omega_ * time_s + phase_);
  return {ps_ * s + pc_ * c + offset_m_, omega_ * (ps_ * c - pc_ * s)};
}

State LinearRegion::Propagate(State y0, double t0, double tau) const {
  return PropagateHomogeneous(HomogeneousAt(y0, t0), t0, tau);
}

State LinearRegion::HomogeneousAt(State y0, double t0) const {
  const State p0 = ParticularAt(t0);
  return {y0.x_m - p0.x_m, y0.v_m_per_s - p0.v_m_per_s};
}

State LinearRegion::PropagateHomogeneous(State z0, double t0, double tau) const {
  const State z = Propagator(tau).Apply(z0);
  const State p1 = ParticularAt(t0 + tau);
  return {z.x_m + p1.x_m, z.v_m_per_s + p1.v_m_per_s};
}

LinearRegion::Motion LinearRegion::MotionAt(State z0, double t0, double tau) const {
  const State z = Propagator(tau).Apply(z0);
  // ParticularAt and Force, term for term, on one sin/cos.
  const auto [s, c] = SinCosOf(omega_ * (t0 + tau) + phase_);
  const State p{ps_ * s + pc_ * c + offset_m_, omega_ * (ps_ * c - pc_ * s)};
  const State y{z.x_m + p.x_m, z.v_m_per_s + p.v_m_per_s};
  return {y, sine_force_n_ * s + constant_force_n_ - stiffness_ * y.x_m - damping_ * y.v_m_per_s, s, c};
}

double LinearRegion::Force(State y, double time_s) const {
  return sine_force_n_ * SinCosOf(omega_ * time_s + phase_).sin + constant_force_n_ - stiffness_ * y.x_m -
         damping_ * y.v_m_per_s;
}

}  // namespace strokelab
