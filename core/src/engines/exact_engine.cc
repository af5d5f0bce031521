// The exact engine: closed-form propagation through each linear region of a piecewise-linear model
// (linear_region.h), switching instants located on the closed form (pwl_system.h).
//
// Speed comes from the uniform output grid: inside a region, one output step is a fixed 2x2
// transition of the homogeneous part, exp(A dt), and a fixed rotation of (sin, cos) of the drive
// phase, so a sample costs a few multiply-adds and no transcendental function. Only a sample that
// lands near or across a switching surface takes the slow path (Advance from the previous sample,
// with every switch located to 1e-14 s); the phase rotation is re-anchored every 1024 samples.
#include <cmath>

#include "strokelab/base/cancel.h"
#include "strokelab/engines/engine.h"
#include "strokelab/engines/pwl_system.h"
#include "contact_log.h"

namespace strokelab {
namespace {

constexpr size_t kReanchorEvery = 1024;  // samples between exact re-evaluations of sin/cos

// What one output step costs inside one region.
struct FastRegion {
  Transition step;         // exp(A dt)
  Transition steps[4];     // exp(A k dt), k = 1..4, for the four-lane loop
  double ps, pc, offset, omega, stiffness, damping, sine_force, constant_force;
};

// The cheap per-sample test of whether a switch may lie in the step just taken. Held by value in
// the hot loop so that nothing in it is reloaded from memory after each store.
struct SwitchGuard {
  bool lower, upper, clips;
  double d_lower, d_upper, ks, cs, limit, amplitude;
  double clip_margin_v;   // a sinusoid of amplitude V dips at most V (w dt)^2 / 8 between samples; 8x
  double dip_per_force;   // a mass dips at most |F|/m dt^2 / 8 between samples; 8x margin [m/N]
  ContactMode contact;
  int clip;

  // True (per lane, for vectors) where the step just taken may hold a switch.
  template <class T>
  auto NeedsAttention(T x, T v, T force, T sin_theta) const {
    const T abs_force = force < 0.0 ? -force : force;
    const T near_m = abs_force * dip_per_force + 1e-12;
    auto mask = x != x;  // false in every lane
    if (lower) mask = mask | (contact.lower ? ks * (d_lower - x) - cs * v <= 0.0 : x < d_lower + near_m);
    if (upper) mask = mask | (contact.upper ? ks * (x - d_upper) + cs * v <= 0.0 : x > d_upper - near_m);
    if (clips) {
      const T u = amplitude * sin_theta;
      const T abs_u = u < 0.0 ? -u : u;
      if (clip == 0) mask = mask | (abs_u > limit - clip_margin_v);
      else if (clip > 0) mask = mask | (u < limit + clip_margin_v);
      else mask = mask | (u > -limit - clip_margin_v);
    }
    return mask;
  }
};

// Recurrence state at sample n: (sin, cos) of the drive phase and the homogeneous part z = y - y_p.
struct Recurrence {
  double sin_t = 0, cos_t = 0;
  State z;
};

double RegionForce(const FastRegion& r, double x, double v, double sin_theta) {
  return r.sine_force * sin_theta + r.constant_force - r.stiffness * x - r.damping * v;
}

// Steps the recurrences from sample `begin` while no sample needs attention, writing samples
// [begin, returned index). The returned sample (if < end) was not written: it needs the slow path.
size_t RunFast(const FastRegion& region, const SwitchGuard& guard_in, Recurrence* recurrence, double rot_c,
               double rot_s, size_t begin, size_t end, double* __restrict x_out, double* __restrict v_out,
               double* __restrict f_out, State* last) {
  const FastRegion r = region;
  const SwitchGuard guard = guard_in;
  double sin_t = recurrence->sin_t, cos_t = recurrence->cos_t;
  double zx = recurrence->z.x_m, zv = recurrence->z.v_m_per_s;
  double x_last = last->x_m, v_last = last->v_m_per_s;
  size_t n = begin;
  for (; n < end; ++n) {
    const double s_next = sin_t * rot_c + cos_t * rot_s;
    const double c_next = cos_t * rot_c - sin_t * rot_s;
    const double zx_next = r.step.xx * zx + r.step.xv * zv;
    const double zv_next = r.step.vx * zx + r.step.vv * zv;
    const double x = zx_next + r.ps * s_next + r.pc * c_next + r.offset;
    const double v = zv_next + r.omega * (r.ps * c_next - r.pc * s_next);
    const double force = RegionForce(r, x, v, s_next);
    if (guard.NeedsAttention(x, v, force, s_next)) break;
    x_out[n] = x;
    if (v_out) v_out[n] = v;
    f_out[n] = force;
    sin_t = s_next;
    cos_t = c_next;
    zx = zx_next;
    zv = zv_next;
    x_last = x;
    v_last = v;
  }
  *recurrence = {sin_t, cos_t, {zx, zv}};
  *last = {x_last, v_last};
  return n;
}

// Four consecutive samples per iteration, one per vector lane, each lane advanced by 4 dt: the
// recurrences are latency-bound chains, and four independent chains keep the FPU busy.
using Lanes = double __attribute__((vector_size(32)));

struct Rotations {
  double c[5], s[5];  // cos and sin of k w dt, k = 0..4
};

// As RunFast, from the recurrence at sample begin-1; stops at a multiple of four samples before
// `end` (the scalar RunFast takes the rest) or at the first sample that needs attention.
size_t RunFast4(const FastRegion& region, const SwitchGuard& guard, const Recurrence& at_previous,
                const Rotations& rot, size_t begin, size_t end, double* __restrict x_out, double* __restrict v_out,
                double* __restrict f_out, State* last) {
  const FastRegion r = region;
  Lanes sin_l, cos_l, zx, zv;
  for (int k = 0; k < 4; ++k) {
    const double s0 = at_previous.sin_t, c0 = at_previous.cos_t;
    sin_l[k] = s0 * rot.c[k + 1] + c0 * rot.s[k + 1];
    cos_l[k] = c0 * rot.c[k + 1] - s0 * rot.s[k + 1];
    const State z = r.steps[k].Apply(at_previous.z);
    zx[k] = z.x_m;
    zv[k] = z.v_m_per_s;
  }
  const Transition& p4 = r.steps[3];
  size_t n = begin;
  for (; n + 4 <= end; n += 4) {
    const Lanes x = zx + r.ps * sin_l + r.pc * cos_l + r.offset;
    const Lanes v = zv + r.omega * (r.ps * cos_l - r.pc * sin_l);
    const Lanes force = r.sine_force * sin_l + r.constant_force - r.stiffness * x - r.damping * v;
    const auto mask = guard.NeedsAttention(x, v, force, sin_l);
    if (mask[0] | mask[1] | mask[2] | mask[3]) {
      int k = 0;
      while (!mask[k]) {
        x_out[n + k] = x[k];
        if (v_out) v_out[n + k] = v[k];
        f_out[n + k] = force[k];
        *last = {x[k], v[k]};
        ++k;
      }
      return n + k;
    }
    for (int k = 0; k < 4; ++k) {
      x_out[n + k] = x[k];
      f_out[n + k] = force[k];
    }
    if (v_out)
      for (int k = 0; k < 4; ++k) v_out[n + k] = v[k];
    *last = {x[3], v[3]};
    const Lanes s_next = sin_l * rot.c[4] + cos_l * rot.s[4];
    cos_l = cos_l * rot.c[4] - sin_l * rot.s[4];
    sin_l = s_next;
    const Lanes zx_next = p4.xx * zx + p4.xv * zv;
    zv = p4.vx * zx + p4.vv * zv;
    zx = zx_next;
  }
  return n;
}

class ExactEngine final : public Engine {
 public:
  Method method() const override { return Method::kExact; }


 protected:
  void Run(const ActuatorModel& model, const SineDrive& drive, const SimulationOptions& options,
           Record* out) const override {
    const PiecewiseLinearSystem system(model, drive);
    const size_t count = options.SampleCount();
    const double fs = options.sample_rate_hz, dt = 1.0 / fs;
    const double omega = drive.AngularFrequency(), phase = drive.phase_rad;

    out->sample_rate_hz = fs;
    out->displacement_m.resize(count);
    out->force_n.resize(count);
    out->in_contact.resize(count);
    if (options.record_velocity) out->velocity_m_per_s.resize(count); else out->velocity_m_per_s.clear();
    out->contacts.clear();
    out->rhs_evaluations = 0;
    double* const x_out = out->displacement_m.data();
    double* const f_out = out->force_n.data();
    double* const v_out = options.record_velocity ? out->velocity_m_per_s.data() : nullptr;

    State y = options.initial;
    PwlMode mode = system.InitialMode(0.0, y);
    ContactLog contacts(&out->contacts, mode.contact);
    auto on_switch = [&](const SwitchEvent& e) { contacts.Update(e.time_s, e.after.contact); };

    std::array<std::optional<FastRegion>, 12> fast_cache;
    auto fast_region = [&](PwlMode m) -> const FastRegion& {
      std::optional<FastRegion>& slot = fast_cache[m.Index()];
      if (!slot) {
        const LinearRegion& r = system.Region(m);
        slot = FastRegion{r.Propagator(dt),
                          {r.Propagator(dt), r.Propagator(2 * dt), r.Propagator(3 * dt), r.Propagator(4 * dt)},
                          r.ps(), r.pc(), r.offset_m(), r.omega(), r.stiffness(), r.damping(),
                          r.sine_force_n(), r.constant_force_n()};
      }
      return *slot;
    };

    SwitchGuard guard{model.HasLowerStop(), model.HasUpperStop(), model.HasAmplifierLimit(),
                      model.lower_stop_m, model.upper_stop_m, model.contact_stiffness,
                      model.contact_damping_n_s_per_m, model.amplifier_limit_v, drive.amplitude_v,
                      drive.amplitude_v * (omega * dt) * (omega * dt) + 1e-12, dt * dt / model.mass_kg,
                      mode.contact, mode.clip};

    const double rot_c = std::cos(omega * dt), rot_s = std::sin(omega * dt);
    Rotations rotations;
    for (int k = 0; k <= 4; ++k) {
      rotations.c[k] = std::cos(k * omega * dt);
      rotations.s[k] = std::sin(k * omega * dt);
    }
    Recurrence recurrence;
    // Exact (sin, cos) and homogeneous part at sample n, in the current mode.
    auto anchor = [&](size_t n, State state) {
      const double theta = omega * (static_cast<double>(n) / fs) + phase;
      const FastRegion& r = fast_region(mode);
      recurrence.sin_t = std::sin(theta);
      recurrence.cos_t = std::cos(theta);
      recurrence.z = {state.x_m - (r.ps * recurrence.sin_t + r.pc * recurrence.cos_t + r.offset),
                      state.v_m_per_s - r.omega * (r.ps * recurrence.cos_t - r.pc * recurrence.sin_t)};
      guard.contact = mode.contact;
      guard.clip = mode.clip;
    };
    // Sample n from the closed form, every switch in (t_{n-1}, t_n] located: the slow path.
    auto exact_step = [&](size_t n) {
      double t = static_cast<double>(n - 1) / fs;
      system.Advance(&t, &y, &mode, static_cast<double>(n) / fs, on_switch);
      anchor(n, y);
    };
    auto write_sample = [&](size_t n) {
      x_out[n] = y.x_m;
      if (v_out) v_out[n] = y.v_m_per_s;
      f_out[n] = RegionForce(fast_region(mode), y.x_m, y.v_m_per_s, recurrence.sin_t);
    };

    anchor(0, y);
    write_sample(0);
    out->in_contact[0] = mode.contact.Any();
    size_t n = 1;
    while (n < count) {
      ThrowIfCancelled();  // cancel.h; once per run of at most kReanchorEvery samples
      // A run ends at a sample that needs the slow path, or at a re-anchoring point.
      const size_t run_end = std::min(count, (n / kReanchorEvery + 1) * kReanchorEvery);
      size_t stop = RunFast4(fast_region(mode), guard, recurrence, rotations, n, run_end, x_out, v_out, f_out, &y);
      bool attention = stop + 4 <= run_end;
      if (!attention && stop < run_end) {
        // Fewer than four samples left in the run: the scalar loop, from sample stop - 1.
        if (stop > n) anchor(stop - 1, y);
        stop = RunFast(fast_region(mode), guard, &recurrence, rot_c, rot_s, stop, run_end, x_out, v_out, f_out, &y);
        attention = stop < run_end;
      }
      std::fill(out->in_contact.begin() + static_cast<std::ptrdiff_t>(n),
                out->in_contact.begin() + static_cast<std::ptrdiff_t>(stop), mode.contact.Any());
      n = stop;
      if (n == count) break;
      if (attention) {
        exact_step(n);  // y: sample n-1 -> n
        write_sample(n);
        out->in_contact[n] = mode.contact.Any();
        ++n;
      }
      anchor(n - 1, y);  // fresh sin/cos; y is sample n-1
    }
    // The final state at t = N / fs, one step past the last sample.
    exact_step(count);
    out->final_state = y;
    contacts.Finish(static_cast<double>(count) / fs);
  }
};
}  // namespace

std::unique_ptr<Engine> MakeExactEngine() { return std::make_unique<ExactEngine>(); }

}  // namespace strokelab
