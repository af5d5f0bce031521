// Internal to strokelab::core (harmonics.cc, spikes.cc): the harmonic least-squares fit behind
// HarmonicAmplitudes, with the option of leaving samples out (the smooth baseline of DetectSpikes).
#pragma once

#include <complex>
#include <cstddef>
#include <span>
#include <vector>

#include "strokelab/signal/signal.h"

namespace strokelab::internal {

// signal(t) ~ offset + sum_{h=1..H} Re(amplitudes[h-1] exp(j h w t)), t = n / fs absolute.
struct HarmonicFit {
  double offset = 0.0;                              // c_0, signal units
  std::vector<std::complex<double>> amplitudes;     // C_1..C_H, signal units
};

// Least-squares fit of `orders` harmonics (orders >= 0; 0 fits the offset alone) over the samples of
// `window`. `excluded`, when not empty, has window.size() entries; samples with a non-zero entry are
// left out of the fit. Throws InputError on bad arguments (naming the field), NumericalError if the
// samples kept cannot determine the coefficients.
HarmonicFit FitHarmonics(std::span<const double> signal, double sample_rate_hz, double frequency_hz,
                         SampleWindow window, int orders, std::span<const char> excluded = {});

// The fitted curve at the samples of `window`: out[i] is its value at sample window.begin + i.
// out.size() must equal window.size().
void EvaluateHarmonics(const HarmonicFit& fit, double sample_rate_hz, double frequency_hz, SampleWindow window,
                       std::span<double> out);

}  // namespace strokelab::internal
