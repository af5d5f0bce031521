// Step 1 of the fit (fit.h), one record: its harmonics with mains hum removed, noise level, impact
// spikes and distortion (the drive is fit_drive.cc's).
#include <algorithm>
#include <cmath>
#include <complex>
#include <cstddef>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "fit_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/identify/fit.h"
#include "strokelab/signal/harmonic_fit.h"
#include "strokelab/signal/signal.h"

namespace strokelab {
namespace fit_internal {
namespace {

constexpr double kMadToSigma = 1.4826;  // sigma / MAD for normal noise

// Mains hum.
constexpr int kHumPasses = 3;                    // alternating drive-harmonic / hum fits
constexpr double kHumSeparationPerWindow = 0.5;  // hum within half a bin (1/T) of a drive harmonic: inseparable

constexpr double kLagRoundingSlack = 0.05;         // lags rounded this much worse than the best still count [samples]
constexpr double kImpactHeightFraction = 0.25;     // smaller spikes in a record are baseline artefacts
constexpr double kRelativeSeFloor = 1e-12;         // noise at least this fraction of |C_1| (rounding)

double Median(std::vector<double> values) {
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

// 1.4826 MAD about the median: the standard deviation of normal noise, blind to a minority of spikes.
double RobustSigma(std::span<const double> residual) {
  std::vector<double> values(residual.begin(), residual.end());
  const double median = Median(values);
  for (double& v : values) v = std::abs(v - median);
  return kMadToSigma * Median(std::move(values));
}

// Re-throws an InputError with the record's name in front of its field.
[[noreturn]] void RethrowForRecord(const InputError& e, const std::string& record) {
  throw InputError(record + (e.field().empty() ? "" : "." + e.field()), e.bare_message());
}

// The mains hum frequencies to remove from a response: the candidates (50 and 60 Hz, or the one the
// options name) that no drive harmonic masks (closer than half a frequency bin 1/T: inseparable).
// Removing a family that is not there costs 2 kHumOrders of the window's n >> 1 degrees of freedom.
std::vector<double> HumCandidates(double fs, const RecordAnalysis& a, const FitOptions& options) {
  std::vector<double> candidates, kept;
  if (options.mains_frequency_hz > 0)
    candidates = {options.mains_frequency_hz};
  else if (options.mains_frequency_hz == 0)
    candidates = {50.0, 60.0};
  const double window_s = static_cast<double>(a.window.size()) / fs;
  for (double hum : candidates) {
    if (hum * window_s < 2.0 || hum >= 0.5 * fs) continue;
    bool masked = false;
    for (int k = 1; k <= kHumOrders && !masked; ++k)
      for (int h = 1; h <= options.harmonic_orders && !masked; ++h)
        masked = std::abs(k * hum - h * a.drive.frequency_hz) * window_s < kHumSeparationPerWindow;
    if (!masked) kept.push_back(hum);
  }
  return kept;
}

// Harmonics not masked by a mains hum overtone (RecordAnalysis::usable). Harmonic 1 always counts:
// the drive's response dwarfs the hum there, and without it there is no record.
std::vector<bool> UsableHarmonics(double fs, const RecordAnalysis& a, const FitOptions& options) {
  std::vector<bool> usable(options.harmonic_orders, true);
  std::vector<double> mains;
  if (options.mains_frequency_hz > 0)
    mains = {options.mains_frequency_hz};
  else if (options.mains_frequency_hz == 0)
    mains = {50.0, 60.0};
  const double window_s = static_cast<double>(a.window.size()) / fs;
  for (double hum : mains)
    for (int k = 1; k <= kHumOrders; ++k)
      for (int h = 2; h <= options.harmonic_orders; ++h)
        if (std::abs(k * hum - h * a.drive.frequency_hz) * window_s < kHumSeparationPerWindow) usable[h - 1] = false;
  return usable;
}

// The white-noise level of a periodic signal with spikes: sigma = 1.4826 MAD(y[n + L] - y[n]) / sqrt(2)
// for a lag L = k fs / f rounded, k <= P/2 whole periods. The periodic part cancels (to y' times the
// rounding, far below the noise for the smooth part); the impacts spoil only the few samples near
// them, which the median ignores. The smallest sigma over the lags with the least rounding (within
// kLagRoundingSlack samples of the best) is taken, so that a period-2 response (cancelled by even k
// only) is not mistaken for noise. (A harmonic fit's residual would count the impacts' harmonics
// above N as noise; the scatter of per-period harmonic fits is spoiled by their leakage, one period
// not being a whole number of samples.) NaN when the window holds less than two periods.
double PeriodicNoiseSigma(std::span<const double> signal, double fs, double f, SampleWindow w) {
  const int max_k = static_cast<int>(w.periods) / 2;
  std::vector<double> rounding(max_k + 1, 1.0);
  double best_rounding = 1.0;
  for (int k = 1; k <= max_k; ++k) {
    const double lag = k * fs / f;
    rounding[k] = std::abs(lag - std::round(lag));
    best_rounding = std::min(best_rounding, rounding[k]);
  }
  double sigma = kNaN;
  for (int k = 1; k <= max_k; ++k) {
    if (rounding[k] > best_rounding + kLagRoundingSlack) continue;
    const size_t lag = static_cast<size_t>(std::llround(k * fs / f));
    if (lag >= w.size()) continue;
    std::vector<double> differences(w.size() - lag);
    for (size_t i = 0; i < differences.size(); ++i) differences[i] = signal[w.begin + i + lag] - signal[w.begin + i];
    const double candidate = RobustSigma(differences) / std::sqrt(2.0);
    if (!(candidate >= sigma)) sigma = candidate;
  }
  return sigma;
}

// The response's harmonic fit with mains hum taken out by alternating least squares (block
// Gauss-Seidel: the bases are nearly orthogonal over the window, so a few passes suffice): each hum
// family fitted to the response less the drive harmonics and the other families, the drive harmonics
// to the response less the hum. Fills harmonics, offset, hum, noise; returns the response with the
// hum removed (full length; the window's samples changed).
std::vector<double> FitResponse(const Recording& record, const FitOptions& options, RecordAnalysis* a) {
  const double fs = record.sample_rate_hz, f = a->drive.frequency_hz;
  const int orders = options.harmonic_orders;
  const SampleWindow w = a->window;
  std::vector<double> cleaned = record.response;
  std::vector<double> evaluated(w.size()), target(record.response.size(), 0.0);
  const std::vector<double> hums = HumCandidates(fs, *a, options);
  // While the hum is estimated the drive's harmonics are fitted up to above its highest overtone:
  // impacts put drive harmonics next to the hum's, which would otherwise leak into it.
  int hum_pass_orders = orders;
  for (double hum : hums) {
    const double highest_hz = kHumOrders * hum + kHumSeparationPerWindow * fs / static_cast<double>(w.size());
    hum_pass_orders = std::max(hum_pass_orders, static_cast<int>(std::ceil(highest_hz / f)) + 1);
  }
  hum_pass_orders = std::min(hum_pass_orders, static_cast<int>(std::ceil(0.5 * fs / f)) - 1);
  internal::HarmonicFit fit = internal::FitHarmonics(cleaned, fs, f, w, hum_pass_orders);
  internal::EvaluateHarmonics(fit, fs, f, w, evaluated);

  std::vector<std::vector<double>> hum_values(hums.size(), std::vector<double>(w.size(), 0.0));
  std::vector<double> hum_amplitudes(hums.size(), 0.0);
  for (int pass = 0; pass < kHumPasses && !hums.empty(); ++pass) {
    for (size_t j = 0; j < hums.size(); ++j) {
      for (size_t i = 0; i < w.size(); ++i) {
        double others = 0.0;
        for (size_t k = 0; k < hums.size(); ++k) others += k == j ? 0.0 : hum_values[k][i];
        target[w.begin + i] = record.response[w.begin + i] - evaluated[i] - others;
      }
      const int hum_orders = std::max(1, std::min(kHumOrders, static_cast<int>(std::floor(0.5 * fs / hums[j] - 1e-9))));
      const internal::HarmonicFit hum_fit = internal::FitHarmonics(target, fs, hums[j], w, hum_orders);
      internal::EvaluateHarmonics(internal::HarmonicFit{0.0, hum_fit.amplitudes}, fs, hums[j], w, hum_values[j]);
      hum_amplitudes[j] = std::abs(hum_fit.amplitudes[0]);
    }
    for (size_t i = 0; i < w.size(); ++i) {
      double hum = 0.0;
      for (const std::vector<double>& values : hum_values) hum += values[i];
      cleaned[w.begin + i] = record.response[w.begin + i] - hum;
    }
    fit = internal::FitHarmonics(cleaned, fs, f, w, hum_pass_orders);
    internal::EvaluateHarmonics(fit, fs, f, w, evaluated);
  }
  if (hum_pass_orders != orders) {
    fit = internal::FitHarmonics(cleaned, fs, f, w, orders);
    internal::EvaluateHarmonics(fit, fs, f, w, evaluated);
  }
  for (size_t j = 0; j < hums.size(); ++j) {
    if (hum_amplitudes[j] > a->hum_amplitude) a->hum_amplitude = hum_amplitudes[j], a->hum_frequency_hz = hums[j];
  }
  a->response_offset = fit.offset;
  a->harmonics.resize(orders);
  for (int h = 1; h <= orders; ++h)
    a->harmonics[h - 1] = fit.amplitudes[h - 1] * std::polar(1.0, -h * a->drive.phase_rad);
  const double n = static_cast<double>(w.size());
  a->noise_rms = PeriodicNoiseSigma(cleaned, fs, f, w);
  if (!(a->noise_rms > 0.0)) {
    // Too short for the lag (or noise-free): the robust spread of the harmonic fit's residual.
    std::vector<double> residual(w.size());
    for (size_t i = 0; i < w.size(); ++i) residual[i] = cleaned[w.begin + i] - evaluated[i];
    a->noise_rms = RobustSigma(residual);
  }
  // A noise-free (simulated) record: a floor at rounding level keeps the weights finite.
  a->noise_rms = std::max(a->noise_rms, kRelativeSeFloor * std::abs(fit.amplitudes[0]));
  a->harmonic_se = a->noise_rms * std::sqrt(2.0 / n);
  return cleaned;
}

// Where impacts show as spikes: the force or acceleration itself, else its derivatives by central
// differences (velocity once, displacement twice) [acceleration units].
std::vector<double> SpikeSignal(std::vector<double> signal, ResponseKind kind, double fs) {
  const int derivatives = kind == ResponseKind::kVelocity ? 1 : kind == ResponseKind::kDisplacement ? 2 : 0;
  for (int d = 0; d < derivatives && signal.size() >= 3; ++d) {
    std::vector<double> out(signal.size());
    for (size_t i = 1; i + 1 < signal.size(); ++i) out[i] = 0.5 * fs * (signal[i + 1] - signal[i - 1]);
    out.front() = out[1];
    out.back() = out[out.size() - 2];
    signal = std::move(out);
  }
  return signal;
}

// The spikes of impacts: those at least kImpactHeightFraction of the record's largest. The rest are
// the baseline's: DetectSpikes' smooth baseline (a few harmonics) cannot follow the step that an
// impact leaves in the force (the damping force c_p x' flips with the velocity), and flags it.
std::vector<Spike> ImpactSpikes(std::vector<Spike> spikes) {
  double largest = 0.0;
  for (const Spike& s : spikes) largest = std::max(largest, std::abs(s.peak_height));
  std::erase_if(spikes, [&](const Spike& s) { return std::abs(s.peak_height) < kImpactHeightFraction * largest; });
  return spikes;
}

}  // namespace
}  // namespace fit_internal

RecordAnalysis AnalyseRecord(const Recording& record, ResponseKind kind, const FitOptions& options) {
  using fit_internal::Complex, fit_internal::FitResponse, fit_internal::Format, fit_internal::ImpactSpikes,
      fit_internal::RequirePositiveFinite, fit_internal::RethrowForRecord, fit_internal::SpikeSignal,
      fit_internal::UsableHarmonics;
  Validate(options);
  const std::string name = record.name.empty() ? "record" : record.name;
  if (record.broadband) throw InputError(name, "is broadband: only stepped-sine records are fitted");
  if (record.voltage_v.size() != record.response.size())
    throw InputError(name, "has " + std::to_string(record.voltage_v.size()) + " voltage samples but " +
                               std::to_string(record.response.size()) + " response samples");
  RecordAnalysis a;
  a.name = record.name;
  a.nominal_frequency_hz = record.nominal_frequency_hz;
  a.nominal_amplitude_v = record.nominal_amplitude_v;
  a.sample_rate_hz = record.sample_rate_hz;
  try {
    RequirePositiveFinite(record.sample_rate_hz, "sample_rate_hz");
    a.drive = EstimateDrive(record.voltage_v, record.sample_rate_hz, record.nominal_frequency_hz);
    const double fs = record.sample_rate_hz, f = a.drive.frequency_hz;
    const size_t n = record.size();
    // Whole periods of the estimated drive at the record's end (half a sample of slack).
    const double periods = std::floor((static_cast<double>(n) + 0.5) * f / fs);
    if (periods < 2.0) throw InputError("voltage", "holds less than two periods of the drive at " + Format(f) + " Hz");
    const size_t count = std::min(n, static_cast<size_t>(std::llround(periods * fs / f)));
    a.window = SampleWindow{n - count, n, periods};
    if (options.harmonic_orders * f >= 0.5 * fs)
      throw InputError("harmonic_orders", "harmonic " + std::to_string(options.harmonic_orders) + " of " + Format(f) +
                                              " Hz is not below the Nyquist frequency " + Format(0.5 * fs) + " Hz");
    const std::vector<double> cleaned = FitResponse(record, options, &a);
    a.usable = UsableHarmonics(fs, a, options);
    a.frf = Complex(0.0, 1.0) * a.harmonics[0] / a.drive.amplitude_v;  // C_1(v) = V e^{j(phi - pi/2)}
    double higher = 0.0;
    for (size_t h = 1; h < a.harmonics.size(); ++h) higher += std::norm(a.harmonics[h]);
    const double noise_share = 2.0 * a.harmonic_se * a.harmonic_se * static_cast<double>(a.harmonics.size() - 1);
    a.distortion = std::sqrt(std::max(0.0, higher - noise_share)) / std::abs(a.harmonics[0]);
    a.spikes = ImpactSpikes(DetectSpikes(SpikeSignal(cleaned, kind, fs), fs, f, a.window, options.spikes));
    a.clear = a.spikes.empty() && a.distortion < options.max_clear_distortion;
  } catch (const InputError& e) {
    RethrowForRecord(e, name);
  }
  if (!(std::abs(a.harmonics[0]) > 0.0) || !std::isfinite(a.distortion))
    throw InputError(name, "has no response at the drive frequency");
  return a;
}

}  // namespace strokelab
