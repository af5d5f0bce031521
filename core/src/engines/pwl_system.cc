#include "strokelab/engines/pwl_system.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "strokelab/base/sincos.h"

namespace strokelab {
namespace {

constexpr double kTimeToleranceS = 1e-14;  // switching instants are located to this [s]
// A mass this close to a stop counts as on its surface: an undamped stop lets go at x = d up to
// rounding, and the state just after must not count as "still inside" [m].
constexpr double kOnSurfaceM = 1e-15;

// h and its first two time derivatives on a surface at a state and time.
struct SurfaceValue {
  double h, dh, ddh;
};

// h, dh/dt and d2h/dt2 of a surface from the region's motion at one instant (one sin/cos of the
// drive phase shared by the state, the force and the surface).
SurfaceValue Evaluate(const Surface& s, const LinearRegion& region, double omega, const LinearRegion::Motion& m) {
  const State y = m.y;
  const double inv_mass = 1.0 / region.mass_kg();
  // x'' from the region's ODE, and x''' by differentiating it once more.
  const double acceleration = m.force_n * inv_mass;
  const double jerk = (region.sine_force_n() * omega * m.cos_theta - region.stiffness() * y.v_m_per_s -
                       region.damping() * acceleration) * inv_mass;
  return {s.alpha * y.x_m + s.beta * y.v_m_per_s + s.gamma + s.delta * m.sin_theta,
          s.alpha * y.v_m_per_s + s.beta * acceleration + s.delta * omega * m.cos_theta,
          s.alpha * acceleration + s.beta * jerk - s.delta * omega * omega * m.sin_theta};
}

// Zero of a smooth function g on [lo, hi] where g changes sign, by Newton's method kept inside a
// shrinking bracket (bisection when a step leaves it). g(tau) returns {g, dg/dtau}; lo_positive is
// the sign of g(lo) (known to every caller, which saves an evaluation).
template <class G>
double BracketedNewton(G&& g, double lo, double hi, bool lo_positive) {
  double tau = 0.5 * (lo + hi);
  for (int iteration = 0; iteration < 100; ++iteration) {
    const auto [value, slope] = g(tau);
    if (value == 0.0) return tau;
    if ((value > 0.0) == lo_positive) lo = tau; else hi = tau;
    double next = slope != 0.0 ? tau - value / slope : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - tau) < kTimeToleranceS || hi - lo < kTimeToleranceS) return next;
    tau = next;
  }
  return tau;
}

// The instant where h crosses zero in [lo, hi] (h(lo) >= 0 >= h(hi)).
template <class ValueAt>
double LocateRoot(ValueAt&& value_at, const Surface& s, double lo, double hi, bool lo_positive) {
  return BracketedNewton(
      [&](double tau) {
        const SurfaceValue v = value_at(s, tau);
        return std::pair{v.h, v.dh};
      },
      lo, hi, lo_positive);
}

// The extremum of h in [lo, hi] (dh/dt changes sign there, from the sign lo_positive at lo).
template <class ValueAt>
double LocateExtremum(ValueAt&& value_at, const Surface& s, double lo, double hi, bool lo_positive) {
  return BracketedNewton(
      [&](double tau) {
        const SurfaceValue v = value_at(s, tau);
        return std::pair{v.dh, v.ddh};
      },
      lo, hi, lo_positive);
}

}  // namespace

PiecewiseLinearSystem::PiecewiseLinearSystem(const ActuatorModel& model, const SineDrive& drive)
    : model_(model), drive_(drive) {
  if (!model.IsPiecewiseLinear())
    throw InputError("method", "the exact engine needs a piecewise-linear model; this one has " +
                                   model.NonlinearTerms() + " (use cvode or ode3)");
  const double w = drive.AngularFrequency();
  const double drive_period_s = 1.0 / drive.frequency_hz;
  for (int clip = -1; clip <= 1; ++clip) {
    if (clip != 0 && !model.HasAmplifierLimit()) continue;  // modes it cannot enter (a map is built per Newton step)
    for (int contacts = 0; contacts < 4; ++contacts) {
      PwlMode mode{{(contacts & 1) != 0, (contacts & 2) != 0}, clip};
      // Paper Eq. 2, continuous form: each pushing stop adds k_s (d - x) - c_s x'.
      double stiffness = model.stiffness_n_per_m, damping = model.damping_n_s_per_m, constant = 0.0;
      if (mode.contact.lower) {
        stiffness += model.contact_stiffness;
        damping += model.contact_damping_n_s_per_m;
        constant += model.contact_stiffness * model.lower_stop_m;
      }
      if (mode.contact.upper) {
        stiffness += model.contact_stiffness;
        damping += model.contact_damping_n_s_per_m;
        constant += model.contact_stiffness * model.upper_stop_m;
      }
      double sine_force = model.gain_n_per_v * drive.amplitude_v;
      if (clip != 0) {
        sine_force = 0.0;
        constant += clip * model.gain_n_per_v * model.amplifier_limit_v;
      }
      if (!std::isfinite(constant)) constant = 0.0;  // a mode the model cannot reach (no such stop)
      const LinearRegion region(model.mass_kg, damping, stiffness, sine_force, constant, w, drive.phase_rad);
      regions_[mode.Index()] = region;
      // At most one extremum of any surface function per substep: 1/8 of the shortest period.
      max_substep_s_[mode.Index()] = std::min(drive_period_s, region.NaturalTimeScaleS()) / 8.0;
    }
  }
}

const LinearRegion& PiecewiseLinearSystem::Region(PwlMode mode) const { return regions_[mode.Index()]; }

double PiecewiseLinearSystem::MaxSubstepS(PwlMode mode) const { return max_substep_s_[mode.Index()]; }

PwlMode PiecewiseLinearSystem::InitialMode(double time_s, State y) const {
  PwlMode mode;
  mode.contact = ModeFromState(model_, y.x_m, y.v_m_per_s);
  if (model_.HasAmplifierLimit()) {
    const double u = drive_.Voltage(time_s);
    mode.clip = u > model_.amplifier_limit_v ? 1 : (u < -model_.amplifier_limit_v ? -1 : 0);
  }
  return mode;
}

int PiecewiseLinearSystem::ActiveSurfaces(PwlMode mode, State y, std::array<Surface, 6>* out) const {
  const double ks = model_.contact_stiffness, cs = model_.contact_damping_n_s_per_m;
  int n = 0;
  using K = Surface::Kind;
  if (model_.HasLowerStop()) {
    const double d = model_.lower_stop_m;
    if (mode.contact.lower) {
      (*out)[n++] = {K::kLowerRelease, -ks, -cs, ks * d, 0};  // k_s (d - x) - c_s v: the push
    } else if (y.x_m >= d - kOnSurfaceM) {
      (*out)[n++] = {K::kLowerEnter, 1, 0, -d, 0};  // x - d
    } else {
      // Released inside the stop (a damped stop lets go before x returns to d): contact resumes
      // when the push turns positive again, or the mass simply leaves the stop region.
      (*out)[n++] = {K::kLowerEnter, ks, cs, -ks * d, 0};
      (*out)[n++] = {K::kLowerLeaveInside, -1, 0, d, 0};
    }
  }
  if (model_.HasUpperStop()) {
    const double d = model_.upper_stop_m;
    if (mode.contact.upper) {
      (*out)[n++] = {K::kUpperRelease, ks, cs, -ks * d, 0};  // k_s (x - d_u) + c_s v
    } else if (y.x_m <= d + kOnSurfaceM) {
      (*out)[n++] = {K::kUpperEnter, -1, 0, d, 0};  // d_u - x
    } else {
      (*out)[n++] = {K::kUpperEnter, -ks, -cs, ks * d, 0};
      (*out)[n++] = {K::kUpperLeaveInside, 1, 0, -d, 0};
    }
  }
  if (model_.HasAmplifierLimit()) {
    const double limit = model_.amplifier_limit_v, amplitude = drive_.amplitude_v;
    if (mode.clip == 0) {
      (*out)[n++] = {K::kClipUp, 0, 0, limit, -amplitude};    // L - V sin
      (*out)[n++] = {K::kClipDown, 0, 0, limit, amplitude};   // L + V sin
    } else {
      // clip V sin - L: positive while clipped on either side (V sin > L, or V sin < -L).
      (*out)[n++] = {K::kClipRelease, 0, 0, -limit, mode.clip * amplitude};
    }
  }
  return n;
}

double PiecewiseLinearSystem::SafeSpanS(PwlMode mode, const LinearRegion& r, double t, State y) const {
  std::array<Surface, 6> surfaces;
  const int count = ActiveSurfaces(mode, y, &surfaces);
  if (count == 0) return INFINITY;
  const double b2 = r.beta_squared();
  if (!(b2 > 0.0)) return 0.0;  // the bounds below are for the underdamped form
  const double omega = drive_.AngularFrequency();
  const double a = r.decay_rate(), b = std::sqrt(b2), omega0_sq = r.stiffness() / r.mass_kg();
  const State p = r.ParticularAt(t);
  const double zx = y.x_m - p.x_m, zv = y.v_m_per_s - p.v_m_per_s;
  // Amplitudes (for all later times, e^{-a tau} <= 1) of the particular and homogeneous parts of
  // x, x' and x'' (linear_region.h: z_x = e^{-a tau}(zx cos + (a zx + zv)/b sin), z_v likewise).
  // (sqrt rather than hypot, which is slow: these lengths can neither overflow nor underflow.)
  const auto length = [](double p, double q) { return std::sqrt(p * p + q * q); };
  const double particular_x = length(r.ps(), r.pc());
  const double homogeneous_x = length(zx, (a * zx + zv) / b);
  const double homogeneous_v = length(zv, (omega0_sq * zx + a * zv) / b);
  const double bound_x = particular_x + homogeneous_x;
  const double bound_v = omega * particular_x + homogeneous_v;
  const double bound_a = omega * omega * particular_x + omega0_sq * homogeneous_x + 2.0 * a * homogeneous_v;
  const double sin_theta = SinCosOf(omega * t + drive_.phase_rad).sin;
  double safe = INFINITY;
  for (int i = 0; i < count; ++i) {
    const Surface& s = surfaces[i];
    const double lowest = s.alpha * r.offset_m() + s.gamma - std::abs(s.alpha) * bound_x - std::abs(s.beta) * bound_v -
                          std::abs(s.delta);
    if (lowest > 0.0) continue;  // never reachable in this region
    const double h = s.alpha * y.x_m + s.beta * y.v_m_per_s + s.gamma + s.delta * sin_theta;
    if (!(h > 0.0)) return 0.0;
    const double rate = std::abs(s.alpha) * bound_v + std::abs(s.beta) * bound_a + std::abs(s.delta) * omega;
    safe = std::min(safe, h / rate);
  }
  return safe;
}

void PiecewiseLinearSystem::AppendExtrema(PwlMode mode, double t0, State y0, double span,
                                          std::vector<std::pair<double, State>>* out) const {
  const LinearRegion& region = Region(mode);
  const double inv_mass = 1.0 / region.mass_kg();
  // Every sample propagates from the same start: its homogeneous part once.
  const State z0 = region.HomogeneousAt(y0, t0);
  // The extrema of x are the zeros of v, located with the slope x''.
  auto velocity_at = [&](double tau) {
    const LinearRegion::Motion m = region.MotionAt(z0, t0, tau);
    return std::pair{m.y.v_m_per_s, m.force_n * inv_mass};
  };
  const int substeps = std::max(1, static_cast<int>(std::ceil(span / MaxSubstepS(mode))));
  double tau_a = 0.0;
  double v_a = y0.v_m_per_s;
  for (int i = 1; i <= substeps; ++i) {
    const double tau_b = span * i / substeps;
    const double v_b = region.PropagateHomogeneous(z0, t0, tau_b).v_m_per_s;
    if ((v_a < 0.0 && v_b > 0.0) || (v_a > 0.0 && v_b < 0.0)) {
      const double tau = BracketedNewton(velocity_at, tau_a, tau_b, v_a > 0.0);
      out->emplace_back(t0 + tau, region.PropagateHomogeneous(z0, t0, tau));
    }
    tau_a = tau_b;
    v_a = v_b;
  }
}

void PiecewiseLinearSystem::ThrowStuck(double time_s, State y) {
  char message[200];
  std::snprintf(message, sizeof message,
                "exact engine: switching surfaces chatter without time advancing at t = %.17g s "
                "(x = %.17g m, v = %.17g m/s)", time_s, y.x_m, y.v_m_per_s);
  throw NumericalError(message);
}

double PiecewiseLinearSystem::StepBudget(double t_s, double t_end_s) const {
  const double span_s = std::max(0.0, t_end_s - t_s);
  return budget_base_steps_ + (budget_steps_per_second_ + budget_steps_per_drive_period_ * drive_.frequency_hz) * span_s;
}

void PiecewiseLinearSystem::ThrowBudgetSpent(const char* what, double steps, double t_start_s, double t_end_s,
                                             double time_s, State y) const {
  char message[500];
  std::snprintf(message, sizeof message,
                "exact engine: %s: %.3g substeps and switches advanced t only from %.17g s to %.17g s of "
                "%.17g s (x = %.6g m, v = %.6g m/s) under the drive %.6g Hz, %.6g V; the model's time scales "
                "are too short to resolve (check k_s, m_p and the damping against the model bounds)",
                what, steps, t_start_s, time_s, t_end_s, y.x_m, y.v_m_per_s, drive_.frequency_hz,
                drive_.amplitude_v);
  throw WorkBudgetSpent(message);
}

PwlMode PiecewiseLinearSystem::Apply(PwlMode mode, Surface::Kind kind) const {
  using K = Surface::Kind;
  switch (kind) {
    case K::kLowerEnter: mode.contact.lower = true; break;
    case K::kLowerRelease: mode.contact.lower = false; break;
    case K::kUpperEnter: mode.contact.upper = true; break;
    case K::kUpperRelease: mode.contact.upper = false; break;
    case K::kClipUp: mode.clip = 1; break;
    case K::kClipDown: mode.clip = -1; break;
    case K::kClipRelease: mode.clip = 0; break;
    case K::kLowerLeaveInside:
    case K::kUpperLeaveInside: break;
  }
  return mode;
}

std::optional<PiecewiseLinearSystem::LocatedSwitch> PiecewiseLinearSystem::FirstSwitch(
    PwlMode mode, const LinearRegion& region, double t0, State y0, double span, bool skip_immediate) const {
  std::array<Surface, 6> surfaces;
  const int count = ActiveSurfaces(mode, y0, &surfaces);
  if (count == 0) return std::nullopt;
  const double w = drive_.AngularFrequency();
  // The motion at both ends once for all surfaces, and inside from the same homogeneous start.
  const State z0 = region.HomogeneousAt(y0, t0);
  LinearRegion::Motion start = region.MotionAt(z0, t0, 0.0);
  start.y = y0;  // the state itself, not its round trip through z0
  start.force_n = region.Force(y0, t0);
  const LinearRegion::Motion end = region.MotionAt(z0, t0, span);
  auto value_at = [&](const Surface& s, double tau) { return Evaluate(s, region, w, region.MotionAt(z0, t0, tau)); };

  std::optional<LocatedSwitch> first;
  for (int i = 0; i < count; ++i) {
    const Surface& s = surfaces[i];
    const SurfaceValue a = Evaluate(s, region, w, start);
    const SurfaceValue b = Evaluate(s, region, w, end);
    double lo = 0.0, hi = span;
    bool lo_positive = a.h > 0.0;
    if (a.h <= 0.0) {
      // On the surface already (just after a switch, or rounding): it switches now only if it is
      // heading across.
      if (a.dh < 0.0 && !skip_immediate) return LocatedSwitch{0.0, s};
      if (b.h > 0.0) continue;
      if (!(a.dh > 0.0 && b.dh < 0.0)) continue;
      // Rose off the surface and came back: the crossing lies after the maximum.
      lo = LocateExtremum(value_at, s, 0.0, span, true);
      lo_positive = value_at(s, lo).h > 0.0;
    } else if (b.h > 0.0) {
      // Both ends clear: it can still dip through zero in between (grazing) if h has a minimum there.
      if (!(a.dh < 0.0 && b.dh > 0.0)) continue;
      const double tau_min = LocateExtremum(value_at, s, 0.0, span, false);
      if (value_at(s, tau_min).h > 0.0) continue;
      hi = tau_min;
    }
    if (first && lo >= first->tau_s) continue;
    const double tau = LocateRoot(value_at, s, lo, hi, lo_positive);
    if (!first || tau < first->tau_s) first = LocatedSwitch{tau, s};
  }
  return first;
}

}  // namespace strokelab
