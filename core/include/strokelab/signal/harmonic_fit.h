// Internal to strokelab::core (harmonics.cc, spikes.cc): the harmonic least-squares fit behind
// HarmonicAmplitudes, with the option of leaving samples out (the smooth baseline of DetectSpikes), and
// the joint fit of several harmonic series (a response's drive harmonics beside mains hum).
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

// One harmonic series of a joint fit: harmonics 1..orders of frequency_hz.
struct HarmonicFamily {
  double frequency_hz = 0.0;
  int orders = 0;
};

// Least-squares fit of several harmonic series and one offset together over the samples of `window`
// (`excluded` as for FitHarmonics): fits[i] holds family i's amplitudes, fits[0] the offset and the
// others none. Series that are not orthogonal over the window (mains hum beside a drive harmonic) are
// fitted as one, where fitting them in turn converges slowly. A harmonic closer than a thousandth of
// a frequency bin (1 / window length) to one of an earlier family is the same sinusoid over the window:
// it is not fitted (0) and the earlier one holds it. Throws as FitHarmonics.
std::vector<HarmonicFit> FitHarmonicFamilies(std::span<const double> signal, double sample_rate_hz,
                                             std::span<const HarmonicFamily> families, SampleWindow window,
                                             std::span<const char> excluded = {});

// The fitted curve at the samples of `window`: out[i] is its value at sample window.begin + i.
// out.size() must equal window.size().
void EvaluateHarmonics(const HarmonicFit& fit, double sample_rate_hz, double frequency_hz, SampleWindow window,
                       std::span<double> out);

}  // namespace strokelab::internal
