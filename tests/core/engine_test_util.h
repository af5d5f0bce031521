// Helpers shared by the engine tests: a direct DFT and paper Eq. 3 written out independently of
// core's own signal.h and linear_response.h, so that the engines are checked by a second method.
#pragma once

#include <cmath>
#include <complex>
#include <numbers>
#include <vector>

#include "strokelab/engines/engine.h"
#include "strokelab/model/model.h"

namespace strokelab::testing {

// Complex amplitude A of signal[first..] at f_hz, so that signal ~ Re(A e^{j 2 pi f t}). Exact (a
// DFT bin) when the window holds a whole number of periods, as the last second does at integer f.
inline std::complex<double> ComplexAmplitude(const std::vector<double>& signal, size_t first, double sample_rate_hz,
                                             double f_hz) {
  std::complex<double> sum = 0.0;
  for (size_t n = first; n < signal.size(); ++n) {
    const double phase = 2.0 * std::numbers::pi * f_hz * static_cast<double>(n) / sample_rate_hz;
    sum += signal[n] * std::complex<double>(std::cos(phase), -std::sin(phase));
  }
  return 2.0 * sum / static_cast<double>(signal.size() - first);
}

// First sample of the record's last whole second.
inline size_t LastSecond(const Record& record) {
  return record.size() - static_cast<size_t>(record.sample_rate_hz);
}

// Damped natural frequency in contact with a linear stop [rad/s]: the linear part plus the stop's
// stiffness and damping, sqrt((k_p + k_c)/m_p - ((c_p + c_c)/(2 m_p))^2).
inline double ContactDampedFrequency(const ActuatorModel& m) {
  const double a = (m.damping_n_s_per_m + m.contact_damping_n_s_per_m) / (2.0 * m.mass_kg);
  return std::sqrt((m.stiffness_n_per_m + m.contact_stiffness) / m.mass_kg - a * a);
}

// No drive at all: free responses from an initial state.
inline const SineDrive kNoDrive{.amplitude_v = 0.0, .frequency_hz = 8.0, .phase_rad = 0.0};

// Paper Eq. 3 for a model's linear part.
inline std::complex<double> PaperEq3(const ActuatorModel& m, double w_rad_per_s) {
  const double w_p = std::sqrt(m.stiffness_n_per_m / m.mass_kg);
  const double zeta_p = m.damping_n_s_per_m / (2.0 * std::sqrt(m.stiffness_n_per_m * m.mass_kg));
  return -m.gain_n_per_v * w_rad_per_s * w_rad_per_s /
         std::complex<double>(w_p * w_p - w_rad_per_s * w_rad_per_s, 2.0 * zeta_p * w_p * w_rad_per_s);
}

}  // namespace strokelab::testing
