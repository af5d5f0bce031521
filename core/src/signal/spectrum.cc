// One-sided Hann-windowed amplitude spectrum (paper Fig. 3), with Eigen's FFT (kissfft backend,
// any length).
//
// Scaling. The periodic Hann window w_n = (1 - cos(2 pi n / N)) / 2 sums to N/2 (coherent gain 0.5).
// A sinusoid A cos(2 pi k n / N + phi) at bin k (0 < k < N/2) puts A/2 * sum(w) into X_k, and nothing
// else does as long as 2 <= k <= N/2 - 2 (the Hann kernel reaches the neighbouring bins only), so
// amplitude_k = 2 |X_k| / sum(w) reads A exactly. The DC and Nyquist bins have no mirror image:
// amplitude = |X_k| / sum(w).
#include <unsupported/Eigen/FFT>

#include <cmath>
#include <complex>
#include <numbers>
#include <sstream>
#include <vector>

#include "strokelab/base/errors.h"
#include "strokelab/signal/signal.h"

namespace strokelab {
namespace {

// The periodic ("DFT-even") Hann window, the one whose bins are exact for bin-centred sinusoids.
std::vector<double> PeriodicHann(size_t count) {
  std::vector<double> window(count);
  for (size_t n = 0; n < count; ++n) {
    window[n] = 0.5 * (1.0 - std::cos(2.0 * std::numbers::pi * static_cast<double>(n) / static_cast<double>(count)));
  }
  return window;
}

}  // namespace

Spectrum HannSpectrum(std::span<const double> signal, double sample_rate_hz) {
  if (!std::isfinite(sample_rate_hz) || sample_rate_hz <= 0.0) {
    std::ostringstream message;
    message << "must be a finite number > 0 (got " << sample_rate_hz << ")";
    throw InputError("sample_rate_hz", message.str());
  }
  const size_t count = signal.size();
  if (count < 2) throw InputError("signal", "needs at least 2 samples for a spectrum");

  std::vector<double> windowed = PeriodicHann(count);
  for (size_t n = 0; n < count; ++n) {
    if (!std::isfinite(signal[n])) {
      throw InputError("signal", "sample " + std::to_string(n) + " is not a finite number");
    }
    windowed[n] *= signal[n];
  }

  Eigen::FFT<double> fft;
  fft.SetFlag(Eigen::FFT<double>::HalfSpectrum);
  std::vector<std::complex<double>> bins;
  fft.fwd(bins, windowed);  // bins 0..N/2

  const double window_sum = 0.5 * static_cast<double>(count);  // sum of the periodic Hann window
  const bool has_nyquist_bin = count % 2 == 0;
  Spectrum spectrum;
  spectrum.frequency_hz.resize(bins.size());
  spectrum.amplitude.resize(bins.size());
  for (size_t k = 0; k < bins.size(); ++k) {
    const bool unmirrored = k == 0 || (has_nyquist_bin && k == bins.size() - 1);
    spectrum.frequency_hz[k] = static_cast<double>(k) * sample_rate_hz / static_cast<double>(count);
    spectrum.amplitude[k] = (unmirrored ? 1.0 : 2.0) * std::abs(bins[k]) / window_sum;
  }
  return spectrum;
}

double RmsAboutMean(std::span<const double> signal) {
  double sum = 0.0, mean = 0.0;
  for (double x : signal) mean += x;
  mean /= static_cast<double>(signal.size());
  for (double x : signal) sum += (x - mean) * (x - mean);
  return std::sqrt(sum / static_cast<double>(signal.size()));
}

}  // namespace strokelab
