#include "strokelab/steady/steady_state.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "strokelab/base/errors.h"
#include "strokelab/model/linear_response.h"
#include "strokelab/engines/pwl_system.h"
#include "strokelab/engines/variational_flow.h"

namespace strokelab {
namespace {

using Complex = std::complex<double>;
constexpr Complex kJ(0.0, 1.0);

// (e^{mu tau} - 1) / mu, and its limit tau; a series where mu tau is small avoids cancellation.
Complex ExpIntegral(Complex mu, double tau) {
  const Complex z = mu * tau;
  if (std::abs(z) < 1e-4) return tau * (1.0 + z / 2.0 + z * z / 6.0);
  return (std::exp(z) - 1.0) / mu;
}

// int_0^tau s e^{mu s} ds.
Complex ExpIntegralLinear(Complex mu, double tau) {
  const Complex z = mu * tau;
  if (std::abs(z) < 1e-4) return tau * tau * (0.5 + z / 3.0 + z * z / 8.0);
  return (std::exp(z) * (z - 1.0) + 1.0) / (mu * mu);
}

// int_{t0}^{t0+tau} x(t) e^{-jhwt} dt for x in one linear region from the state y0 at t0, in closed
// form: the homogeneous part is a sum of (complex) exponentials, the particular part sinusoids.
// omega is the drive's angular frequency, h = harmonic >= 1 the order of the harmonic wanted.
Complex SegmentIntegral(const LinearRegion& r, double t0, State y0, double tau, double omega, double phase,
                        int harmonic = 1) {
  const State p0 = r.ParticularAt(t0);
  const double zx = y0.x_m - p0.x_m, zv = y0.v_m_per_s - p0.v_m_per_s;
  const double a = r.decay_rate(), b2 = r.beta_squared();
  const double drive_omega = omega;
  omega = harmonic * drive_omega;                       // h w: the harmonic's angular frequency
  const Complex rotate = std::exp(-kJ * (omega * t0));  // e^{-jhw t0}
  Complex homogeneous;
  const double omega0_sq = r.stiffness() / r.mass_kg();
  if (std::abs(b2) < 1e-12 * omega0_sq) {
    // Critically damped: e^{-a s} (zx + (a zx + zv) s).
    const Complex mu = -a - kJ * omega;
    homogeneous = zx * ExpIntegral(mu, tau) + (a * zx + zv) * ExpIntegralLinear(mu, tau);
  } else if (b2 > 0) {
    // Underdamped: Re[A e^{lambda s}], lambda = -a + jb, A = zx - j (a zx + zv) / b.
    const double b = std::sqrt(b2);
    const Complex amplitude(zx, -(a * zx + zv) / b);
    homogeneous = 0.5 * (amplitude * ExpIntegral(Complex(-a, b) - kJ * omega, tau) +
                         std::conj(amplitude) * ExpIntegral(Complex(-a, -b) - kJ * omega, tau));
  } else {
    // Overdamped: two real exponentials e^{(-a +- beta) s}.
    const double beta = std::sqrt(-b2), q = (a * zx + zv) / beta;
    homogeneous = 0.5 * ((zx + q) * ExpIntegral(-a + beta - kJ * omega, tau) +
                         (zx - q) * ExpIntegral(-a - beta - kJ * omega, tau));
  }
  // ps sin(theta) + pc cos(theta) = e^{j theta} (pc - j ps)/2 + e^{-j theta} (pc + j ps)/2, theta = w t + phase;
  // times e^{-jhwt}: e^{j phase} e^{j (1-h) w t} and e^{-j phase} e^{-j (1+h) w t} (tau alone for h = 1).
  const double beat = (1 - harmonic) * drive_omega;  // (1 - h) w [rad/s]
  const Complex positive_integral =
      harmonic == 1 ? Complex(tau) : std::exp(kJ * (beat * t0)) * ExpIntegral(kJ * beat, tau);
  const Complex positive = std::exp(kJ * phase) * Complex(r.pc(), -r.ps()) * 0.5 * positive_integral;
  const Complex negative = std::exp(-kJ * phase) * Complex(r.pc(), r.ps()) * 0.5 * std::exp(-kJ * (drive_omega * t0)) *
                           ExpIntegral(-(1.0 + harmonic) * kJ * drive_omega, tau);
  const Complex offset = r.offset_m() * ExpIntegral(-kJ * omega, tau);
  return rotate * (homogeneous + offset + negative) + positive;
}

// 2x2 matrix on (x, v), row-major: the closed form's monodromy (piecewise-linear models have no coil pole).
struct Matrix2 {
  double a = 1, b = 0, c = 0, d = 1;
  Matrix2 operator*(const Matrix2& o) const {
    return {a * o.a + b * o.c, a * o.b + b * o.d, c * o.a + d * o.c, c * o.b + d * o.d};
  }
};

Matrix2 ToMatrix(const Transition& t) { return {t.xx, t.xv, t.vx, t.vv}; }

StateMatrix ToStateMatrix(const Matrix2& m) {
  StateMatrix out(2, 2);
  out << m.a, m.b, m.c, m.d;
  return out;
}

// Saltation matrix at a switch from region `before` to `after` across surface s (header formula).
Matrix2 Saltation(const LinearRegion& before, const LinearRegion& after, const Surface& s, double t, State y,
                  double omega, double phase) {
  const double f_before = before.Force(y, t) / before.mass_kg();
  const double f_after = after.Force(y, t) / after.mass_kg();
  const double jump = f_after - f_before;  // only the acceleration can jump; x' is continuous
  if (jump == 0.0) return {};
  const double h_t = s.delta * omega * std::cos(omega * t + phase);
  const double denominator = s.alpha * y.v_m_per_s + s.beta * f_before + h_t;
  if (!(std::abs(denominator) > 0.0)) return {};  // a grazing switch: the map is not differentiable there
  // S = I + (0, jump)^T (alpha, beta) / denominator.
  return {1.0, 0.0, jump * s.alpha / denominator, 1.0 + jump * s.beta / denominator};
}

// The sizes the map's residual is measured in: the length scale L, L w, and the suspension's force at L
// for the coil's force (0 without the coil's pole: F_e is no state then).
struct Scales {
  double length_m, speed_m_per_s, force_n;
};

Scales ScalesOf(const PeriodMap& map) {
  const ActuatorModel& m = map.model();
  const double length_m = LengthScaleM(m);
  return {length_m, length_m * 2.0 * std::numbers::pi * map.frequency_hz(),
          m.HasCoilPole() ? m.stiffness_n_per_m * length_m : 0.0};
}

double ScaledNorm(State r, const Scales& s) {
  const double x = r.x_m / s.length_m, v = r.v_m_per_s / s.speed_m_per_s;
  double sum = x * x + v * v;  // scaled to order one: hypot's care for overflow costs for nothing
  if (s.force_n > 0) sum += (r.coil_force_n / s.force_n) * (r.coil_force_n / s.force_n);
  return std::sqrt(sum);
}

State Minus(State a, State b) { return {a.x_m - b.x_m, a.v_m_per_s - b.v_m_per_s, a.coil_force_n - b.coil_force_n}; }

// y + lambda step.
State Plus(State y, double lambda, State step) {
  return {y.x_m + lambda * step.x_m, y.v_m_per_s + lambda * step.v_m_per_s,
          y.coil_force_n + lambda * step.coil_force_n};
}

}  // namespace

std::vector<std::complex<double>> Eigenvalues(const StateMatrix& m) {
  if (m.rows() == 2) {
    const double trace = m(0, 0) + m(1, 1), det = m(0, 0) * m(1, 1) - m(0, 1) * m(1, 0);
    const Complex root = std::sqrt(Complex(trace * trace / 4.0 - det, 0.0));
    return {trace / 2.0 + root, trace / 2.0 - root};
  }
  const Eigen::EigenSolver<StateMatrix> solver(m, false);
  if (solver.info() != Eigen::Success) return std::vector<Complex>(m.rows(), Complex(NAN, NAN));
  return {solver.eigenvalues().begin(), solver.eigenvalues().end()};
}

StateMatrix MonodromyFromColumns(const std::vector<State>& columns, int size) {
  StateMatrix m(size, size);
  for (int c = 0; c < size; ++c) {
    m(0, c) = columns[c].x_m;
    m(1, c) = columns[c].v_m_per_s;
    if (size > 2) m(2, c) = columns[c].coil_force_n;
  }
  return m;
}

std::optional<State> SolveShiftedByIdentity(const StateMatrix& m, const State& r) {
  if (m.rows() == 2) {
    const double a = m(0, 0) - 1.0, b = m(0, 1), c = m(1, 0), d = m(1, 1) - 1.0;
    const double det = a * d - b * c;
    if (!(std::abs(det) > 0.0)) return std::nullopt;
    return State{(d * r.x_m - b * r.v_m_per_s) / det, (-c * r.x_m + a * r.v_m_per_s) / det};
  }
  const Eigen::Matrix3d shifted = m - Eigen::Matrix3d::Identity();  // (fixed sizes: the only other size is 3)
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(shifted);
  if (!lu.isInvertible()) return std::nullopt;
  const Eigen::Vector3d step = lu.solve(Eigen::Vector3d(r.x_m, r.v_m_per_s, r.coil_force_n));
  if (!step.allFinite()) return std::nullopt;
  return State{step(0), step(1), step(2)};
}

// The closed-form path for piecewise-linear models, the variational flow otherwise.
struct PeriodMap::Impl {
  ActuatorModel model;
  SineDrive drive;
  std::optional<PiecewiseLinearSystem> system;

  OrbitFigures TraceClosedForm(State y0, int periods, bool with_figures) const;
  OrbitFigures TraceFlow(State y0, int periods, bool with_figures, std::optional<DriveParameter> drive) const;
  // d P^periods(y0) / d(drive parameter) on the closed form: a forward difference.
  State ClosedFormDriveDerivative(State y0, const State& end, int periods, DriveParameter drive) const;
};

PeriodMap::PeriodMap(const ActuatorModel& model, double frequency_hz, double amplitude_v)
    : impl_(std::make_unique<Impl>()), frequency_hz_(frequency_hz), amplitude_v_(amplitude_v) {
  Validate(model);
  impl_->model = model;
  impl_->drive = SineDrive{amplitude_v, frequency_hz, 0.0};
  Validate(impl_->drive);
  if (model.IsPiecewiseLinear()) impl_->system.emplace(model, impl_->drive);
}

PeriodMap::~PeriodMap() = default;
PeriodMap::PeriodMap(PeriodMap&&) noexcept = default;

const ActuatorModel& PeriodMap::model() const { return impl_->model; }

State PeriodMap::Apply(State y) const {
  if (!impl_->system) return Flow(impl_->model, impl_->drive, y, 0.0, period_s(), {}).end;
  double t = 0.0;
  PwlMode mode = impl_->system->InitialMode(0.0, y);
  impl_->system->Advance(&t, &y, &mode, period_s(), [](const SwitchEvent&) {});
  return y;
}

OrbitFigures PeriodMap::Trace(State y, int periods, std::optional<DriveParameter> drive) const {
  if (!impl_->system) return impl_->TraceFlow(y, periods, true, drive);
  OrbitFigures figures = impl_->TraceClosedForm(y, periods, true);
  if (drive) figures.d_end_d_drive = impl_->ClosedFormDriveDerivative(y, figures.end, periods, *drive);
  return figures;
}

OrbitFigures PeriodMap::Linearize(State y, int periods, std::optional<DriveParameter> drive) const {
  if (!impl_->system) return impl_->TraceFlow(y, periods, false, drive);
  OrbitFigures figures = impl_->TraceClosedForm(y, periods, false);
  if (drive) figures.d_end_d_drive = impl_->ClosedFormDriveDerivative(y, figures.end, periods, *drive);
  return figures;
}

State PeriodMap::Impl::ClosedFormDriveDerivative(State y0, const State& end, int periods, DriveParameter drive) const {
  // The map's dependence on the drive is smooth away from grazing; one more pass is cheaper than
  // differentiating the closed form's switch instants.
  const bool frequency = drive == DriveParameter::kFrequencyHz;
  const double value = frequency ? this->drive.frequency_hz : this->drive.amplitude_v;
  const double step = 1e-7 * (value != 0.0 ? value : 1.0);
  const PeriodMap shifted(model, frequency ? value + step : this->drive.frequency_hz,
                          frequency ? this->drive.amplitude_v : value + step);
  State y = y0;
  for (int k = 0; k < periods; ++k) y = shifted.Apply(y);
  return {(y.x_m - end.x_m) / step, (y.v_m_per_s - end.v_m_per_s) / step};  // (no coil pole: closed form)
}

OrbitFigures PeriodMap::Impl::TraceClosedForm(State y0, int periods, bool with_figures) const {
  const PiecewiseLinearSystem& sys = *system;
  const double omega = drive.AngularFrequency(), phase = drive.phase_rad;
  const double t_end = periods / drive.frequency_hz;
  OrbitFigures figures;
  Matrix2 monodromy;
  figures.min_displacement_m = figures.max_displacement_m = y0.x_m;
  Complex integral = 0.0;
  std::vector<std::pair<double, State>> extrema;

  double segment_t = 0.0;
  State segment_y = y0;
  PwlMode segment_mode = sys.InitialMode(0.0, y0);
  auto note = [&](const LinearRegion& region, double t, State y) {
    figures.min_displacement_m = std::min(figures.min_displacement_m, y.x_m);
    figures.max_displacement_m = std::max(figures.max_displacement_m, y.x_m);
    figures.peak_force_n = std::max(figures.peak_force_n, std::abs(region.Force(y, t)));
  };
  auto close_segment = [&](double t_close) {
    const LinearRegion& region = sys.Region(segment_mode);
    const double tau = t_close - segment_t;
    monodromy = ToMatrix(region.Propagator(tau)) * monodromy;
    if (!with_figures) return;
    integral += SegmentIntegral(region, segment_t, segment_y, tau, omega, phase);
    extrema.clear();
    sys.AppendExtrema(segment_mode, segment_t, segment_y, tau, &extrema);
    note(region, segment_t, segment_y);
    for (const auto& [t, y] : extrema) note(region, t, y);
  };

  double t = 0.0;
  State y = y0;
  PwlMode mode = segment_mode;
  sys.Advance(&t, &y, &mode, t_end, [&](const SwitchEvent& e) {
    close_segment(e.time_s);
    monodromy = Saltation(sys.Region(e.before), sys.Region(e.after), e.surface, e.time_s, e.state, omega, phase) *
                monodromy;
    if ((!e.before.contact.lower && e.after.contact.lower) || (!e.before.contact.upper && e.after.contact.upper))
      ++figures.contacts;
    segment_t = e.time_s;
    segment_y = e.state;
    segment_mode = e.after;
  });
  close_segment(t_end);
  figures.end = y;
  figures.monodromy = ToStateMatrix(monodromy);
  if (!with_figures) {
    figures.min_displacement_m = figures.max_displacement_m = figures.peak_force_n = NAN;  // not computed
    return figures;
  }
  note(sys.Region(mode), t_end, y);
  figures.x1 = 2.0 * integral / t_end;
  return figures;
}

OrbitFigures PeriodMap::Impl::TraceFlow(State y0, int periods, bool with_figures,
                                        std::optional<DriveParameter> drive_parameter) const {
  FlowRequest request;
  request.monodromy = true;
  request.drive_amplitude = drive_parameter == DriveParameter::kAmplitudeV;
  request.drive_frequency = drive_parameter == DriveParameter::kFrequencyHz;
  request.harmonics = with_figures ? 1 : 0;
  request.figures = with_figures;
  const double t_end = periods / drive.frequency_hz;
  const FlowResult flow = Flow(model, drive, y0, 0.0, t_end, request);
  OrbitFigures figures;
  figures.end = flow.end;
  const int d = model.StateSize();
  figures.monodromy = MonodromyFromColumns(flow.columns, d);
  if (drive_parameter) {
    figures.d_end_d_drive = flow.columns[d];
    // The pass ends at t = periods / f: d/df adds the flow's rate there times dt/df = -periods / f^2.
    if (request.drive_frequency)
      figures.d_end_d_drive = Plus(figures.d_end_d_drive, -periods / (drive.frequency_hz * drive.frequency_hz),
                                   flow.end_rate);
  }
  figures.contacts = flow.contacts;
  if (!with_figures) {
    figures.min_displacement_m = figures.max_displacement_m = figures.peak_force_n = NAN;  // not computed
    return figures;
  }
  figures.min_displacement_m = flow.min_displacement_m;
  figures.max_displacement_m = flow.max_displacement_m;
  figures.peak_force_n = flow.peak_force_n;
  figures.x1 = 2.0 * flow.harmonic_integrals[0] / t_end;
  return figures;
}

State PeriodMap::ClippedLinearStart() const {
  const ActuatorModel& m = impl_->model;
  const double omega = impl_->drive.AngularFrequency();
  State y;
  if (m.HasCoilPole()) {
    // u = V sin(wt) = Im(V e^{jwt}): x = Im(X e^{jwt}) with X = H_p V, and F_e's phasor (model.h) at t = 0.
    const Complex x = DisplacementFrf(m, omega) * amplitude_v_;
    const Complex coil = (m.gain_n_per_v * amplitude_v_ - kJ * omega * m.back_emf_damping_n_s_per_m * x) /
                         Complex(1.0, omega * m.coil_time_constant_s);
    y = {x.imag(), omega * x.real(), coil.imag()};
  } else {
    const LinearRegion free(m.mass_kg, m.damping_n_s_per_m, m.stiffness_n_per_m, m.gain_n_per_v * amplitude_v_, 0.0,
                            omega, 0.0);
    y = free.ParticularAt(0.0);
  }
  if (m.HasLowerStop()) y.x_m = std::max(y.x_m, m.lower_stop_m);
  if (m.HasUpperStop()) y.x_m = std::min(y.x_m, m.upper_stop_m);
  return y;
}

std::vector<std::complex<double>> OrbitHarmonics(const PeriodMap& map, State start, int period, int orders) {
  if (period < 1) throw InputError("period", "must be >= 1 (got " + std::to_string(period) + ")");
  if (orders < 1) throw InputError("orders", "must be >= 1 (got " + std::to_string(orders) + ")");
  const ActuatorModel& model = map.model();
  const SineDrive drive{map.amplitude_v(), map.frequency_hz(), 0.0};
  const double t_end = period / drive.frequency_hz;
  if (!model.IsPiecewiseLinear()) {
    FlowRequest request;
    request.harmonics = orders;
    std::vector<Complex> integral = Flow(model, drive, start, 0.0, t_end, request).harmonic_integrals;
    for (Complex& c : integral) c *= 2.0 / t_end;
    return integral;
  }
  // The same segments as PeriodMap's closed-form trace, each integrated at every harmonic.
  const PiecewiseLinearSystem sys(model, drive);
  const double omega = drive.AngularFrequency();
  std::vector<Complex> integral(orders, 0.0);
  double segment_t = 0.0;
  State segment_y = start;
  PwlMode segment_mode = sys.InitialMode(0.0, start);
  auto close_segment = [&](double t_close) {
    const LinearRegion& region = sys.Region(segment_mode);
    for (int h = 1; h <= orders; ++h)
      integral[h - 1] += SegmentIntegral(region, segment_t, segment_y, t_close - segment_t, omega, 0.0, h);
  };
  double t = 0.0;
  State y = start;
  PwlMode mode = segment_mode;
  sys.Advance(&t, &y, &mode, t_end, [&](const SwitchEvent& e) {
    close_segment(e.time_s);
    segment_t = e.time_s;
    segment_y = e.state;
    segment_mode = e.after;
  });
  close_segment(t_end);
  for (Complex& c : integral) c *= 2.0 / t_end;
  return integral;
}

double SteadyState::MaxMultiplier() const {
  double largest = 0.0;
  for (const Complex& mu : multipliers) largest = std::max(largest, std::abs(mu));
  return largest;
}

std::complex<double> SteadyState::Frf(const PeriodMap& map) const {
  // C_1(f) = -m w^2 C_1(x); C_1(v_in) = V e^{-j pi/2} for v_in = V sin(w t).
  const double omega = 2.0 * std::numbers::pi * map.frequency_hz();
  const Complex force_c1 = -map.model().mass_kg * omega * omega * figures.x1;
  if (map.amplitude_v() == 0.0) return 0.0;
  return force_c1 / Complex(0.0, -map.amplitude_v());
}

double SteadyState::ContactsPerPeriod() const {
  const int periods = period > 0 ? period : 16;
  return static_cast<double>(figures.contacts) / periods;
}

std::optional<FieldError> ShootingOptions::IsValid() const {
  if (plain_iterations < 0) return FieldError{"plain_iterations", "must be >= 0"};
  if (max_newton_iterations < 1) return FieldError{"max_newton_iterations", "must be >= 1"};
  if (!(tolerance > 0) || !std::isfinite(tolerance)) return FieldError{"tolerance", "must be a finite number > 0"};
  if (settle_periods < 0) return FieldError{"settle_periods", "must be >= 0"};
  if (max_period < 1) return FieldError{"max_period", "must be >= 1"};
  return std::nullopt;
}

std::optional<SteadyState> Shoot(const PeriodMap& map, State guess, int period, const ShootingOptions& options) {
  Validate(options);
  if (period < 1) throw InputError("period", "must be >= 1");
  const Scales scales = ScalesOf(map);
  auto apply = [&](State y) {
    for (int k = 0; k < period; ++k) y = map.Apply(y);
    return y;
  };
  State y = guess;
  double best = INFINITY;
  int stalled = 0;
  // The guess is rarely the orbit (the continuation's guesses need one Newton step): its pass only
  // linearizes, and a guess that is the orbit after all is traced again for its figures.
  OrbitFigures figures = map.Linearize(y, period);
  bool figures_traced = false;
  for (int iteration = 0; iteration < options.max_newton_iterations; ++iteration) {
    const State residual = Minus(figures.end, y);
    const double error = ScaledNorm(residual, scales);
    if (!std::isfinite(error)) return std::nullopt;
    if (error < options.tolerance) {
      SteadyState s;
      s.start = y;
      s.period = period;
      s.figures = figures_traced ? figures : map.Trace(y, period);
      s.multipliers = Eigenvalues(figures.monodromy);
      s.stable = s.MaxMultiplier() < 1.0;
      s.newton_iterations = iteration;
      return s;
    }
    // Stalled Newton (cycling, seen at high drive): give up and let the caller fall back.
    if (error < 0.5 * best) {
      best = error;
      stalled = 0;
    } else if (++stalled > 6) {
      return std::nullopt;
    }
    // Solve (M - I) step = -residual.
    const std::optional<State> step = SolveShiftedByIdentity(figures.monodromy, Minus(State{}, residual));
    if (!step) return std::nullopt;
    // Damped step: halve until the residual falls. The full step is traced, not only applied: it
    // is nearly always taken, and its trace is then the next iteration's (one map per iteration).
    const State full = Plus(y, 1.0, *step);
    OrbitFigures full_figures = map.Trace(full, period);
    if (ScaledNorm(Minus(full_figures.end, full), scales) < error) {
      y = full;
      figures = full_figures;
      figures_traced = true;
      continue;
    }
    double lambda = 0.5;
    for (int halving = 1; halving < 8; ++halving) {
      const State trial = Plus(y, lambda, *step);
      const double trial_error = ScaledNorm(Minus(apply(trial), trial), scales);
      if (trial_error < error || halving == 7) {
        y = trial;
        break;
      }
      lambda *= 0.5;
    }
    figures = map.Trace(y, period);
    figures_traced = true;
  }
  return std::nullopt;
}

namespace {

// The smallest p <= max_period with P^p(y) = y to within `tolerance` (scaled), from a point on an
// attractor; 0 if none.
int DetectPeriod(const PeriodMap& map, State y, int max_period, double tolerance) {
  const Scales scales = ScalesOf(map);
  State z = y;
  for (int p = 1; p <= max_period; ++p) {
    z = map.Apply(z);
    if (ScaledNorm(Minus(z, y), scales) < tolerance) return p;
  }
  return 0;
}

// The stable periodic orbit the settled motion from `y` follows, if its period is at most max_period.
std::optional<SteadyState> PeriodicOrbitOfSettled(const PeriodMap& map, State y, const ShootingOptions& options) {
  for (double tolerance : {1e-8, 1e-5}) {
    const int p = DetectPeriod(map, y, options.max_period, tolerance);
    if (p == 0) continue;
    // Newton may land on a divisor's orbit: keep the true period.
    if (std::optional<SteadyState> orbit = Shoot(map, y, p, options); orbit && orbit->stable) return orbit;
  }
  return std::nullopt;
}

// Plain periods from *y, as a test rig's transient: settle_periods of them, or fewer where the motion
// already repeats after one or two periods to 1e-9 (scaled; most orbits' multipliers are far below 1,
// so it takes a few) and the stable orbit of that period is found there. Returns that orbit, else the
// one PeriodicOrbitOfSettled finds after all the periods (nullopt if none); *y is the last state.
std::optional<SteadyState> SettleOntoOrbit(const PeriodMap& map, State* y, const ShootingOptions& options) {
  constexpr double kRepeatTolerance = 1e-9;
  const Scales scales = ScalesOf(map);
  State one_back = *y, two_back = *y;
  bool tried = false;
  for (int i = 0; i < options.settle_periods; ++i) {
    two_back = one_back;
    one_back = *y;
    *y = map.Apply(*y);
    if (tried || i < 2) continue;
    if (ScaledNorm(Minus(*y, one_back), scales) < kRepeatTolerance ||
        ScaledNorm(Minus(*y, two_back), scales) < kRepeatTolerance) {
      tried = true;  // once: where Newton fails here (a slow passage by a saddle), the full count follows
      if (std::optional<SteadyState> orbit = PeriodicOrbitOfSettled(map, *y, options)) return orbit;
    }
  }
  return PeriodicOrbitOfSettled(map, *y, options);
}

}  // namespace

SteadyState SolveAttractor(const PeriodMap& map, State guess, const ShootingOptions& options) {
  Validate(options);
  State y = guess;
  for (int i = 0; i < options.plain_iterations; ++i) y = map.Apply(y);
  const std::optional<SteadyState> period1 = Shoot(map, y, 1, options);
  if (period1 && period1->stable) return *period1;

  // Period-1 unstable or not found: settle on the attractor by plain iteration, starting next to
  // the unstable orbit (plain iteration from exactly on it would stay there for a while).
  if (period1) {
    y = period1->start;
    y.x_m += 1e-6 * LengthScaleM(map.model());
  }
  if (std::optional<SteadyState> orbit = SettleOntoOrbit(map, &y, options)) return *orbit;
  // No period found: aperiodic. Figures over max_period periods of the settled motion.
  SteadyState s;
  s.start = y;
  s.period = 0;
  s.figures = map.Trace(y, options.max_period);
  s.multipliers = Eigenvalues(s.figures.monodromy);
  s.stable = true;  // it is the attractor; its multipliers describe a finite stretch only
  return s;
}

std::optional<SteadyState> SettledAttractor(const PeriodMap& map, State guess, const ShootingOptions& options) {
  Validate(options);
  return SettleOntoOrbit(map, &guess, options);
}

}  // namespace strokelab
