#include "free_flight_map.h"

#include <Eigen/Dense>
#include <unsupported/Eigen/MatrixFunctions>
#include <algorithm>

namespace strokelab::variational {

bool FreeFlightMap::Applies(const ActuatorModel& model, const FlowRequest& request) {
  if (model.quadratic_stiffness_n_per_m2 != 0 || model.cubic_stiffness_n_per_m3 != 0 || model.friction_force_n != 0 ||
      model.quadratic_damping_n_s2_per_m2 != 0 || model.force_factor_b1_per_m != 0 ||
      model.force_factor_b2_per_m2 != 0)
    return false;
  // The parameters whose columns outside the stops are forced by terms affine in the state and u:
  // the linear suspension and drive, the coil's pole, and the stops' own (0 outside them), and the
  // amplifier's limit (0 while it does not clip).
  static constexpr double ActuatorModel::*kAffine[] = {
      &ActuatorModel::mass_kg,           &ActuatorModel::damping_n_s_per_m,
      &ActuatorModel::stiffness_n_per_m, &ActuatorModel::gain_n_per_v,
      &ActuatorModel::lower_stop_m,      &ActuatorModel::upper_stop_m,
      &ActuatorModel::contact_stiffness, &ActuatorModel::contact_damping_n_s_per_m,
      &ActuatorModel::coil_time_constant_s, &ActuatorModel::back_emf_damping_n_s_per_m,
      &ActuatorModel::amplifier_limit_v};
  return std::all_of(request.parameters.begin(), request.parameters.end(), [](double ActuatorModel::*p) {
    return std::find(std::begin(kAffine), std::end(kAffine), p) != std::end(kAffine);
  });
}

FreeFlightMap::FreeFlightMap(const ActuatorModel& model, const FlowRequest& request, double interval_s,
                             const std::vector<double>& scale, double voltage_scale_v) {
  // The field driven by u(t) = t over [0, 1] s: at t = 0 it is M Y + c, at t = 1 M Y + N + c.
  // The amplifier's limit is taken away (the ramp would cross it); b is read off the clipped model
  // below.
  const SampledDrive unit_ramp{1.0, {0.0, 1.0}};
  ActuatorModel unclipped = model;
  unclipped.amplifier_limit_v = ActuatorModel::kNoLimit;
  const Field field(unclipped, Drive{SineDrive{}, &unit_ramp}, request);
  n_ = field.layout().size;
  limit_v_ = model.amplifier_limit_v;
  const int n = n_;
  std::vector<double> y(n, 0.0), at_zero(n), at_one(n), dy(n), clipped(n, 0.0);
  field.Evaluate(0.0, y.data(), at_zero.data(), ContactMode{});
  field.Evaluate(1.0, y.data(), at_one.data(), ContactMode{});
  if (model.HasAmplifierLimit()) {
    // Driven beyond the limit, the clipped model's field at Y = 0 is N L + c + b.
    const SampledDrive beyond{1.0, {2.0 * limit_v_ + 1.0, 2.0 * limit_v_ + 1.0}};
    const Field clipped_field(model, Drive{SineDrive{}, &beyond}, request);
    clipped_field.Evaluate(0.0, y.data(), clipped.data(), ContactMode{});
    for (int i = 0; i < n; ++i) clipped[i] -= limit_v_ * (at_one[i] - at_zero[i]) + at_zero[i];
  }
  // A: rows 0..n-1 [M | N | 0 | c | b]; row n (u): du / h; rows n+1 (du), n+2 (1) and n+3 (s): 0.
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n + 4, n + 4);
  for (int j = 0; j < n; ++j) {
    y[j] = 1.0;
    field.Evaluate(0.0, y.data(), dy.data(), ContactMode{});
    y[j] = 0.0;
    for (int i = 0; i < n; ++i) a(i, j) = dy[i] - at_zero[i];
  }
  for (int i = 0; i < n; ++i) {
    a(i, n) = at_one[i] - at_zero[i];
    a(i, n + 2) = at_zero[i];
    a(i, n + 3) = clipped[i];
  }
  a(n, n + 1) = 1.0 / interval_s;
  // Balanced: z = S z' with S = diag(scale, voltage scale twice, 1, 1), A' = S^-1 A S, E = S E' S^-1.
  Eigen::VectorXd s(n + 4);
  for (int i = 0; i < n; ++i) s[i] = scale[i];
  s[n] = s[n + 1] = voltage_scale_v;
  s[n + 2] = s[n + 3] = 1.0;
  const Eigen::MatrixXd balanced = s.cwiseInverse().asDiagonal() * a * s.asDiagonal();
  const Eigen::MatrixXd e = s.asDiagonal() * (balanced * interval_s).exp() * s.cwiseInverse().asDiagonal();
  transition_.resize(static_cast<size_t>(n) * n);
  from_voltage_.resize(n);
  from_voltage_change_.resize(n);
  constant_.resize(n);
  from_clipping_.resize(n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) transition_[static_cast<size_t>(i) * n + j] = e(i, j);
    from_voltage_[i] = e(i, n);
    from_voltage_change_[i] = e(i, n + 1);
    constant_[i] = e(i, n + 2);
    from_clipping_[i] = e(i, n + 3);
  }
}

int FreeFlightMap::Side(double u_v) const { return u_v > limit_v_ ? 1 : u_v < -limit_v_ ? -1 : 0; }

bool FreeFlightMap::Covers(double u_start_v, double u_end_v) const { return Side(u_start_v) == Side(u_end_v); }

void FreeFlightMap::Advance(const double* y, double u_start_v, double u_end_v, double* y_next) const {
  // Beyond the limit the amplifier holds s L throughout (Covers).
  const double s = Side(u_start_v);
  if (s != 0) u_start_v = u_end_v = s * limit_v_;
  const double du = u_end_v - u_start_v;
  for (int i = 0; i < n_; ++i) {
    const double* row = &transition_[static_cast<size_t>(i) * n_];
    double sum = constant_[i] + from_voltage_[i] * u_start_v + from_voltage_change_[i] * du + s * from_clipping_[i];
    for (int j = 0; j < n_; ++j) sum += row[j] * y[j];
    y_next[i] = sum;
  }
}

}  // namespace strokelab::variational
