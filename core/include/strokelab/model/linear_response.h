// Closed forms of the linear actuator (no stop contact): paper Eq. 3 and the saturation threshold
// V_sat (the non-contacting part of Eq. 2 reaching the stop).
#pragma once

#include <complex>

#include "strokelab/model/model.h"

namespace strokelab {

// Paper Eq. 3: H(w) = -g w^2 / (w_p^2 + j 2 zeta_p w_p w - w^2) [N/V], blocked force per drive volt.
std::complex<double> ForceFrfEq3(double natural_frequency_rad_s, double damping_ratio, double gain_n_per_v,
                                 double omega_rad_s);
// Eq. 3 from the model's m_p, c_p, k_p, g; with the coil's pole (model.h), -m_p w^2 DisplacementFrf.
std::complex<double> ForceFrf(const ActuatorModel& model, double omega_rad_s);
// H_p = -H / (m_p w^2) [m/V] (paper section 3.2), with the coil's pole where the model has one.
std::complex<double> DisplacementFrf(const ActuatorModel& model, double omega_rad_s);

// w_p = sqrt(k_p / m_p) [rad/s] and zeta_p = c_p / (2 sqrt(k_p m_p)) (dimensionless).
double NaturalFrequencyRadS(const ActuatorModel& model);
double DampingRatio(const ActuatorModel& model);

// V_sat(w) = |d| |k_p - m_p w^2 + j c_p w| / g [V]: the drive amplitude at which the linear
// steady state first grazes the lower stop d. Infinite without a lower stop.
double LinearSaturationThresholdV(const ActuatorModel& model, double omega_rad_s);

}  // namespace strokelab
