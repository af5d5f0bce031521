// A piecewise-linear actuator model as a hybrid system: a discrete mode (which stops push, whether
// the amplifier clips) selects a LinearRegion, and switching surfaces, all of the form
//
//   h(t) = alpha x + beta v + gamma + delta sin(w t + phi),
//
// end a region. Switching instants are located on the closed form (safeguarded Newton to 1e-14 s),
// grazing (h touching zero between two evaluations) included. Used by the exact engine and by the
// steady-state solver.
#pragma once

#include <algorithm>
#include <cstdint>
#include <array>
#include <cmath>
#include <optional>
#include <utility>
#include <vector>

#include "strokelab/base/cancel.h"
#include "strokelab/model/dynamics.h"
#include "strokelab/engines/engine.h"
#include "strokelab/engines/linear_region.h"
#include "strokelab/model/model.h"

namespace strokelab {

struct PwlMode {
  ContactMode contact;
  int clip = 0;  // -1, 0, +1: drive clipped at -limit, free, clipped at +limit
  bool operator==(const PwlMode&) const = default;
  int Index() const { return (contact.lower ? 1 : 0) + (contact.upper ? 2 : 0) + 4 * (clip + 1); }
};

// A switching surface of one mode; h > 0 before the switch.
struct Surface {
  enum class Kind {
    kLowerEnter, kLowerRelease, kLowerLeaveInside,   // the last changes no dynamics (see .cc)
    kUpperEnter, kUpperRelease, kUpperLeaveInside,
    kClipUp, kClipDown, kClipRelease,
  };
  Kind kind;
  double alpha = 0, beta = 0, gamma = 0, delta = 0;
};

// Where and what a located switch was.
struct SwitchEvent {
  double time_s = 0.0;
  State state;
  PwlMode before, after;
  Surface surface;  // the surface crossed
};

class PiecewiseLinearSystem {
 public:
  // Throws InputError("method") if the model is not piecewise linear.
  PiecewiseLinearSystem(const ActuatorModel& model, const SineDrive& drive);

  const ActuatorModel& model() const { return model_; }
  // The longest step over which any switching function has at most one extremum [s].
  double MaxSubstepS(PwlMode mode) const;

  // The work budget of one Advance over (t, t_end) (issue 15: k_s = 1e40 made substeps of 1e-21 s,
  // below the resolution of t, and the loop never ended): kBudgetBaseSteps plus, per simulated
  // second, kBudgetStepsPerSecond and kBudgetStepsPerDrivePeriod per drive period. A model within
  // ModelBounds needs at most 8 substeps per period of its fastest region (1 MHz: 8e6 per second, a
  // sixth of the budget) or of the drive (8 f), and a few switches per contact; the budget is spent
  // only outside those bounds or by a defect, and then ends the call (a step costs ~0.5 us, so a
  // per-sample call ends at once and a period map of 1/8 s within seconds) instead of never.
  // Substeps that no longer move t on and a non-finite state end it at once.
  static constexpr double kBudgetBaseSteps = 1000;
  static constexpr double kBudgetStepsPerSecond = 5e7;
  static constexpr double kBudgetStepsPerDrivePeriod = 64;
  double StepBudget(double t_s, double t_end_s) const;
  // A smaller budget (tests of what happens when it is spent).
  void SetStepBudget(double base_steps, double steps_per_second, double steps_per_drive_period) {
    budget_base_steps_ = base_steps;
    budget_steps_per_second_ = steps_per_second;
    budget_steps_per_drive_period_ = steps_per_drive_period;
  }
  const SineDrive& drive() const { return drive_; }
  const LinearRegion& Region(PwlMode mode) const;
  PwlMode InitialMode(double time_s, State y) const;

  // The extrema of x (v = 0) strictly inside (t0, t0 + span) of one region, appended to *out as
  // (time, state) pairs; located to 1e-14 s.
  void AppendExtrema(PwlMode mode, double t0, State y0, double span, std::vector<std::pair<double, State>>* out) const;

  // Advances (t, y, mode) to t_end, locating every switch on the closed form; calls
  // on_switch(const SwitchEvent&) at each switch that changes the mode.
  // Throws WorkBudgetSpent (errors.h) naming the budget and the drive when one call takes more than
  // StepBudget(t, t_end) substeps and switches (see kBudgetStepsPerSecond).
  template <class OnSwitch>
  void Advance(double* t, State* y, PwlMode* mode, double t_end, OnSwitch&& on_switch) const {
    int immediate_switches = 0;
    const double t_start = *t, budget = StepBudget(*t, t_end);
    double steps = 0;
    while (*t < t_end) {
      if ((static_cast<uint64_t>(steps) & 16383) == 0) ThrowIfCancelled();  // cancel.h: a few ms apart
      if (++steps > budget) ThrowBudgetSpent("work budget spent", budget, t_start, t_end, *t, *y);
      const LinearRegion& region = Region(*mode);
      // Far from every surface, a bound on how fast the surfaces can be approached lets the step
      // skip ahead without looking for switches (often straight to t_end).
      const double safe = SafeSpanS(*mode, region, *t, *y);
      if (!std::isfinite(y->x_m) || !std::isfinite(y->v_m_per_s))
        ThrowBudgetSpent("the state is not finite", steps, t_start, t_end, *t, *y);
      if (safe > MaxSubstepS(*mode) || safe >= t_end - *t) {
        const double t1 = std::min(t_end, *t + safe);
        if (t1 == *t) ThrowBudgetSpent("substeps below the resolution of t", steps, t_start, t_end, *t, *y);
        *y = region.Propagate(*y, *t, t1 - *t);
        *t = t1;
        continue;
      }
      const double t1 = std::min(t_end, *t + MaxSubstepS(*mode));
      // A substep below the resolution of t would spend any budget without moving on.
      if (t1 == *t) ThrowBudgetSpent("substeps below the resolution of t", steps, t_start, t_end, *t, *y);
      const std::optional<LocatedSwitch> hit = FirstSwitch(*mode, region, *t, *y, t1 - *t, immediate_switches > 3);
      if (!hit) {
        *y = region.Propagate(*y, *t, t1 - *t);
        *t = t1;
        continue;
      }
      // A switch that does not move time on (tau below the resolution of t) must not repeat forever.
      const bool no_progress = *t + hit->tau_s == *t;
      immediate_switches = no_progress ? immediate_switches + 1 : 0;
      if (immediate_switches > 8) ThrowStuck(*t, *y);
      *y = region.Propagate(*y, *t, hit->tau_s);
      *t += hit->tau_s;
      const PwlMode after = Apply(*mode, hit->surface.kind);
      if (!(after == *mode)) on_switch(SwitchEvent{*t, *y, *mode, after, hit->surface});
      *mode = after;
    }
  }

 private:
  struct LocatedSwitch {
    double tau_s;
    Surface surface;
  };
  int ActiveSurfaces(PwlMode mode, State y, std::array<Surface, 6>* out) const;
  // A span from t over which no surface of the mode can be reached (from amplitude bounds on the
  // closed form); 0 when none can be guaranteed, +inf when no surface is reachable at all.
  double SafeSpanS(PwlMode mode, const LinearRegion& region, double t, State y) const;
  std::optional<LocatedSwitch> FirstSwitch(PwlMode mode, const LinearRegion& region, double t0, State y0,
                                           double span_s, bool skip_immediate) const;
  PwlMode Apply(PwlMode mode, Surface::Kind kind) const;
  [[noreturn]] static void ThrowStuck(double time_s, State y);
  [[noreturn]] void ThrowBudgetSpent(const char* what, double steps, double t_start_s, double t_end_s, double time_s, State y) const;

  ActuatorModel model_;
  SineDrive drive_;
  std::array<LinearRegion, 12> regions_;
  std::array<double, 12> max_substep_s_{};
  double budget_base_steps_ = kBudgetBaseSteps, budget_steps_per_second_ = kBudgetStepsPerSecond;
  double budget_steps_per_drive_period_ = kBudgetStepsPerDrivePeriod;
};

}  // namespace strokelab
