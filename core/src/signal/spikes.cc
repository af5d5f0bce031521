// Impact spikes in a force signal and the contact parameters derived from them (paper section 4.1).
//
// Detection. The smooth part of the force is a few harmonics of the drive; an impact adds a narrow
// one-sided pulse (paper section 3.1: one stop, so one polarity). The baseline is the harmonic
// least-squares fit of the samples not taken for spikes, refitted kBaselineIterations times: each pass
// flags |residual| > threshold_sigmas * sigma, sigma = 1.4826 * MAD(residual) (the normal-consistent
// median absolute deviation, blind to the few spike samples). Spikes are the flagged runs of the
// polarity with the larger extreme residual.
//
// Contact time. Nagurka and Huang model the contact force as a half-sine of base dT (paper Eq. 4);
// sin(pi t / dT) >= 1/2 on [dT/6, 5 dT/6], so the full width at half height is 2 dT / 3 and
// dT = 1.5 x FWHM. The half-height crossings are interpolated linearly between samples.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <vector>

#include "strokelab/signal/harmonic_fit.h"
#include "strokelab/base/errors.h"
#include "strokelab/signal/signal.h"
#include "require_positive.h"

namespace strokelab {
namespace {

using signal_internal::RequirePositiveFinite;

constexpr int kBaselineIterations = 3;
constexpr double kMadToSigma = 1.4826;          // sigma / MAD for normal noise
constexpr size_t kMergeGapSamples = 3;          // runs this close are one spike (noise dips near threshold)
constexpr double kBaseOverHalfHeightWidth = 1.5;  // half-sine: base = 1.5 x FWHM (paper Eq. 4)
// sigma never goes below this fraction of the window's RMS: in a noise-free simulated signal the
// residual of a spike-free stretch is rounding error, which must not count as spikes.
constexpr double kSigmaFloorRelative = 1e-9;

// A run of flagged samples [first, last], window-relative.
struct Run {
  size_t first = 0;
  size_t last = 0;
  size_t size() const { return last - first + 1; }
};

double Median(std::vector<double> values) {
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

// 1.4826 MAD: the standard deviation of normal noise, robust to a minority of outliers.
double RobustSigma(const std::vector<double>& residual) {
  const double median = Median(residual);
  std::vector<double> deviation(residual.size());
  for (size_t i = 0; i < residual.size(); ++i) deviation[i] = std::abs(residual[i] - median);
  return kMadToSigma * Median(deviation);
}

double RootMeanSquareAboutMean(std::span<const double> values) {
  double mean = 0.0;
  for (double v : values) mean += v;
  mean /= static_cast<double>(values.size());
  double sum_squares = 0.0;
  for (double v : values) sum_squares += (v - mean) * (v - mean);
  return std::sqrt(sum_squares / static_cast<double>(values.size()));
}

// Runs of score > threshold; runs separated by at most kMergeGapSamples samples are merged.
std::vector<Run> RunsAbove(const std::vector<double>& score, double threshold) {
  std::vector<Run> runs;
  for (size_t i = 0; i < score.size(); ++i) {
    if (!(score[i] > threshold)) continue;
    if (!runs.empty() && i - runs.back().last <= kMergeGapSamples + 1) {
      runs.back().last = i;
    } else {
      runs.push_back(Run{i, i});
    }
  }
  return runs;
}

// Samples left out of the baseline fit: each run widened by its own length on both sides, since a
// pulse's feet lie below the threshold but are not baseline. Falls back to the bare runs if the
// widening would leave out more than half the window.
std::vector<char> ExclusionMask(const std::vector<Run>& runs, size_t count) {
  std::vector<char> widened(count, 0), bare(count, 0);
  size_t widened_count = 0;
  for (const Run& run : runs) {
    const size_t first = run.first > run.size() ? run.first - run.size() : 0;
    const size_t last = std::min(count - 1, run.last + run.size());
    for (size_t i = first; i <= last; ++i) {
      if (!widened[i]) ++widened_count;
      widened[i] = 1;
    }
    std::fill(bare.begin() + static_cast<std::ptrdiff_t>(run.first),
              bare.begin() + static_cast<std::ptrdiff_t>(run.last) + 1, 1);
  }
  return 2 * widened_count <= count ? widened : bare;
}

// Where `score` falls to `level` walking from `peak` in `direction` (-1 or +1), as a fractional,
// window-relative sample index interpolated linearly; NaN if the window ends first.
double LevelCrossing(const std::vector<double>& score, size_t peak, double level, int direction) {
  size_t inside = peak;  // last sample above the level
  while (true) {
    if (direction < 0 ? inside == 0 : inside + 1 == score.size()) return std::numeric_limits<double>::quiet_NaN();
    const size_t next = direction < 0 ? inside - 1 : inside + 1;
    if (!(score[next] > level)) {
      const double fraction = (score[inside] - level) / (score[inside] - score[next]);
      return static_cast<double>(inside) + direction * fraction;
    }
    inside = next;
  }
}

// Residual of the window about its harmonic baseline, refitted without the samples taken for spikes.
// Returns the residual and sets *sigma to its robust standard deviation.
std::vector<double> BaselineResidual(std::span<const double> force, double sample_rate_hz,
                                     double drive_frequency_hz, SampleWindow window, const SpikeOptions& options,
                                     double* sigma) {
  std::span<const double> values = force.subspan(window.begin, window.size());
  const double sigma_floor = kSigmaFloorRelative * RootMeanSquareAboutMean(values);
  std::vector<char> excluded;  // empty: first pass fits every sample
  std::vector<double> baseline(window.size()), residual(window.size()), magnitude(window.size());
  for (int pass = 0; pass < kBaselineIterations; ++pass) {
    const internal::HarmonicFit fit = internal::FitHarmonics(force, sample_rate_hz, drive_frequency_hz, window,
                                                             options.baseline_harmonics, excluded);
    internal::EvaluateHarmonics(fit, sample_rate_hz, drive_frequency_hz, window, baseline);
    for (size_t i = 0; i < values.size(); ++i) {
      residual[i] = values[i] - baseline[i];
      magnitude[i] = std::abs(residual[i]);
    }
    *sigma = std::max(RobustSigma(residual), sigma_floor);
    excluded = ExclusionMask(RunsAbove(magnitude, options.threshold_sigmas * *sigma), values.size());
  }
  return residual;
}

}  // namespace

std::vector<Spike> DetectSpikes(std::span<const double> force, double sample_rate_hz, double drive_frequency_hz,
                                SampleWindow window, const SpikeOptions& options) {
  RequirePositiveFinite(sample_rate_hz, "sample_rate_hz");
  RequirePositiveFinite(drive_frequency_hz, "drive_frequency_hz");
  RequirePositiveFinite(options.threshold_sigmas, "threshold_sigmas");
  if (options.baseline_harmonics < 0) throw InputError("baseline_harmonics", "must be >= 0");
  if (window.begin >= window.end || window.end > force.size()) {
    throw InputError("window", "is not a non-empty range within the " + std::to_string(force.size()) +
                                   " samples of the force signal");
  }

  double sigma = 0.0;
  const std::vector<double> residual =
      BaselineResidual(force, sample_rate_hz, drive_frequency_hz, window, options, &sigma);
  if (!(sigma > 0.0)) return {};  // a constant signal has no spikes

  // One stop, one polarity: the side with the larger extreme deviation (paper section 3.1).
  const auto [lowest, highest] = std::minmax_element(residual.begin(), residual.end());
  const double polarity = *highest >= -*lowest ? 1.0 : -1.0;
  std::vector<double> score(residual.size());
  for (size_t i = 0; i < residual.size(); ++i) score[i] = polarity * residual[i];

  std::vector<Spike> spikes;
  for (const Run& run : RunsAbove(score, options.threshold_sigmas * sigma)) {
    const auto first = score.begin() + static_cast<std::ptrdiff_t>(run.first);
    const size_t peak = static_cast<size_t>(std::max_element(first, first + static_cast<std::ptrdiff_t>(run.size())) -
                                            score.begin());
    const double half_height = 0.5 * score[peak];
    const double left = LevelCrossing(score, peak, half_height, -1);
    const double right = LevelCrossing(score, peak, half_height, +1);
    if (std::isnan(left) || std::isnan(right)) continue;  // cut by the window edge: width unknown

    const double contact_time_s = kBaseOverHalfHeightWidth * (right - left) / sample_rate_hz;
    const double middle_s = (static_cast<double>(window.begin) + 0.5 * (left + right)) / sample_rate_hz;
    Spike spike;
    spike.peak_index = window.begin + peak;
    spike.peak_time_s = static_cast<double>(spike.peak_index) / sample_rate_hz;
    spike.peak_height = residual[peak];
    spike.start_s = middle_s - 0.5 * contact_time_s;
    spike.end_s = middle_s + 0.5 * contact_time_s;
    spikes.push_back(spike);
  }
  return spikes;
}

// Paper Eq. 6 with the square root restored (as printed it has none).
ContactTimeStatistics ContactTimeStats(std::span<const double> contact_times_s) {
  for (double t : contact_times_s) {
    if (!std::isfinite(t) || t <= 0.0) {
      std::ostringstream message;
      message << "must be finite and > 0 (got " << t << ")";
      throw InputError("contact_times_s", message.str());
    }
  }
  ContactTimeStatistics stats;
  stats.count = contact_times_s.size();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (stats.count == 0) {
    stats.mean_s = nan;
    stats.rsd = nan;
    return stats;
  }
  double sum = 0.0;
  for (double t : contact_times_s) sum += t;
  stats.mean_s = sum / static_cast<double>(stats.count);
  if (stats.count < 2) {
    stats.rsd = nan;
    return stats;
  }
  double sum_squares = 0.0;
  for (double t : contact_times_s) sum_squares += (t - stats.mean_s) * (t - stats.mean_s);
  stats.rsd = std::sqrt(sum_squares / static_cast<double>(stats.count - 1)) / stats.mean_s;
  return stats;
}

// Paper Eq. 5.
double ContactStiffnessEq5(double mass_kg, double contact_time_s) {
  RequirePositiveFinite(mass_kg, "mass_kg");
  RequirePositiveFinite(contact_time_s, "contact_time_s");
  const double contact_frequency_rad_s = std::numbers::pi / contact_time_s;  // w_s, paper Eq. 4
  return mass_kg * contact_frequency_rad_s * contact_frequency_rad_s;
}

// dT = pi / w_d, w_d^2 = (k_p + k_s) / m - (c / 2m)^2  =>  k_s = m ((pi / dT)^2 + (c / 2m)^2) - k_p.
double ContactStiffnessDamped(double mass_kg, double contact_time_s, double suspension_stiffness_n_per_m,
                              double total_damping_n_s_per_m) {
  RequirePositiveFinite(mass_kg, "mass_kg");
  RequirePositiveFinite(contact_time_s, "contact_time_s");
  if (!std::isfinite(suspension_stiffness_n_per_m) || suspension_stiffness_n_per_m < 0.0) {
    throw InputError("suspension_stiffness_n_per_m", "must be finite and >= 0");
  }
  if (!std::isfinite(total_damping_n_s_per_m) || total_damping_n_s_per_m < 0.0) {
    throw InputError("total_damping_n_s_per_m", "must be finite and >= 0");
  }
  const double damped_rad_s = std::numbers::pi / contact_time_s;
  const double decay_rate_per_s = total_damping_n_s_per_m / (2.0 * mass_kg);
  const double contact_stiffness_n_per_m =
      mass_kg * (damped_rad_s * damped_rad_s + decay_rate_per_s * decay_rate_per_s) - suspension_stiffness_n_per_m;
  if (!(contact_stiffness_n_per_m > 0.0)) {
    throw InputError("contact_time_s", "is longer than the half-period of the suspension alone: no stop stiffness > 0 gives it");
  }
  return contact_stiffness_n_per_m;
}

double ContactHalfPeriodS(double mass_kg, double suspension_stiffness_n_per_m, double contact_stiffness_n_per_m,
                          double total_damping_n_s_per_m) {
  RequirePositiveFinite(mass_kg, "mass_kg");
  if (!std::isfinite(suspension_stiffness_n_per_m) || suspension_stiffness_n_per_m < 0.0) {
    throw InputError("suspension_stiffness_n_per_m", "must be finite and >= 0");
  }
  RequirePositiveFinite(contact_stiffness_n_per_m, "contact_stiffness_n_per_m");
  if (!std::isfinite(total_damping_n_s_per_m) || total_damping_n_s_per_m < 0.0) {
    throw InputError("total_damping_n_s_per_m", "must be finite and >= 0");
  }
  const double decay_rate_per_s = total_damping_n_s_per_m / (2.0 * mass_kg);
  const double damped_squared =
      (suspension_stiffness_n_per_m + contact_stiffness_n_per_m) / mass_kg - decay_rate_per_s * decay_rate_per_s;
  if (!(damped_squared > 0.0)) {
    throw NumericalError("contact oscillator is critically damped or overdamped: no half-period");
  }
  return std::numbers::pi / std::sqrt(damped_squared);
}

}  // namespace strokelab
