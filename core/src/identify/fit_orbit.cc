// The fit's model side (fit_orbit.h): steady states at a record's drive and their harmonics.
#include "strokelab/identify/fit_orbit.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>

#include "strokelab/signal/harmonic_fit.h"
#include "fit_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/engines/pwl_system.h"
#include "strokelab/engines/variational_flow.h"
#include "strokelab/steady/steady_state.h"

namespace strokelab::internal {
namespace {

using Complex = std::complex<double>;
constexpr int kSettlePeriods = 64;     // plain periods when Newton fails inside the cost function
constexpr int kAperiodicPeriods = 16;  // periods over which an aperiodic response is averaged

}  // namespace

Complex ResponseHarmonic(Complex x_h, int h, double omega, ResponseKind kind, double mass_kg) {
  const double w = h * omega;
  switch (kind) {
    case ResponseKind::kForce:
      return -mass_kg * w * w * x_h;  // f = m_p x'' (paper-notes)
    case ResponseKind::kAcceleration:
      return -w * w * x_h;
    case ResponseKind::kVelocity:
      return Complex(0.0, w) * x_h;
    case ResponseKind::kDisplacement:
      return x_h;
  }
  return x_h;
}

// The steady state of `model` at the record's drive, from `anchor`.
std::optional<ModelOrbit> SolveOrbit(const ActuatorModel& model, const RecordAnalysis& record, const Anchor& anchor,
                                     ResponseKind kind, int orders, OrbitSearch search) {
  const PeriodMap map(model, record.drive.frequency_hz, record.drive.amplitude_v);
  std::optional<SteadyState> s;
  if (search == OrbitSearch::kSettled) {
    s = SettledAttractor(map, anchor.start);
    if (!s) return std::nullopt;
  } else if (anchor.period > 0) {
    s = Shoot(map, anchor.start, anchor.period);
  }
  if (search == OrbitSearch::kAttractor && (!s || !s->stable)) s = SolveAttractor(map, s ? s->start : anchor.start);
  if (!s) {
    State y = anchor.start;
    for (int i = 0; i < kSettlePeriods; ++i) y = map.Apply(y);
    s.emplace();
    s->start = y;
    s->period = anchor.period;
    s->stable = false;
    s->figures = map.Trace(y, std::max(anchor.period, 1));
  }
  const int periods = s->period > 0 ? s->period : kAperiodicPeriods;
  const std::vector<Complex> x = OrbitHarmonics(map, s->start, periods, orders);
  ModelOrbit orbit;
  orbit.anchor = Anchor{s->start, s->period};
  orbit.stable = s->stable;
  orbit.contacts_per_period = s->ContactsPerPeriod();
  const double omega = fit_internal::kTwoPi * record.drive.frequency_hz;
  orbit.harmonics.resize(orders);
  for (int h = 1; h <= orders; ++h) {
    orbit.harmonics[h - 1] = ResponseHarmonic(x[h - 1], h, omega, kind, model.mass_kg);
    if (!std::isfinite(orbit.harmonics[h - 1].real()) || !std::isfinite(orbit.harmonics[h - 1].imag()))
      return std::nullopt;
  }
  return orbit;
}

OrbitSlopes OrbitHarmonicSlopes(const ActuatorModel& model, const RecordAnalysis& record, State start, int period,
                                ResponseKind kind, int orders, const std::vector<double ActuatorModel::*>& parameters) {
  const double f = record.drive.frequency_hz, omega = fit_internal::kTwoPi * f;
  const int periods = period > 0 ? period : kAperiodicPeriods;
  const double duration_s = periods / f;
  // No parameters: the harmonics alone (a cost evaluation without Jacobian), a flow of 2 + 2N
  // components instead of 2 + 2 (2 + P) (N + 1).
  const bool slopes = !parameters.empty();
  FlowRequest request;
  request.monodromy = slopes;
  request.parameters = parameters;
  request.harmonics = orders;
  request.harmonic_sensitivities = slopes;
  const FlowResult flow = Flow(model, SineDrive{record.drive.amplitude_v, f, 0.0}, start, 0.0, duration_s, request);
  const double scale = 2.0 / duration_s;  // C_h = (2 / pT) int x e^{-jhwt} dt
  OrbitSlopes out;
  out.harmonics.resize(orders);
  for (int h = 1; h <= orders; ++h)
    out.harmonics[h - 1] = ResponseHarmonic(scale * flow.harmonic_integrals[h - 1], h, omega, kind, model.mass_kg);
  if (!slopes) return out;
  // dy*/dp_j = (I - M)^{-1} dP/dp_j on a periodic orbit; 0 on a fixed stretch of aperiodic motion.
  const int d = model.StateSize();
  const StateMatrix monodromy = MonodromyFromColumns(flow.columns, d);
  const auto& hs = flow.harmonic_sensitivities;
  for (size_t j = 0; j < parameters.size(); ++j) {
    const State dp = flow.columns[d + j];
    State dy0;
    if (period > 0) {
      const std::optional<State> solved = SolveShiftedByIdentity(monodromy, State{-dp.x_m, -dp.v_m_per_s, -dp.coil_force_n});
      if (!solved) throw NumericalError("the orbit's monodromy has a multiplier of 1");
      dy0 = *solved;
    }
    std::vector<Complex> slopes(orders);
    for (int h = 1; h <= orders; ++h) {
      Complex sum = hs[d + j][h - 1] + hs[0][h - 1] * dy0.x_m + hs[1][h - 1] * dy0.v_m_per_s;
      if (d > 2) sum += hs[2][h - 1] * dy0.coil_force_n;
      const Complex dx_h = scale * sum;
      slopes[h - 1] = ResponseHarmonic(dx_h, h, omega, kind, model.mass_kg);
      // The force is m_p x'': its harmonics scale with the mass too.
      if (parameters[j] == &ActuatorModel::mass_kg && kind == ResponseKind::kForce)
        slopes[h - 1] += out.harmonics[h - 1] / model.mass_kg;
    }
    out.d_harmonics.push_back(std::move(slopes));
  }
  return out;
}

double MismatchSquared(const RecordAnalysis& record, const std::vector<Complex>& model) {
  double sum = 0.0;
  for (size_t h = 0; h < record.harmonics.size(); ++h)
    if (record.usable.empty() || record.usable[h]) sum += std::norm(record.harmonics[h] - model[h]);
  return sum;
}

size_t FittedResiduals(const RecordAnalysis& record, int orders) {
  size_t n = 0;
  for (int h = 0; h < orders; ++h) n += record.usable.empty() || record.usable[h] ? 2 : 0;
  return n;
}

double PowerOf(const RecordAnalysis& record) {
  double sum = 0.0;
  for (size_t h = 0; h < record.harmonics.size(); ++h)
    if (record.usable.empty() || record.usable[h]) sum += std::norm(record.harmonics[h]);
  return sum;
}

void MoveAnchor(const ActuatorModel& model, const RecordAnalysis& record, ResponseKind kind, int orders,
                Anchor* anchor) {
  try {
    if (std::optional<ModelOrbit> orbit = SolveOrbit(model, record, *anchor, kind, orders, OrbitSearch::kAttractor))
      *anchor = orbit->anchor;
  } catch (const std::exception&) {
    // keep the old anchor
  }
}

std::optional<ModelOrbit> BestMatchingOrbit(const ActuatorModel& model, const RecordAnalysis& record, ResponseKind kind,
                                            int orders) {
  const PeriodMap map(model, record.drive.frequency_hz, record.drive.amplitude_v);
  const State linear = map.ClippedLinearStart();
  std::optional<ModelOrbit> best;
  double best_mismatch = std::numeric_limits<double>::infinity();
  std::vector<State> starts = {linear, State{0.0, 0.0},
                               State{0.5 * linear.x_m, 0.5 * linear.v_m_per_s, 0.5 * linear.coil_force_n}};
  // At a stop, moving into it at the linear response's peak speed: the contacting branch of a
  // bistable record, which none of the starts above may reach (the record may have got there by a
  // transient the model's start does not repeat).
  const double omega = 2.0 * std::numbers::pi * record.drive.frequency_hz;
  const double speed = std::hypot(omega * linear.x_m, linear.v_m_per_s);
  if (model.HasLowerStop()) starts.push_back(State{model.lower_stop_m, -speed, linear.coil_force_n});
  if (model.HasUpperStop()) starts.push_back(State{model.upper_stop_m, speed, linear.coil_force_n});
  for (const State start : starts) {
    for (const OrbitSearch search : {OrbitSearch::kAttractor, OrbitSearch::kSettled}) {
      std::optional<ModelOrbit> orbit;
      try {
        orbit = SolveOrbit(model, record, Anchor{start, 0}, kind, orders, search);
      } catch (const NumericalError&) {
        continue;
      }
      if (!orbit) continue;
      const double mismatch = MismatchSquared(record, orbit->harmonics);
      if (mismatch < best_mismatch) best = std::move(orbit), best_mismatch = mismatch;
    }
  }
  return best;
}

double OrbitMeanDisplacement(const ActuatorModel& model, const SineDrive& drive, const Anchor& anchor) {
  if (anchor.period != 1) return 0.0;
  constexpr int kSamples = 256;
  const double period_s = 1.0 / drive.frequency_hz;
  FlowRequest request;
  request.sample_count = kSamples;
  request.sample_interval_s = period_s / kSamples;
  const FlowResult flow = Flow(model, drive, anchor.start, 0.0, period_s, request);
  double sum = 0.0;
  for (const State& y : flow.samples) sum += y.x_m;
  return flow.samples.empty() ? 0.0 : sum / static_cast<double>(flow.samples.size());
}

namespace {

// OrbitOnRecordGrid from sample `first` on (the samples before it are left 0).
std::vector<double> OrbitOnGridFrom(const ActuatorModel& model, const RecordAnalysis& a, const ModelOrbit& orbit,
                                    ResponseKind kind, size_t first) {
  if (orbit.anchor.period != 1) return {};
  const double f = a.drive.frequency_hz, period_s = 1.0 / f;
  const double interval_s = 1.0 / a.sample_rate_hz;
  // Model time at which the drive phase is the first sample's (the orbit repeats every period).
  double phase_time_s =
      std::fmod(a.drive.phase_rad / (fit_internal::kTwoPi * f) + static_cast<double>(first) * interval_s, period_s);
  if (phase_time_s < 0) phase_time_s += period_s;
  const size_t count = a.window.end - first;
  std::vector<State> states;
  std::vector<double> force_n;
  if (model.IsPiecewiseLinear()) {
    State y = orbit.anchor.start;
    const PiecewiseLinearSystem system(model, SineDrive{a.drive.amplitude_v, f, 0.0});
    double t = 0.0;
    PwlMode mode = system.InitialMode(0.0, y);
    system.Advance(&t, &y, &mode, phase_time_s, [](const SwitchEvent&) {});
    SimulationOptions sim;
    sim.duration_s = static_cast<double>(count) * interval_s;
    sim.sample_rate_hz = a.sample_rate_hz;
    sim.initial = y;
    sim.record_velocity = true;
    const SineDrive drive{a.drive.amplitude_v, f, fit_internal::kTwoPi * f * phase_time_s};
    const Record r = MakeExactEngine()->Simulate(model, drive, sim);
    for (size_t n = 0; n < r.displacement_m.size(); ++n) states.push_back({r.displacement_m[n], r.velocity_m_per_s[n]});
    force_n = r.force_n;
  } else {
    FlowRequest request;
    request.sample_count = static_cast<int>(count);
    request.sample_start_s = phase_time_s;
    request.sample_interval_s = interval_s;
    const double end_s = phase_time_s + static_cast<double>(count - 1) * interval_s;
    FlowResult flow = Flow(model, SineDrive{a.drive.amplitude_v, f, 0.0}, orbit.anchor.start, 0.0, end_s, request);
    states = std::move(flow.samples);
    force_n = std::move(flow.sample_force_n);
  }
  std::vector<double> signal(first + states.size(), 0.0);
  for (size_t n = 0; n < states.size(); ++n) signal[first + n] = ResponseOf(kind, model.mass_kg, states[n], force_n[n]);
  return signal;
}

}  // namespace

// What the record's sampling and least-squares fit make of the model's response, less the orbit's
// continuous-time harmonics (see SamplingCorrection): the orbit sampled on the record's own grid over
// its analysis window, from the orbit's state at drive phase phi (the record's first sample). The
// exact engine samples piecewise-linear models; the variational flow's dense output (7th order, the
// flow's tolerances) samples any other. Empty for orbits of period other than 1 (which of their
// periods the record starts in is unknown).
std::vector<double> OrbitOnRecordGrid(const ActuatorModel& model, const RecordAnalysis& a, const ModelOrbit& orbit,
                                      ResponseKind kind) {
  return OrbitOnGridFrom(model, a, orbit, kind, 0);
}

namespace {

// Where the window's drive periods start between two samples: S = fs / f samples per period, period k
// starts at frac(k S) of a sample. Positions closer than kSamePosition are one (a drive frequency
// estimated 1e-8 off a whole fs / f leaves them together).
// frac(k S) for every period k of the window, sorted [samples].
std::vector<double> SortedStartPositions(const RecordAnalysis& a) {
  const double samples_per_period = a.sample_rate_hz / a.drive.frequency_hz;
  const auto periods = std::max<long>(1, std::lround(static_cast<double>(a.window.size()) / samples_per_period));
  std::vector<double> positions;
  for (long k = 0; k < periods; ++k) {
    const double start = static_cast<double>(k) * samples_per_period;
    positions.push_back(start - std::floor(start));
  }
  std::sort(positions.begin(), positions.end());
  return positions;
}

struct StartPositions {
  size_t distinct = 1;
  bool even = true;  // evenly spaced over the sample interval
};
StartPositions PeriodStartPositions(const RecordAnalysis& a) {
  constexpr double kSamePosition = 1e-3;  // [samples]
  const std::vector<double> positions = SortedStartPositions(a);
  std::vector<double> distinct{positions.front()};
  for (const double x : positions)
    if (x - distinct.back() > kSamePosition) distinct.push_back(x);
  if (distinct.size() > 1 && distinct.front() + 1.0 - distinct.back() <= kSamePosition) distinct.pop_back();
  StartPositions out{distinct.size(), true};
  const double even_gap = 1.0 / static_cast<double>(distinct.size());
  for (size_t k = 0; k < distinct.size(); ++k) {
    const double gap = (k + 1 < distinct.size() ? distinct[k + 1] : distinct.front() + 1.0) - distinct[k];
    if (std::abs(gap - even_gap) > kSamePosition) out.even = false;
  }
  return out;
}

// The fraction of a sample interval over which the pattern of where the window's drive periods start
// repeats: q distinct positions spaced evenly (fs / f a whole number over q, and q periods in the
// window) repeat every 1 / q of a sample; unevenly spaced ones (the pattern longer than the window)
// only over a whole sample.
double JitterSpan(const RecordAnalysis& a) {
  const StartPositions p = PeriodStartPositions(a);
  return p.even ? 1.0 / static_cast<double>(p.distinct) : 1.0;
}

}  // namespace

// The periods' start positions within half a sample of one another: the largest gap between them, round
// the sample interval, above half of it (a drive frequency estimated 4e-8 off 5 Hz moves them 0.002 of
// a sample over a 1 s window: still alike).
bool SamplesEveryPeriodAlike(const RecordAnalysis& record) {
  const std::vector<double> positions = SortedStartPositions(record);
  double largest_gap = positions.front() + 1.0 - positions.back();
  for (size_t k = 1; k < positions.size(); ++k) largest_gap = std::max(largest_gap, positions[k] - positions[k - 1]);
  return largest_gap > 0.5;
}

namespace {

// The correction on the record's grid moved later by `shift` sample intervals. Where every period
// starts at one position between two samples (fs / f a whole number), every period is sampled alike,
// and the window's last period alone gives the same harmonics at a fraction of the cost (the fits'
// slopes of the correction evaluate it many times: linearised_correction.h).
std::vector<Complex> CorrectionOnShiftedGrid(const ActuatorModel& model, const RecordAnalysis& a,
                                             const ModelOrbit& orbit, ResponseKind kind, int orders, double shift) {
  RecordAnalysis shifted = a;
  if (PeriodStartPositions(a).distinct == 1) {
    const auto samples = static_cast<size_t>(std::llround(a.sample_rate_hz / a.drive.frequency_hz));
    if (samples < a.window.size()) shifted.window = SampleWindow{a.window.end - samples, a.window.end, 1.0};
  }
  shifted.drive.phase_rad += fit_internal::kTwoPi * a.drive.frequency_hz / a.sample_rate_hz * shift;
  const std::vector<double> signal = OrbitOnGridFrom(model, shifted, orbit, kind, shifted.window.begin);
  const HarmonicFit fit = FitHarmonics(signal, a.sample_rate_hz, a.drive.frequency_hz, shifted.window, orders);
  std::vector<Complex> correction(orders);
  for (int h = 1; h <= orders; ++h)
    correction[h - 1] = fit.amplitudes[h - 1] * std::polar(1.0, -h * shifted.drive.phase_rad) - orbit.harmonics[h - 1];
  return correction;
}

}  // namespace

// The impacts have harmonics far above N and up to the sample rate; on the record's grid (a period is
// not a whole number of samples) they alias and leak into C_1..C_N by a few 1e-5 of the spike's
// harmonics, which is comparable with the noise's standard error and would bias the fit by several
// standard errors. The model's orbit is sampled on the record's own grid (OrbitOnRecordGrid, from the
// orbit's state at drive phase phi) and analysed as the record was.
//
// Where the response jumps (a damped stop's c_s p' at entry, in the force and the acceleration), each
// jump that crosses a sample instant moves every harmonic by (2 / N) J: a step as large as several
// standard errors where the window's periods start at one position between two samples (fs / f whole),
// so that the harmonics jump when the entry moves by a fraction of a sample interval, a change of
// parameters within their standard errors (contact damping on 8 Hz records at 51.2 kHz: 4.4 of them,
// the fit's passes then alternating between two such steps). Where the jump falls between two samples
// is then taken as unknown and uniform: the correction is the mean over kJitterShifts grids moved by
// j / kJitterShifts of the span over which the periods' start positions repeat (JitterSpan), a sawtooth
// of the step's height sampled evenly, and its variance about that mean (step^2 / 12) is added to the
// record's noise. The response jumps only where a damped stop starts to push (the force and the
// acceleration; the displacement and the velocity are continuous): any other orbit keeps its own
// grid's correction, whose kinks it resolves.
SampledCorrection SamplingCorrection(const ActuatorModel& model, const RecordAnalysis& a, const ModelOrbit& orbit,
                                     ResponseKind kind, int orders) {
  constexpr int kJitterShifts = 8;
  SampledCorrection out;
  out.harmonics.assign(orders, 0.0);
  if (orbit.anchor.period != 1) return out;
  out.harmonics = CorrectionOnShiftedGrid(model, a, orbit, kind, orders, 0.0);
  const bool jumps = orbit.contacts_per_period > 0.0 && model.contact_damping_n_s_per_m > 0.0 &&
                     (kind == ResponseKind::kForce || kind == ResponseKind::kAcceleration);
  if (!jumps) return out;
  const double span = JitterSpan(a);
  std::vector<std::vector<Complex>> shifted{out.harmonics};
  for (int j = 1; j < kJitterShifts; ++j)
    shifted.push_back(CorrectionOnShiftedGrid(model, a, orbit, kind, orders, span * j / kJitterShifts));
  double variance = 0.0;
  int used = 0;
  for (int h = 0; h < orders; ++h) {
    Complex mean = 0.0;
    for (const auto& c : shifted) mean += c[h] / static_cast<double>(kJitterShifts);
    out.harmonics[h] = mean;
    if (!a.usable.empty() && !a.usable[h]) continue;
    for (const auto& c : shifted) variance += std::norm(c[h] - mean) / static_cast<double>(kJitterShifts);
    ++used;
  }
  out.jitter_variance = used == 0 ? 0.0 : variance / (2.0 * used);
  return out;
}

}  // namespace strokelab::internal
