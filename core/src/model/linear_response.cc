// Closed forms of the linear actuator, paper Eq. 3 and section 3.2, and the linear saturation
// threshold V_sat (linear_response.h).
#include "strokelab/model/linear_response.h"

#include <cmath>
#include <limits>
#include <sstream>

#include "strokelab/base/errors.h"

namespace strokelab {
namespace {

using Complex = std::complex<double>;

// Field names are the model's short keys (model.h, Parameters()).
void RequirePositive(double value, const char* key) {
  if (!std::isfinite(value) || value <= 0.0) {
    std::ostringstream message;
    message << "must be a finite number > 0 (got " << value << ")";
    throw InputError(key, message.str());
  }
}

// The dynamic stiffness of the suspension, k_p - m_p w^2 + j c_p w [N/m], seen by the drive's force g u.
// With the coil's pole (model.h) the phasors of m_p x'' + (c_p - c_emf) x' + k_p x = F_e and
// (1 + j w tau_e) F_e = g U - j w c_emf X give g U = [(k_p - m_p w^2 + j (c_p - c_emf) w)(1 + j w tau_e)
// + j w c_emf] X.
Complex DynamicStiffness(const ActuatorModel& model, double omega_rad_s) {
  const double w = omega_rad_s, c_emf = model.back_emf_damping_n_s_per_m;
  if (!model.HasCoilPole())
    return Complex(model.stiffness_n_per_m - model.mass_kg * w * w, model.damping_n_s_per_m * w);
  const Complex mechanical(model.stiffness_n_per_m - model.mass_kg * w * w, (model.damping_n_s_per_m - c_emf) * w);
  return mechanical * Complex(1.0, w * model.coil_time_constant_s) + Complex(0.0, w * c_emf);
}

}  // namespace

// Paper Eq. 3.
Complex ForceFrfEq3(double natural_frequency_rad_s, double damping_ratio, double gain_n_per_v, double omega_rad_s) {
  const double wp = natural_frequency_rad_s;
  const double w = omega_rad_s;
  return -gain_n_per_v * w * w / Complex(wp * wp - w * w, 2.0 * damping_ratio * wp * w);
}

Complex ForceFrf(const ActuatorModel& model, double omega_rad_s) {
  if (model.HasCoilPole()) return -model.mass_kg * omega_rad_s * omega_rad_s * DisplacementFrf(model, omega_rad_s);
  return ForceFrfEq3(NaturalFrequencyRadS(model), DampingRatio(model), model.gain_n_per_v, omega_rad_s);
}

// -H / (m_p w^2) simplifies to g / (k_p - m_p w^2 + j c_p w), which stays finite at w = 0 (g / k_p);
// with the coil's pole, g over DynamicStiffness's form.
Complex DisplacementFrf(const ActuatorModel& model, double omega_rad_s) {
  RequirePositive(model.mass_kg, "m_p");
  return model.gain_n_per_v / DynamicStiffness(model, omega_rad_s);
}

double NaturalFrequencyRadS(const ActuatorModel& model) {
  RequirePositive(model.mass_kg, "m_p");
  RequirePositive(model.stiffness_n_per_m, "k_p");
  return std::sqrt(model.stiffness_n_per_m / model.mass_kg);
}

double DampingRatio(const ActuatorModel& model) {
  RequirePositive(model.mass_kg, "m_p");
  RequirePositive(model.stiffness_n_per_m, "k_p");
  return model.damping_n_s_per_m / (2.0 * std::sqrt(model.stiffness_n_per_m * model.mass_kg));
}

// The linear steady state is x = H_p V sin(...); it grazes the stop when |H_p| V = |d|.
double LinearSaturationThresholdV(const ActuatorModel& model, double omega_rad_s) {
  if (!model.HasLowerStop()) return std::numeric_limits<double>::infinity();
  RequirePositive(model.gain_n_per_v, "g");
  return std::abs(model.lower_stop_m) * std::abs(DynamicStiffness(model, omega_rad_s)) / model.gain_n_per_v;
}

}  // namespace strokelab
