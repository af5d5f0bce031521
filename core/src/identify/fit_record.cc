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
#include "strokelab/base/chi_square.h"
#include "strokelab/base/errors.h"
#include "strokelab/identify/fit.h"
#include "strokelab/signal/harmonic_fit.h"
#include "strokelab/signal/signal.h"

namespace strokelab {
namespace fit_internal {
namespace {

constexpr double kMadToSigma = 1.4826;  // sigma / MAD for normal noise

// Mains hum.
constexpr double kHumSeparationPerWindow = 0.5;  // hum within half a bin (1/T) of a drive harmonic: inseparable
constexpr double kUnfollowedSigmas = 8.0;        // a departure from the drive's harmonics beyond noise (as a spike's)
constexpr double kMaxUnfollowedShare = 0.5;      // more than this left out: the hum is fitted over every sample

constexpr double kLagRoundingSlack = 0.05;         // lags rounded this much worse than the best still count [samples]
constexpr double kImpactHeightFraction = 0.25;     // smaller spikes in a record are baseline artefacts
constexpr double kRelativeSeFloor = 1e-12;         // noise at least this fraction of |C_1| (rounding)

// Subharmonic responses (ResponsePeriods): periods of 2 and 3 drive periods are looked for, and one is
// taken when its subharmonics' chi-square passes its 1e-6 tail under noise alone.
constexpr int kMaxResponsePeriods = 3;
constexpr double kSubharmonicFalseAlarm = 1e-6;
// Subharmonics below this share of the fundamental (per harmonic) are not looked for. Impacts sampled
// at a rate that is no multiple of the drive's frequency put content between the drive's harmonics (the
// spike moves on the sample grid from period to period), which no response period removes: measured
// up to 3.5e-4 of |C_1| per harmonic at 51.2 kHz (fit_test.cc's campaign), 3e-3 (an acceleration channel
// with contact damping, tools/gen2) and 5.5e-3 at 8192 Hz (foreign_formats_test.cc's). True period-2
// responses measured 2.3e-2 (a cubic spring at 9 Hz) to 0.49 (alternating impacts on two stops). One of
// this size leaks some 6 % of it into the drive's neighbouring harmonics over an odd number of periods
// (the first sidelobe of half a harmonic), 6e-4 of |C_1|: below a rig's noise there at most levels.
constexpr double kSubharmonicFloor = 1e-2;
constexpr double kMainsGuardBins = 1.5;  // subharmonics this close to a mains overtone are not counted

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

// The mains frequencies a record's hum may come from: the one the options name, or 50 and 60 Hz.
std::vector<double> MainsCandidates(const FitOptions& options) {
  if (options.mains_frequency_hz > 0) return {options.mains_frequency_hz};
  if (options.mains_frequency_hz == 0) return {50.0, 60.0};
  return {};
}

// Whether `frequency_hz` lies within `bins` frequency bins (1 / window_s) of a mains overtone.
bool NearMains(double frequency_hz, double window_s, double bins, const FitOptions& options) {
  for (double hum : MainsCandidates(options))
    for (int k = 1; k <= kHumOrders; ++k)
      if (std::abs(k * hum - frequency_hz) * window_s < bins) return true;
  return false;
}

// The mains hum frequencies to remove from a response: the candidates that the drive's fundamental
// does not mask (closer than half a frequency bin 1/T: inseparable). Removing a family that is not
// there costs 2 kHumOrders of the window's n >> 1 degrees of freedom. A higher drive harmonic does not
// mask it: that harmonic is left out of every residual (UsableHarmonics), and a hum left in the record
// leaked into the harmonics beside it (gen2's velocity control 9601: 50 Hz hum of 2.5 times the noise
// beside harmonic 7 of 7 Hz over 3 periods left its 7 Hz records 8-10 times the noise in harmonic 8,
// and the control "unexplained"). Nor do a subharmonic response's harmonics: fitted beside them, the
// hum takes its share of what they cannot tell apart, and neither leaks into the drive's harmonics.
std::vector<double> HumCandidates(double fs, const RecordAnalysis& a, const FitOptions& options) {
  std::vector<double> kept;
  const double window_s = static_cast<double>(a.window.size()) / fs;
  for (double hum : MainsCandidates(options)) {
    if (hum * window_s < 2.0 || hum >= 0.5 * fs) continue;
    bool masked = false;
    for (int k = 1; k <= kHumOrders && !masked; ++k)
      masked = std::abs(k * hum - a.drive.frequency_hz) * window_s < kHumSeparationPerWindow;
    if (!masked) kept.push_back(hum);
  }
  return kept;
}

// Harmonics not masked by a mains hum overtone (RecordAnalysis::usable). Harmonic 1 always counts:
// the drive's response dwarfs the hum there, and without it there is no record.
std::vector<bool> UsableHarmonics(double fs, const RecordAnalysis& a, const FitOptions& options) {
  std::vector<bool> usable(options.harmonic_orders, true);
  const double window_s = static_cast<double>(a.window.size()) / fs;
  for (int h = 2; h <= options.harmonic_orders; ++h)
    if (NearMains(h * a.drive.frequency_hz, window_s, kHumSeparationPerWindow, options)) usable[h - 1] = false;
  return usable;
}

// The white-noise level of a periodic signal with spikes: sigma = 1.4826 MAD(y[n + L] - y[n]) / sqrt(2)
// for a lag L = k fs / f rounded, k <= P/2 whole periods of the signal (f its fundamental, of the
// response's own period: FitResponse). The periodic part cancels (to y' times the
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

// The samples of window w where the response departs from its drive harmonics fitted so far
// (`evaluated`, the first `orders` of them) by more than kUnfollowedSigmas robust standard deviations,
// widened by half the period of the highest (what the truncated series cannot resolve either side):
// 1 for each, or empty where there are none. There an impact's content runs far above the harmonics
// fitted. A hum over a window of no whole number of its cycles is not orthogonal to those higher
// harmonics, and they leaked into it: on gen2 9706 (acceleration at 44.1 kHz, 7.5 Hz, 0.45 V, 1.5 s)
// a 50 Hz hum of 0.074 m/s^2 was found where there was none, and taken out of harmonics 6 and 7; with
// these samples left out it comes out at the noise (1.6e-6 V against 2.8e-6).
std::vector<char> UnfollowedSamples(std::span<const double> response, SampleWindow w,
                                    std::span<const double> evaluated, double fs, double f, int orders) {
  std::vector<double> residual(w.size());
  for (size_t i = 0; i < w.size(); ++i) residual[i] = response[w.begin + i] - evaluated[i];
  const double limit = kUnfollowedSigmas * RobustSigma(residual);
  const auto guard = static_cast<size_t>(std::ceil(0.5 * fs / (orders * f)));
  std::vector<char> unfollowed(w.size(), 0);
  size_t count = 0;
  for (size_t i = 0; i < w.size(); ++i) {
    if (!(std::abs(residual[i]) > limit)) continue;
    const size_t last = std::min(w.size() - 1, i + guard);
    for (size_t k = i > guard ? i - guard : 0; k <= last; ++k) {
      count += unfollowed[k] == 0;
      unfollowed[k] = 1;
    }
  }
  if (count == 0 || static_cast<double>(count) > kMaxUnfollowedShare * static_cast<double>(w.size())) return {};
  return unfollowed;
}

// The response's harmonic fit with mains hum taken out: the drive's harmonics and each hum family
// fitted together (FitHarmonicFamilies). Fitted in turn, three passes left a 50 Hz hum beside harmonic 7
// of 7 Hz over three periods (0.43 frequency bins apart) half removed, and what was left leaked into
// harmonics 6 and 8: a correct model came out "unexplained" at 1.4-1.5 times the noise (stepped
// campaigns of the paper's model, 0.5 s records, 0.2 mV noise and 0.5 mV hum, seeds 1 and 2).
// Fills harmonics, offset, hum, noise; returns the response with the hum removed (full length; the
// window's samples changed). The hum is fitted without the samples that the drive's harmonics do not
// follow (UnfollowedSamples); the drive's harmonics are then fitted again over every sample of the
// response less the hum. A response of `response_periods` drive periods is fitted by the harmonics of
// its own period, so that its subharmonics leak neither into the hum nor into the drive's harmonics,
// which are every response_periods-th of them.
std::vector<double> FitResponse(const Recording& record, const FitOptions& options, int response_periods,
                                RecordAnalysis* a) {
  const double fs = record.sample_rate_hz, f = a->drive.frequency_hz / response_periods;
  const int orders = options.harmonic_orders * response_periods;
  const SampleWindow w = a->window;
  std::vector<double> cleaned = record.response;
  std::vector<double> evaluated(w.size());
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
  std::vector<char> unfollowed =
      hums.empty() ? std::vector<char>{} : UnfollowedSamples(record.response, w, evaluated, fs, f, hum_pass_orders);

  std::vector<double> hum_amplitudes(hums.size(), 0.0);
  if (!hums.empty()) {
    std::vector<internal::HarmonicFamily> families{{f, hum_pass_orders}};
    for (double hum : hums)
      families.push_back({hum, std::max(1, std::min(kHumOrders, static_cast<int>(std::floor(0.5 * fs / hum - 1e-9))))});
    std::vector<internal::HarmonicFit> fits;
    try {
      fits = internal::FitHarmonicFamilies(record.response, fs, families, w, unfollowed);
    } catch (const NumericalError&) {
      // Gaps too wide for that many sinusoids on what is left: every sample, the leak taken.
      unfollowed.clear();
      fits = internal::FitHarmonicFamilies(record.response, fs, families, w);
    }
    std::vector<double> hum_values(w.size());
    for (size_t j = 0; j < hums.size(); ++j) {
      internal::EvaluateHarmonics(internal::HarmonicFit{0.0, fits[j + 1].amplitudes}, fs, hums[j], w, hum_values);
      for (size_t i = 0; i < w.size(); ++i) cleaned[w.begin + i] -= hum_values[i];
      hum_amplitudes[j] = std::abs(fits[j + 1].amplitudes[0]);
    }
    fit = fits[0];
    internal::EvaluateHarmonics(fit, fs, f, w, evaluated);
  }
  if (hum_pass_orders != orders || !unfollowed.empty()) {
    fit = internal::FitHarmonics(cleaned, fs, f, w, orders);
    internal::EvaluateHarmonics(fit, fs, f, w, evaluated);
  }
  a->hum_amplitude = a->hum_frequency_hz = 0.0;
  for (size_t j = 0; j < hums.size(); ++j) {
    if (hum_amplitudes[j] > a->hum_amplitude) a->hum_amplitude = hum_amplitudes[j], a->hum_frequency_hz = hums[j];
  }
  a->response_offset = fit.offset;
  a->harmonics.resize(options.harmonic_orders);
  for (int h = 1; h <= options.harmonic_orders; ++h)
    a->harmonics[h - 1] = fit.amplitudes[h * response_periods - 1] * std::polar(1.0, -h * a->drive.phase_rad);
  const double n = static_cast<double>(w.size());
  // Lags of whole drive periods cancel a response of one, lags of its own period any response (with
  // the least rounding among fewer lags); neither leaves less than the noise, so the smaller counts.
  a->noise_rms = PeriodicNoiseSigma(cleaned, fs, a->drive.frequency_hz, w);
  if (response_periods > 1) {
    const SampleWindow own{w.begin, w.end, w.periods / response_periods};
    a->noise_rms = std::min(a->noise_rms, PeriodicNoiseSigma(cleaned, fs, f, own));
  }
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

// The last `periods` whole drive periods of a record of n samples (half a sample of slack).
SampleWindow LastPeriods(size_t n, double fs, double f, double periods) {
  const size_t count = std::min(n, static_cast<size_t>(std::llround(periods * fs / f)));
  return SampleWindow{n - count, n, periods};
}

// The response's period in drive periods: 1, or P = 2 or 3 where the harmonics of f / P that are no
// harmonic of f stand out of the noise. They are fitted beside the drive's harmonics over the window's
// last whole multiple of P periods, where every harmonic of f / P is orthogonal to the others; their
// chi-square (Re and Im over the standard error sigma sqrt(2 / n), sigma the noise level from lags of
// whole multiples of P periods, which cancel such a response; at least kSubharmonicFloor |C_1|) must
// pass its kSubharmonicFalseAlarm tail. Of two such P, the one whose subharmonics carry more of the
// signal beyond noise: a period-2 response leaks into the thirds too, and a period-3 one into the
// halves, but less than into their own. Subharmonics within kMainsGuardBins of a mains overtone are left out: hum that
// was there, or that its removal (FitResponse) put there, is no subharmonic. Over a window that is no
// whole multiple of P periods, a period-P response's subharmonics leak into the drive's harmonics,
// which a model's periodic orbit does not have.
int ResponsePeriods(std::span<const double> cleaned, double fs, double f, SampleWindow w, const FitOptions& options) {
  const int orders = options.harmonic_orders;
  int best = 1;
  double best_excess = 0.0;
  for (int p = 2; p <= kMaxResponsePeriods; ++p) {
    const double periods = p * std::floor(w.periods / p);
    if (periods < 2.0 * p) continue;
    const SampleWindow wp = LastPeriods(w.end, fs, f, periods);
    const internal::HarmonicFit fit = internal::FitHarmonics(cleaned, fs, f / p, wp, orders * p);
    const double noise_rms = PeriodicNoiseSigma(cleaned, fs, f / p, SampleWindow{wp.begin, wp.end, periods / p});
    const double se = std::max(noise_rms * std::sqrt(2.0 / static_cast<double>(wp.size())),
                               kSubharmonicFloor * std::abs(fit.amplitudes[p - 1]));
    if (!(se > 0.0)) continue;
    double chi2 = 0.0;
    int dof = 0;
    const double window_s = static_cast<double>(wp.size()) / fs;
    for (int k = 1; k <= orders * p; ++k) {
      if (k % p == 0 || NearMains(k * f / p, window_s, kMainsGuardBins, options)) continue;
      chi2 += std::norm(fit.amplitudes[k - 1]) / (se * se);
      dof += 2;
    }
    const double excess = chi2 - dof;
    if (ChiSquareUpperTail(chi2, dof) < kSubharmonicFalseAlarm && excess > best_excess) best = p, best_excess = excess;
  }
  return best;
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
      fit_internal::LastPeriods, fit_internal::RequirePositiveFinite, fit_internal::ResponsePeriods,
      fit_internal::RethrowForRecord, fit_internal::SpikeSignal, fit_internal::UsableHarmonics;
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
    a.window = LastPeriods(n, fs, f, periods);
    if (options.harmonic_orders * f >= 0.5 * fs)
      throw InputError("harmonic_orders", "harmonic " + std::to_string(options.harmonic_orders) + " of " + Format(f) +
                                              " Hz is not below the Nyquist frequency " + Format(0.5 * fs) + " Hz");
    std::vector<double> cleaned = FitResponse(record, options, 1, &a);
    // A subharmonic response is analysed over whole periods of its own (ResponsePeriods).
    const int response_periods = ResponsePeriods(cleaned, fs, f, a.window, options);
    a.response_periods = response_periods;
    if (response_periods > 1) {
      a.window = LastPeriods(n, fs, f, response_periods * std::floor(periods / response_periods));
      cleaned = FitResponse(record, options, response_periods, &a);
    }
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
