// Broadband drives (strokelab/data/excitation.h).
#include "strokelab/data/excitation.h"

#include <cmath>
#include <complex>
#include <numbers>
#include <unsupported/Eigen/FFT>

#include "format_number.h"

namespace strokelab {
namespace {

using data_internal::Num;
constexpr double kTwoPi = 2.0 * std::numbers::pi;

// The smallest 2^a 3^b 5^c >= n: a length the FFT splits into small radices.
size_t FftFriendlySize(size_t n) {
  for (size_t m = std::max<size_t>(n, 1);; ++m) {
    size_t r = m;
    for (size_t p : {2, 3, 5})
      while (r % p == 0) r /= p;
    if (r == 1) return m;
  }
}

// One period of sum_k A_k cos(2 pi k t / T + phi_k) over the lines k in [first, last] (every
// `stride`-th), at N = T fs samples, by the inverse FFT; A_k = 1 (multisine) or Rayleigh (noise),
// phi_k uniform. Scaled to the rms level afterwards.
std::vector<double> LineSum(size_t samples, size_t first, size_t last, size_t stride, bool rayleigh, double level_v_rms,
                            const std::function<double()>& uniform) {
  std::vector<std::complex<double>> spectrum(samples / 2 + 1, 0.0);
  for (size_t k = first; k <= last && k < spectrum.size(); k += stride) {
    const double amplitude = rayleigh ? std::sqrt(-2.0 * std::log(1.0 - uniform())) : 1.0;
    spectrum[k] = std::polar(amplitude, kTwoPi * uniform());
  }
  Eigen::FFT<double> fft;
  fft.SetFlag(Eigen::FFT<double>::HalfSpectrum);
  std::vector<double> signal;
  fft.inv(signal, spectrum, static_cast<Eigen::Index>(samples));
  double sum_squares = 0.0;
  for (double v : signal) sum_squares += v * v;
  const double rms = std::sqrt(sum_squares / static_cast<double>(signal.size()));
  for (double& v : signal) v *= rms > 0 ? level_v_rms / rms : 0.0;
  return signal;
}

// Line indices k (lines k / T) within [low, high] Hz.
void LinesInBand(double low_hz, double high_hz, double length_s, size_t* first, size_t* last) {
  *first = static_cast<size_t>(std::max(1.0, std::ceil(low_hz * length_s - 1e-9)));
  *last = static_cast<size_t>(std::max(0.0, std::floor(high_hz * length_s + 1e-9)));
}

}  // namespace

Excitation ParseExcitation(std::string_view text) {
  if (text == "stepped-sine") return Excitation::kSteppedSine;
  if (text == "multisine") return Excitation::kMultisine;
  if (text == "noise") return Excitation::kNoise;
  if (text == "sweep") return Excitation::kSweep;
  throw InputError("excitation",
                   "unknown excitation '" + std::string(text) + "' (known: stepped-sine, multisine, noise, sweep)");
}

const char* ToString(Excitation excitation) {
  switch (excitation) {
    case Excitation::kSteppedSine: return "stepped-sine";
    case Excitation::kMultisine: return "multisine";
    case Excitation::kNoise: return "noise";
    case Excitation::kSweep: return "sweep";
  }
  return "?";
}

std::optional<FieldError> BroadbandSignal::IsValid(double sample_rate_hz) const {
  if (!std::isfinite(band_low_hz) || band_low_hz < 0)
    return FieldError{"band_low_hz", "must be a finite number >= 0, got " + Num(band_low_hz)};
  if (!std::isfinite(band_high_hz) || !(band_high_hz > band_low_hz))
    return FieldError{"band_high_hz", "must be a finite number above the band's low edge, got " + Num(band_high_hz)};
  if (!(band_high_hz < 0.5 * sample_rate_hz))
    return FieldError{"band_high_hz", Num(band_high_hz) + " Hz is not below the Nyquist frequency " +
                                          Num(0.5 * sample_rate_hz) + " Hz"};
  if (!std::isfinite(level_v_rms) || level_v_rms < 0)
    return FieldError{"level_v_rms", "must be a finite number >= 0, got " + Num(level_v_rms)};
  if (!std::isfinite(period_s) || !(period_s > 0)) return FieldError{"period_s", "must be a finite number > 0"};
  if (excitation == Excitation::kSweep && !(band_low_hz > 0))
    return FieldError{"band_low_hz", "a logarithmic sweep starts above 0 Hz"};
  if (excitation == Excitation::kMultisine) {
    const double samples = period_s * sample_rate_hz;
    if (std::abs(samples - std::round(samples)) > 1e-6 * samples)
      return FieldError{"period_s", "must hold a whole number of samples (" + Num(samples) + " at " +
                                        Num(sample_rate_hz) + " Hz), so that the multisine repeats exactly"};
    size_t first = 0, last = 0;
    LinesInBand(band_low_hz, band_high_hz, period_s, &first, &last);
    bool any = false;
    for (size_t k = first; k <= last && !any; ++k) any = !odd_grid || k % 2 == 1;
    if (!any)
      return FieldError{"band_low_hz", "the band " + Num(band_low_hz) + ".." + Num(band_high_hz) +
                                           " Hz holds no line of the multisine's grid 1 / " + Num(period_s) + " s"};
  }
  return std::nullopt;
}

std::vector<double> BroadbandVoltage(const BroadbandSignal& signal, double sample_rate_hz, double t0_s, size_t count,
                                     double length_s, const std::function<double()>& uniform) {
  if (std::optional<FieldError> error = signal.IsValid(sample_rate_hz)) throw InputError(error->field, error->message);
  std::vector<double> out(count);
  if (signal.excitation == Excitation::kMultisine) {
    const auto period = static_cast<size_t>(std::llround(signal.period_s * sample_rate_hz));
    size_t first = 0, last = 0;
    LinesInBand(signal.band_low_hz, signal.band_high_hz, signal.period_s, &first, &last);
    if (signal.odd_grid && first % 2 == 0) ++first;
    const std::vector<double> one = LineSum(period, first, last, signal.odd_grid ? 2 : 1, false, signal.level_v_rms, uniform);
    const auto shift = static_cast<long long>(std::llround(t0_s * sample_rate_hz));
    const auto p = static_cast<long long>(period);
    for (size_t n = 0; n < count; ++n) out[n] = one[static_cast<size_t>((((shift + static_cast<long long>(n)) % p) + p) % p)];
  } else if (signal.excitation == Excitation::kNoise) {
    const size_t samples = FftFriendlySize(std::max(count, static_cast<size_t>(std::llround(length_s * sample_rate_hz))));
    const double grid_length_s = static_cast<double>(samples) / sample_rate_hz;
    size_t first = 0, last = 0;
    LinesInBand(signal.band_low_hz, signal.band_high_hz, grid_length_s, &first, &last);
    const std::vector<double> noise = LineSum(samples, first, last, 1, true, signal.level_v_rms, uniform);
    std::copy_n(noise.begin(), count, out.begin());
  } else if (signal.excitation == Excitation::kSweep) {
    const double f1 = signal.band_low_hz, f2 = signal.band_high_hz, length = signal.period_s;
    const double rate = std::log(f2 / f1) / length, amplitude = std::sqrt(2.0) * signal.level_v_rms;
    const double phase_at_end = kTwoPi * f1 / rate * (std::exp(rate * length) - 1.0);
    for (size_t n = 0; n < count; ++n) {
      const double t = t0_s + static_cast<double>(n) / sample_rate_hz;
      const double phase = t < 0        ? kTwoPi * f1 * t
                           : t < length ? kTwoPi * f1 / rate * (std::exp(rate * t) - 1.0)
                                        : phase_at_end + kTwoPi * f2 * (t - length);
      out[n] = amplitude * std::sin(phase);
    }
  } else {
    throw InputError("excitation", "a stepped sine is not a broadband signal");
  }
  return out;
}

}  // namespace strokelab
