// Fit of the linear FRF model, paper Eq. 3, to a measured or simulated first-order FRF, with Ceres:
//
//   H_mod(w) = -g w^2 / (w_p^2 + j 2 zeta_p w_p w - w^2)   [N/V]                    (paper Eq. 3)
//
// k_p = m_p w_p^2 and c_p = 2 zeta_p m_p w_p follow from the proof mass (paper section 4).
// Least squares over the real and imaginary parts of H_meas - H_mod at every sample, in the
// parameters (ln w_p, ln zeta_p, g), so that w_p and zeta_p stay positive; g may take either sign.
// Starting values come from the data (linearised Eq. 3, or where Re H changes sign, which is w_p
// exactly in Eq. 3); the report says which.
//
// Reference: "Nonlinear vibrations of a stroke-saturated inertial actuator" (the paper in
// shared/paper/), Eq. 3 and section 4.
#pragma once

#include <complex>
#include <optional>
#include <span>
#include <string>

#include "strokelab/base/errors.h"  // FieldError

namespace strokelab {

struct FrfSample {
  double frequency_hz = 0.0;  // [Hz], finite and > 0
  std::complex<double> h;     // [N/V], finite and non-zero
};

struct FrfFitOptions {
  double mass_kg = 0.032;   // m_p [kg], manufacturer data (paper section 4); only for k_p and c_p
  int max_iterations = 200; // Ceres iterations, >= 1
  // Residuals are relative (H_meas - H_mod) / |H_meas| so that every frequency counts alike.
  // Weighting by the measured (noisy) |H| biases the estimates by O(noise^2), far below their
  // standard errors at a few per cent noise. Otherwise absolute [N/V].
  bool relative_residuals = true;
  // Nothing, or the wrong field: mass_kg <= 0 or non-finite, max_iterations < 1.
  std::optional<FieldError> IsValid() const;
};

// Standard errors (_se, same units as their value) are from the Gauss-Newton covariance of the
// parameters scaled by the residual variance s^2 = SSR / (2n - 3), propagated to k_p and c_p by
// the delta method (including the w_p-zeta_p covariance).
struct FrfFitSummary {
  double natural_frequency_rad_s = 0.0, natural_frequency_se = 0.0;  // w_p [rad/s]
  double damping_ratio = 0.0, damping_ratio_se = 0.0;                // zeta_p, dimensionless
  double gain_n_per_v = 0.0, gain_se = 0.0;                          // g [N/V]
  double stiffness_n_per_m = 0.0, stiffness_se = 0.0;                // k_p = m_p w_p^2 [N/m]
  double damping_n_s_per_m = 0.0, damping_se = 0.0;                  // c_p = 2 zeta_p m_p w_p [N s/m]
  double rms_residual = 0.0;       // sqrt(SSR / 2n): dimensionless if relative, else [N/V]
  int iterations = 0;              // Ceres steps taken (successful and unsuccessful)
  // True only if Ceres reported CONVERGENCE, the covariance exists (the Jacobian has full rank)
  // and every number is finite. When false, finite estimates are kept for diagnosis, standard
  // errors may be 0 (unknown), and non-finite values are cleared to 0.
  bool converged = false;
  // The starting value used, Ceres' brief report, and, when not converged, "NOT CONVERGED: why".
  std::string report;
  bool IsSolutionUsable() const { return converged; }
};

// Needs at least 3 samples with finite, positive frequency and finite, non-zero H, and valid
// options; throws InputError naming the field (e.g. "samples[4].h") otherwise. Numerical failure
// is not thrown: it is reported in the summary (converged = false).
FrfFitSummary FitLinearFrf(std::span<const FrfSample> samples, const FrfFitOptions& options = {});

}  // namespace strokelab
