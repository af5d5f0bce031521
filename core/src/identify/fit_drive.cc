// Step 1 of the fit (fit.h), the drive: its frequency, amplitude and phase from the voltage channel.
#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <numbers>
#include <numeric>
#include <span>
#include <string>
#include <vector>

#include "fit_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/identify/fit.h"
#include "strokelab/signal/harmonic_fit.h"

namespace strokelab {
namespace fit_internal {
namespace {

// EstimateDrive.
constexpr double kCoarseStepPerRecord = 0.25;  // grid spacing of the coarse search [1/T]
constexpr double kCoarseRangePerRecord = 2.0;  // half-width of the search, at least [1/T] ...
constexpr double kCoarseRangeRelative = 0.01;  // ... and at least this fraction of the nominal frequency
constexpr int kDriveSegments = 4;              // segments for the phase drift
constexpr int kMaxDriveNewtonSteps = 8;
constexpr double kDriveFrequencyTolerance = 1e-10;  // relative |df| / f that ends the Newton steps
// Half-width of the final parabola [1/T]: the residual is quadratic in the frequency error only for
// errors far below 1/T (at 0.01/T its cubic term moves the vertex by ~1e-5 Hz).
constexpr double kParabolaStepPerRecord = 1e-3;

double WrapPhase(double phase) { return std::remainder(phase, kTwoPi); }

Complex FirstHarmonicOver(std::span<const double> signal, double fs, double f, SampleWindow window) {
  return internal::FitHarmonics(signal, fs, f, window, 1).amplitudes[0];
}

}  // namespace

void RequirePositiveFinite(double value, const std::string& field) {
  if (!std::isfinite(value) || value <= 0.0)
    throw InputError(field, "must be a finite number > 0 (got " + Format(value) + ")");
}

}  // namespace fit_internal

DriveEstimate EstimateDrive(std::span<const double> voltage, double sample_rate_hz, double nominal_frequency_hz) {
  using fit_internal::FirstHarmonicOver, fit_internal::Format, fit_internal::kCoarseRangePerRecord,
      fit_internal::kCoarseRangeRelative, fit_internal::kCoarseStepPerRecord, fit_internal::kDriveFrequencyTolerance,
      fit_internal::kDriveSegments, fit_internal::kMaxDriveNewtonSteps, fit_internal::kParabolaStepPerRecord,
      fit_internal::kTwoPi, fit_internal::RequirePositiveFinite, fit_internal::WrapPhase;
  RequirePositiveFinite(sample_rate_hz, "sample_rate_hz");
  RequirePositiveFinite(nominal_frequency_hz, "nominal_frequency_hz");
  if (nominal_frequency_hz >= 0.5 * sample_rate_hz)
    throw InputError("nominal_frequency_hz", Format(nominal_frequency_hz) + " Hz is not below the Nyquist frequency " +
                                                 Format(0.5 * sample_rate_hz) + " Hz");
  const size_t n = voltage.size();
  const double record_s = static_cast<double>(n) / sample_rate_hz;
  if (nominal_frequency_hz * record_s < 2.0)
    throw InputError("voltage", "holds " + std::to_string(n) + " samples (" + Format(record_s) +
                                    " s), less than two periods of " + Format(nominal_frequency_hz) + " Hz");
  const SampleWindow all{0, n, nominal_frequency_hz * record_s};
  auto c1 = [&](double f, SampleWindow w) {
    try {
      return FirstHarmonicOver(voltage, sample_rate_hz, f, w);
    } catch (const InputError& e) {
      throw InputError("voltage", e.bare_message());
    }
  };

  // Coarse: the largest |C_1| on a grid around the nominal frequency.
  const double step = kCoarseStepPerRecord / record_s;
  const double range = std::max(kCoarseRangePerRecord / record_s, kCoarseRangeRelative * nominal_frequency_hz);
  const int half = static_cast<int>(std::ceil(range / step));
  double f = nominal_frequency_hz, best = -1.0;
  for (int k = -half; k <= half; ++k) {
    const double trial = nominal_frequency_hz + k * step;
    if (trial * record_s < 1.0 || trial >= 0.5 * sample_rate_hz) continue;
    const double amplitude = std::abs(c1(trial, all));
    if (amplitude > best) best = amplitude, f = trial;
  }
  if (!(best > 0.0))
    throw InputError("voltage", "has no sinusoidal component near the nominal " + Format(nominal_frequency_hz) + " Hz");

  // Newton on the phase drift over kDriveSegments segments.
  DriveEstimate drive;
  for (int iteration = 0; iteration < kMaxDriveNewtonSteps; ++iteration) {
    std::array<double, kDriveSegments> t{}, phase{};
    for (int k = 0; k < kDriveSegments; ++k) {
      const SampleWindow w{n * k / kDriveSegments, n * (k + 1) / kDriveSegments, 0.0};
      t[k] = 0.5 * static_cast<double>(w.begin + w.end - 1) / sample_rate_hz;
      const double raw = std::arg(c1(f, w));
      phase[k] = k == 0 ? raw : phase[k - 1] + WrapPhase(raw - phase[k - 1]);
    }
    const double t_mean = std::accumulate(t.begin(), t.end(), 0.0) / kDriveSegments;
    const double p_mean = std::accumulate(phase.begin(), phase.end(), 0.0) / kDriveSegments;
    double num = 0.0, den = 0.0;
    for (int k = 0; k < kDriveSegments; ++k)
      num += (t[k] - t_mean) * (phase[k] - p_mean), den += (t[k] - t_mean) * (t[k] - t_mean);
    const double df = num / den / kTwoPi;
    if (!std::isfinite(df)) throw InputError("voltage", "holds non-finite samples or no drive");
    f += df;
    ++drive.newton_steps;
    if (std::abs(df) < kDriveFrequencyTolerance * f) break;
  }

  // Last, the least-squares (for white noise the maximum-likelihood) frequency: the minimum over the
  // whole record of the residual sum of squares of the sine-plus-offset fit, by a parabola through f
  // and f +- 0.001 / T. The phase drift of four segments leaves a few times its Cramer-Rao bound.
  {
    std::vector<double> fitted(n);
    auto residual_sum = [&](double trial) {
      const internal::HarmonicFit fit = internal::FitHarmonics(voltage, sample_rate_hz, trial, all, 1);
      internal::EvaluateHarmonics(fit, sample_rate_hz, trial, all, fitted);
      double sum = 0.0;
      for (size_t i = 0; i < n; ++i) sum += (voltage[i] - fitted[i]) * (voltage[i] - fitted[i]);
      return sum;
    };
    const double h = kParabolaStepPerRecord / record_s;
    const double below = residual_sum(f - h), centre = residual_sum(f), above = residual_sum(f + h);
    const double curvature = below - 2.0 * centre + above;
    if (curvature > 0.0) f += 0.5 * h * (below - above) / curvature;
  }

  internal::HarmonicFit fit;
  try {
    fit = internal::FitHarmonics(voltage, sample_rate_hz, f, all, 1);
  } catch (const InputError& e) {
    throw InputError("voltage", e.bare_message());
  }
  std::vector<double> model(n);
  internal::EvaluateHarmonics(fit, sample_rate_hz, f, all, model);
  double sum_squares = 0.0;
  for (size_t i = 0; i < n; ++i) sum_squares += (voltage[i] - model[i]) * (voltage[i] - model[i]);
  drive.frequency_hz = f;
  drive.amplitude_v = std::abs(fit.amplitudes[0]);
  // C_1 of V sin(wt + phi) is V e^{j (phi - pi/2)}.
  drive.phase_rad = WrapPhase(std::arg(fit.amplitudes[0]) + 0.5 * std::numbers::pi);
  drive.offset_v = fit.offset;
  drive.noise_rms_v = std::sqrt(sum_squares / static_cast<double>(n));
  return drive;
}

}  // namespace strokelab
