// Plain stepped-sine sweeps in the time domain, as on the test rig (paper section 3): the drive
// frequency steps up (or down) a list, and each step starts from the state the previous one ended
// in. The second method that continuation (sweep.h) is checked against: an up-sweep follows a
// branch until it ends (fold or grazing) and then jumps; a down-sweep does the same from above.
#pragma once

#include <complex>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "strokelab/engines/engine.h"
#include "strokelab/model/model.h"

namespace strokelab {

struct SteppedSineOptions {
  int settle_periods = 300;     // drive periods run before the analysis window, per step
  int analyse_periods = 20;     // drive periods analysed at the end of each step
  int samples_per_period = 512; // output samples per drive period
  // Nothing, or the wrong field: any count < 1, samples_per_period < 4, or more than 2e8 samples per
  // step.
  std::optional<FieldError> IsValid() const;
};

struct SteppedSinePoint {
  double frequency_hz = 0.0;
  std::complex<double> h;         // first-order FRF C1(f)/C1(v_in) over the analysis window [N/V]
                                  // (paper Eq. 3 convention; C1(v_in) = V e^{-j pi/2})
  double min_displacement_m = 0.0;  // min x over the analysis window [m]
  double contacts_per_period = 0.0; // stop contacts starting in the analysis window / analyse_periods
  State final_state;              // at the step's end, carried into the next step
};

// Steps through `frequencies_hz` in the order given (ascending for an up-sweep, descending for a
// down-sweep) at one drive amplitude, starting from rest, each step a whole number of periods so
// that the drive phase is continuous from step to step. Uses the exact engine for piecewise-linear
// models and cvode otherwise. Throws InputError naming the field on bad input (the model's fields,
// amplitude_v (finite, > 0: H is a ratio to the drive), frequencies_hz (not empty),
// frequencies_hz[i] (finite, > 0), the options' fields); NumericalError if a response is not finite.
std::vector<SteppedSinePoint> SteppedSineSweep(const ActuatorModel& model, double amplitude_v,
                                               const std::vector<double>& frequencies_hz,
                                               const SteppedSineOptions& options = {});

// Where a sweep jumped: indices i such that the response changed branch between step i and i+1:
// contacts appear or disappear (contacts_per_period becomes or stops being 0), or |H| changes by more
// than `relative_jump` relative beyond the local trend. The trend is the neighbouring step's slope:
// with d_i = ln(|H_{i+1}| / |H_i|) and u_i = ln(f_{i+1} / f_i), step i jumps if
//   min(|d_i|, |d_i - s u_i|) > ln(1 + relative_jump),   s = d_k / u_k of the neighbouring step
// k = i +- 1 with the smaller |slope| (s = 0 for a sweep of two points).
// Why the trend: on the paper's 2 % grid (Eq. 1) the linear |H| alone changes by up to 5.3 % per step
// (near 6.9 Hz, slope d ln|H| / d ln f = 2.55), which a bare 5 % threshold would call a jump.
// Throws InputError("relative_jump") unless it is finite and > 0.
std::vector<size_t> JumpIndices(const std::vector<SteppedSinePoint>& sweep, double relative_jump = 0.05);

}  // namespace strokelab
