// Stepped-sine sweeps in the time domain (paper section 3): one run per frequency step, each
// started from the state the previous step ended in.
//
// Phase. A step at frequency f runs settle_periods and then analyse_periods whole drive periods at
// fs = samples_per_period * f, as two records (the second started from the first's final state), and
// ends at a whole period, where the drive v_in = V sin(2 pi f t) is back at phase 0. Every record
// starts its own clock at t = 0 with phase 0: the drive phase is continuous across the steps and only
// the frequency changes, as on a rig whose generator steps the frequency at a zero crossing.
//
// H over the analysis record [t0, t1], t1 - t0 = K T (K = analyse_periods, T = 1/f, w = 2 pi f):
//   H = C1(f) / C1(v_in),   C1(v_in) = V e^{-j pi/2} = -j V   (signal.h: v = Re(C1 e^{j w t})),
//   C1(f) = (2 / KT) int_{t0}^{t1} f e^{-j w t} dt,   the continuous-time Fourier coefficient.
// With f = m_p x'' (model.h) and e^{-j w t0} = e^{-j w t1} = 1 (whole periods), integrating by
// parts twice gives
//   C1(f) = m_p [ (2 / KT) (x'(t1) - x'(t0) + j w (x(t1) - x(t0))) - w^2 C1(x) ],
// where the bracketed boundary term is the transient left in the window (0 for a periodic response)
// and C1(x) is the least-squares fit (FirstHarmonic) of the displacement samples. Why not fit the
// force samples: an impact spike lasts ~0.5 ms (paper Fig. 7), 1-3 samples at 512 samples per period
// below 15 Hz, and the sampled sum then misses the spike's impulse by up to 6.5 % of |H| (measured on
// the paper model at 0.5 V, 5-14 Hz, against 32768 samples per period), an error that changes from
// one frequency to the next and looks like jumps. The displacement is smooth (C1 even through a
// contact), so its samples alias nothing measurable; the two estimates agree to ~1e-6 once the force
// is sampled finely enough (stepped_sine_test).
#include "strokelab/sweep/stepped_sine.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdint>
#include <memory>
#include <optional>
#include <sstream>
#include <string>

#include "strokelab/base/errors.h"
#include "strokelab/signal/signal.h"

namespace strokelab {
namespace {

// The engines refuse records longer than this (engine.cc); checked here so that the error names
// the stepped-sine option, not the engine's duration_s.
constexpr std::int64_t kMaxSamplesPerStep = 200'000'000;
// Fewer samples per period and the sampled sine at phase 0 is identically zero (2 per period) or
// C1 is aliased with the higher harmonics of an impacting response.
constexpr int kMinSamplesPerPeriod = 4;

}  // namespace

std::optional<FieldError> SteppedSineOptions::IsValid() const {
  const SteppedSineOptions& o = *this;
  if (o.settle_periods < 1)
    return FieldError{"settle_periods", "must be >= 1 (got " + std::to_string(o.settle_periods) + ")"};
  if (o.analyse_periods < 1)
    return FieldError{"analyse_periods", "must be >= 1 (got " + std::to_string(o.analyse_periods) + ")"};
  if (o.samples_per_period < kMinSamplesPerPeriod)
    return FieldError{"samples_per_period", "must be >= " + std::to_string(kMinSamplesPerPeriod) + " (got " +
                                                std::to_string(o.samples_per_period) + ")"};
  const std::int64_t samples = (static_cast<std::int64_t>(o.settle_periods) + o.analyse_periods) * o.samples_per_period;
  if (samples > kMaxSamplesPerStep) {
    return FieldError{"samples_per_period", "(settle_periods + analyse_periods) x samples_per_period = " +
                                                std::to_string(samples) + " exceeds 2e8 samples per step"};
  }
  return std::nullopt;
}

namespace {

void ValidateInput(const ActuatorModel& model, double amplitude_v, const std::vector<double>& frequencies_hz,
                   const SteppedSineOptions& options) {
  Validate(model);
  // H is a ratio to C1(v_in) = -j V: undefined at V = 0.
  if (!std::isfinite(amplitude_v) || amplitude_v <= 0) {
    std::ostringstream message;
    message << "must be a finite number > 0 (got " << amplitude_v << ")";
    throw InputError("amplitude_v", message.str());
  }
  if (frequencies_hz.empty()) throw InputError("frequencies_hz", "must hold at least one frequency");
  for (size_t i = 0; i < frequencies_hz.size(); ++i) {
    if (!std::isfinite(frequencies_hz[i]) || frequencies_hz[i] <= 0) {
      std::ostringstream message;
      message << "must be a finite number > 0 (got " << frequencies_hz[i] << ")";
      throw InputError("frequencies_hz[" + std::to_string(i) + "]", message.str());
    }
  }
  Validate(options);
}

bool IsFinite(std::complex<double> z) { return std::isfinite(z.real()) && std::isfinite(z.imag()); }

}  // namespace

std::vector<SteppedSinePoint> SteppedSineSweep(const ActuatorModel& model, double amplitude_v,
                                               const std::vector<double>& frequencies_hz,
                                               const SteppedSineOptions& options) {
  ValidateInput(model, amplitude_v, frequencies_hz, options);
  const std::unique_ptr<Engine> engine = MakeEngine(ChooseMethod("auto", model).method);

  const size_t samples_per_period = static_cast<size_t>(options.samples_per_period);
  const size_t analyse_count = static_cast<size_t>(options.analyse_periods) * samples_per_period;
  const SampleWindow window{0, analyse_count, static_cast<double>(options.analyse_periods)};
  // C1(v_in) for v_in = V sin(w t): V e^{-j pi/2}.
  const std::complex<double> drive_c1(0.0, -amplitude_v);
  const double mass_kg = model.mass_kg;

  std::vector<SteppedSinePoint> sweep;
  sweep.reserve(frequencies_hz.size());
  Record settle, analyse;  // storage reused from step to step
  State state;             // rest
  for (const double f : frequencies_hz) {
    const SineDrive drive{amplitude_v, f, 0.0};
    SimulationOptions sim;
    sim.sample_rate_hz = options.samples_per_period * f;
    sim.record_velocity = false;
    sim.duration_s = options.settle_periods / f;
    sim.initial = state;
    engine->Simulate(model, drive, sim, &settle);
    sim.duration_s = options.analyse_periods / f;
    sim.initial = settle.final_state;
    engine->Simulate(model, drive, sim, &analyse);
    // llround(K / f * spp * f) is K * spp for any f, so the window is the whole analysis record.
    if (analyse.size() != analyse_count) {
      throw NumericalError("stepped sine at " + std::to_string(f) + " Hz: the record holds " +
                           std::to_string(analyse.size()) + " samples, expected " + std::to_string(analyse_count));
    }

    SteppedSinePoint point;
    point.frequency_hz = f;
    const double omega = drive.AngularFrequency();
    const State& start = settle.final_state;
    const State& end = analyse.final_state;
    const std::complex<double> boundary(end.v_m_per_s - start.v_m_per_s, omega * (end.x_m - start.x_m));
    const std::complex<double> force_c1 =
        mass_kg * (2.0 * f / options.analyse_periods * boundary -
                   omega * omega * FirstHarmonic(analyse.displacement_m, sim.sample_rate_hz, f, window));
    point.h = force_c1 / drive_c1;
    point.min_displacement_m = *std::min_element(analyse.displacement_m.begin(), analyse.displacement_m.end());
    // Contacts that start in [t0, t1). A record that starts in contact logs that contact from t = 0:
    // it started before t0 if the settling record ended in it.
    size_t contacts = 0;
    for (const ContactInterval& c : analyse.contacts) {
      const bool carried_over = c.start_s == 0.0 && std::any_of(settle.contacts.begin(), settle.contacts.end(),
                                                                [&](const ContactInterval& s) {
                                                                  return !s.closed && s.upper == c.upper;
                                                                });
      if (!carried_over) ++contacts;
    }
    point.contacts_per_period = static_cast<double>(contacts) / options.analyse_periods;
    point.final_state = end;
    if (!IsFinite(point.h) || !std::isfinite(point.min_displacement_m) || !std::isfinite(end.x_m) ||
        !std::isfinite(end.v_m_per_s)) {
      throw NumericalError("stepped sine at " + std::to_string(f) + " Hz: non-finite response");
    }
    state = end;
    sweep.push_back(point);
  }
  return sweep;
}

std::vector<size_t> JumpIndices(const std::vector<SteppedSinePoint>& sweep, double relative_jump) {
  if (!std::isfinite(relative_jump) || relative_jump <= 0) {
    std::ostringstream message;
    message << "must be a finite number > 0 (got " << relative_jump << ")";
    throw InputError("relative_jump", message.str());
  }
  std::vector<size_t> jumps;
  if (sweep.size() < 2) return jumps;
  const size_t steps = sweep.size() - 1;
  // Step i: d_i = ln|H_{i+1}| - ln|H_i| over u_i = ln f_{i+1} - ln f_i.
  std::vector<double> d(steps), u(steps);
  std::vector<bool> defined(steps);
  for (size_t i = 0; i < steps; ++i) {
    const double a = std::abs(sweep[i].h), b = std::abs(sweep[i + 1].h);
    defined[i] = a > 0 && b > 0;
    d[i] = defined[i] ? std::log(b / a) : 0.0;
    u[i] = std::log(sweep[i + 1].frequency_hz / sweep[i].frequency_hz);
  }
  const double log_threshold = std::log1p(relative_jump);
  for (size_t i = 0; i < steps; ++i) {
    const bool contacting = sweep[i].contacts_per_period > 0, next_contacting = sweep[i + 1].contacts_per_period > 0;
    if (contacting != next_contacting) {
      jumps.push_back(i);
      continue;
    }
    if (!defined[i]) {
      // |H| = 0 on one side only is a jump; on both sides none.
      if ((std::abs(sweep[i].h) > 0) != (std::abs(sweep[i + 1].h) > 0)) jumps.push_back(i);
      continue;
    }
    // The part of the change the trend does not explain, the trend being the neighbouring step
    // (k = i-1 or i+1) with the flatter slope s_k = d_k / u_k: excess = min(|d_i|, |d_i - s_k u_i|).
    // The flatter neighbour, so that a jump spread over two steps is not explained by its own other half.
    double excess = std::abs(d[i]);
    std::optional<double> flattest_slope;
    for (const size_t k : {i - 1, i + 1}) {
      if (k >= steps || !defined[k] || u[k] == 0.0) continue;  // i - 1 wraps to SIZE_MAX at i = 0
      const double slope = d[k] / u[k];
      if (!flattest_slope || std::abs(slope) < std::abs(*flattest_slope)) flattest_slope = slope;
    }
    if (flattest_slope) excess = std::min(excess, std::abs(d[i] - *flattest_slope * u[i]));
    if (excess > log_threshold) jumps.push_back(i);
  }
  return jumps;
}

}  // namespace strokelab
