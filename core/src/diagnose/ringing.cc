// The residual's ringing after impacts (open_world.h, FindRinging): "rings at about N Hz after every
// impact, decaying in T ms", from the record's time series, where the fitted harmonics do not reach.
#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <string>
#include <vector>

#include "diagnose_internal.h"
#include "strokelab/identify/extended_fit.h"
#include "strokelab/identify/fit_orbit.h"
#include "strokelab/signal/harmonic_fit.h"

namespace strokelab::internal {
namespace {

constexpr double kRingTwoPi = 2.0 * std::numbers::pi;
constexpr double kMaxRingShareOfFs = 0.125;  // ring frequencies searched up to fs / 8
constexpr int kZeroPadding = 4;           // frequency grid: 1 / (4 T) over a segment of T
constexpr double kMaxGridPoints = 4096;   // ... at most this many
constexpr double kFirstSwingToNoise = 5;  // a ring's first cycle pair this far above its noise
constexpr double kSwingToNoise = 3;       // the cycle pairs whose amplitude enters the decay fit
constexpr int kMinSwings = 3;             // cycle pairs above noise for a ring
constexpr double kDecayedShare = 0.1;     // cycle pairs below this share of the first are left out
constexpr double kSameImpact = 0.02;      // impacts this close in drive phase [periods] are one
constexpr double kBeforeNextImpact = 0.9;  // the segment ends this share of the way to the next impact
constexpr double kSameRing = 0.05;         // rings within this share of one frequency are one mode's

// x minus its least-squares fit of `orders` harmonics of `frequency_hz` (and the offset) over `window`.
void RemoveHarmonics(std::vector<double>& x, double fs, double frequency_hz, SampleWindow window, int orders) {
  if (!(frequency_hz > 0) || orders * frequency_hz >= 0.5 * fs) return;
  const HarmonicFit fit = FitHarmonics(x, fs, frequency_hz, window, orders);
  std::vector<double> curve(window.size());
  EvaluateHarmonics(fit, fs, frequency_hz, window, curve);
  for (size_t i = 0; i < curve.size(); ++i) x[window.begin + i] -= curve[i];
}

// (2 / n) sum_k s_k e^{-j w t_k} over [begin, begin + n), t_k = k dt: the complex amplitude there.
std::complex<double> ProjectionAt(const std::vector<double>& s, size_t begin, size_t n, double w, double dt) {
  std::complex<double> sum = 0.0, z = std::polar(1.0, -w * dt * static_cast<double>(begin));
  const std::complex<double> step = std::polar(1.0, -w * dt);
  for (size_t k = 0; k < n; ++k, z *= step) sum += s[begin + k] * z;
  return 2.0 * sum / static_cast<double>(n);
}

// The ring's complex amplitude over successive windows of `pair` samples from the segment's start,
// while it stays above kSwingToNoise x `noise` and above kDecayedShare of the first (later windows hold
// more of the rest of the residual than of the ring).
std::vector<std::complex<double>> Swings(const std::vector<double>& segment, size_t pair, double w, double dt,
                                         double noise) {
  std::vector<std::complex<double>> swings;
  for (size_t begin = 0; begin + pair <= segment.size(); begin += pair) {
    const std::complex<double> a = ProjectionAt(segment, begin, pair, w, dt);
    if (std::abs(a) < kSwingToNoise * noise || (!swings.empty() && std::abs(a) < kDecayedShare * std::abs(swings[0])))
      break;
    swings.push_back(a);
  }
  return swings;
}

}  // namespace

void FindRinging(const Recording& record, const RecordAnalysis& a, const ActuatorModel& model, ResponseKind kind,
                 int orders, Unexplained::Place* place) {
  if (a.spikes.empty() || !(a.window.periods >= 1)) return;
  const std::optional<Prediction> p = Predict(model, a, kind, orders);
  if (!p || p->orbit.anchor.period != 1) return;
  const std::vector<double> modelled = OrbitOnRecordGrid(model, a, p->orbit, kind);
  if (modelled.size() < a.window.end || record.response.size() < a.window.end) return;
  const double fs = a.sample_rate_hz, f = a.drive.frequency_hz;
  std::vector<double> residual(a.window.end, 0.0);
  for (size_t n = a.window.begin; n < a.window.end; ++n) residual[n] = record.response[n] - modelled[n];
  // The drive's harmonics 1..orders and the offset (what the harmonics already say). The mains hum is
  // left: removing it would notch a ring near one of its overtones, and averaging over the drive's
  // periods cancels it unless it is a multiple of the drive frequency (tested below).
  RemoveHarmonics(residual, fs, f, a.window, orders);

  // The residual averaged over the drive periods at the samples' resolution: bins of one drive phase.
  const auto bins = static_cast<size_t>(std::floor(fs / f));
  std::vector<double> average(bins, 0.0);
  std::vector<int> count(bins, 0);
  auto bin_of = [&](double n) {
    const double cycles = n * f / fs;
    return std::min(bins - 1, static_cast<size_t>((cycles - std::floor(cycles)) * static_cast<double>(bins)));
  };
  for (size_t n = a.window.begin; n < a.window.end; ++n) {
    const size_t b = bin_of(static_cast<double>(n));
    average[b] += residual[n], ++count[b];
  }
  double mean_count = 0;
  for (size_t b = 0; b < bins; ++b) {
    if (count[b] > 0) average[b] /= count[b];
    mean_count += count[b];
  }
  mean_count /= static_cast<double>(bins);
  const double bin_noise = a.noise_rms / std::sqrt(std::max(1.0, mean_count));
  const double dt = 1.0 / (f * static_cast<double>(bins));  // one bin's time

  // After the strongest impact: from the end of its contact to the next impact of the period (the
  // impacts' drive phases, those within kSameImpact of a period taken as one).
  const Spike& strongest = *std::max_element(a.spikes.begin(), a.spikes.end(), [](const Spike& x, const Spike& y) {
    return std::abs(x.peak_height) < std::abs(y.peak_height);
  });
  const size_t impact_bin = bin_of(static_cast<double>(strongest.peak_index));
  size_t next = bins;  // bins from the strongest impact to the next other impact
  for (const Spike& s : a.spikes) {
    const size_t ahead = (bin_of(static_cast<double>(s.peak_index)) + bins - impact_bin) % bins;
    if (static_cast<double>(ahead) > kSameImpact * static_cast<double>(bins)) next = std::min(next, ahead);
  }
  const auto skip = static_cast<size_t>(std::ceil(std::max(0.0, strongest.end_s - strongest.peak_time_s) / dt)) + 1;
  const auto span = static_cast<size_t>(kBeforeNextImpact * static_cast<double>(next));
  if (span <= skip + 8) return;
  std::vector<double> segment(span - skip);
  for (size_t k = 0; k < segment.size(); ++k) segment[k] = average[(impact_bin + skip + k) % bins];

  // The strongest frequency above the fitted harmonics (Hann window, zero-padded grid).
  const double duration_s = static_cast<double>(segment.size()) * dt;
  std::vector<double> windowed(segment.size());
  for (size_t k = 0; k < segment.size(); ++k)
    windowed[k] = segment[k] * 0.5 * (1.0 - std::cos(kRingTwoPi * static_cast<double>(k) / static_cast<double>(segment.size())));
  // (At most kMaxGridPoints frequencies: a slow drive's long segment would otherwise scan ~1e4 of them;
  // the phase drift below refines the frequency anyway.)
  const double f_low = (orders + 0.5) * f, f_high = kMaxRingShareOfFs * fs;
  const double df = std::max(1.0 / (kZeroPadding * duration_s), (f_high - f_low) / kMaxGridPoints);
  double ring_hz = 0.0, best = 0.0;
  for (double fr = f_low; fr <= f_high; fr += df) {
    const double amplitude = std::abs(ProjectionAt(windowed, 0, windowed.size(), kRingTwoPi * fr, dt));
    if (amplitude > best) best = amplitude, ring_hz = fr;
  }
  if (!(ring_hz > 0)) return;
  // A steady hum overtone is no ring: near one, the swing must stand well clear of the hum.
  for (int k = 1; k <= kHumOrders && a.hum_frequency_hz > 0; ++k)
    if (std::abs(ring_hz - k * a.hum_frequency_hz) < 2 * df && best < kFirstSwingToNoise * a.hum_amplitude) return;

  // Over successive pairs of cycles: the phase's drift refines the frequency (the grid's and the
  // window's bias), then the amplitude's logarithm gives the decay.
  const auto pair = std::max<size_t>(8, static_cast<size_t>(std::round(2.0 / (ring_hz * dt))));
  const double swing_noise = bin_noise * std::sqrt(2.0 / static_cast<double>(pair));  // of each quadrature
  std::vector<std::complex<double>> swings = Swings(segment, pair, kRingTwoPi * ring_hz, dt, swing_noise);
  if (static_cast<int>(swings.size()) < kMinSwings || std::abs(swings[0]) < kFirstSwingToNoise * swing_noise) return;
  std::vector<double> times, values;
  auto take_times = [&] {
    times.clear();
    for (size_t j = 0; j < swings.size(); ++j) times.push_back((static_cast<double>(j) + 0.5) * static_cast<double>(pair) * dt);
  };
  take_times();
  double phase = std::arg(swings[0]);
  for (const std::complex<double>& a : swings) {
    phase += std::remainder(std::arg(a) - phase, kRingTwoPi);  // unwrapped
    values.push_back(phase);
  }
  ring_hz += LineSlope(times, values).first / kRingTwoPi;  // s ~ sin((w + d) t): the projection's phase grows as d t
  // Refined to below the fitted band, it is the edge of a misfit in the harmonics above it, no ring.
  if (!(ring_hz >= f_low)) return;
  swings = Swings(segment, pair, kRingTwoPi * ring_hz, dt, swing_noise);
  if (static_cast<int>(swings.size()) < kMinSwings || std::abs(swings[0]) < kFirstSwingToNoise * swing_noise) return;
  take_times();
  values.clear();
  for (const std::complex<double>& a : swings) values.push_back(std::log(std::abs(a)));
  place->ring_frequency_hz = ring_hz;
  place->ring_amplitude = std::abs(swings[0]);
  place->ring_to_noise = std::abs(swings[0]) / swing_noise;
  // ln A = c - sigma t; sigma = zeta w_n (w_d ~ w_n for light damping).
  const double sigma_per_s = -LineSlope(times, values).first;
  if (sigma_per_s > 0) place->ring_damping_ratio = sigma_per_s / (kRingTwoPi * ring_hz);
}

std::string DescribeRinging(const Unexplained& u, ResponseKind kind, size_t places) {
  const size_t n = std::min(places, u.places.size());
  // A mode rings at one frequency in Hz whatever the drive: the words need two records of different
  // drive frequencies ringing within kSameRing of each other (one record's ring may be its own misfit).
  auto confirmed = [&](const Unexplained::Place& p) {
    for (size_t j = 0; j < n; ++j) {
      const Unexplained::Place& q = u.places[j];
      if (&q != &p && std::abs(q.frequency_hz - p.frequency_hz) > kSameRing * p.frequency_hz &&
          std::abs(q.ring_frequency_hz - p.ring_frequency_hz) <= kSameRing * p.ring_frequency_hz)
        return true;
    }
    return false;
  };
  for (size_t i = 0; i < n; ++i) {
    const Unexplained::Place& p = u.places[i];
    if (!std::isfinite(p.ring_frequency_hz) || !confirmed(p)) continue;
    const std::string decay =
        std::isfinite(p.ring_damping_ratio)
            ? ", decaying with damping ratio " + FormatFigure(p.ring_damping_ratio, 2) + ", time constant " +
                  FormatFigure(1e3 / (p.ring_damping_ratio * kRingTwoPi * p.ring_frequency_hz), 2) + " ms)"
            : ", not decaying measurably)";
    return "; in " + p.record + " the residual rings at about " + FormatFigure(p.ring_frequency_hz, 3) +
           " Hz after the impacts (first swing " + FormatFigure(p.ring_amplitude, 3) + " " + UnitOf(kind) + ", " +
           FormatFigure(p.ring_to_noise, 3) + " x its noise" + decay + ": a mode near " +
           FormatFigure(p.ring_frequency_hz, 3) + " Hz that the impacts excite and the model lacks";
  }
  return "";
}

}  // namespace strokelab::internal
