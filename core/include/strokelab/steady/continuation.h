// Pseudo-arclength continuation of period-1 orbits in drive frequency (at fixed amplitude) or in
// drive amplitude (at fixed frequency), through folds, so that both stable branches and the
// unstable one between them come out (Keller's method; e.g. Seydel, "Practical Bifurcation and
// Stability Analysis", 3rd ed., Springer 2010, sections 4.4-4.5).
//
// Unknowns u = (x0 / L, v0 / (w_ref L), p / p_ref), with (x0, v0) the orbit's state at phase 0 and p
// the parameter (and F_e0 / (k_p L), the coil's force, for models with the coil's pole: model.h); the
// orbit solves G(u) = P(y0; p) - y0 = 0 (steady_state.h). Predictor along the tangent (the null vector
// of dG/du: the cross product of its two rows, or the signed minors of its three); corrector: Newton on
// [G(u); t . (u - u_pred)] = 0. Along the branch, sign changes mark events: a fold (dp/ds changes
// sign), grazing (the orbit's contact count changes: min x crosses the stop), a change of stability
// (a Floquet multiplier leaves the unit circle); each is located by bisection along the arclength to
// 1e-9 relative in p. In this non-smooth system a branch may turn at a grazing point (a corner, not a
// smooth fold): such a turn is reported as grazing.
#pragma once

#include <atomic>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "strokelab/steady/steady_state.h"

namespace strokelab {

enum class ContinuationParameter { kFrequencyHz, kAmplitudeV };

struct BranchPoint {
  double parameter = 0.0;  // frequency [Hz] or amplitude [V]
  State start;
  // The branch's own points, folds and stability changes carry the contact count and the monodromy
  // only (no extrema or harmonics: continuation linearizes); SolveAt's, SolutionsAt's and grazing
  // points carry all figures.
  OrbitFigures figures;
  std::vector<std::complex<double>> multipliers;  // one per state component
  bool stable = false;
  double dparameter_ds = 0.0;  // tangent's parameter component (sign: direction of travel)
  double arclength = 0.0;      // scaled units
  bool contacting() const { return figures.contacts > 0; }
  double MaxMultiplier() const;
};

struct BranchEvent {
  enum class Kind { kFold, kGrazing, kStabilityChange };
  Kind kind;
  size_t after;          // between points[after] and points[after + 1]
  BranchPoint point;     // located on the branch
  bool period_doubling = false;  // a stability change through a multiplier at -1
};
const char* ToString(BranchEvent::Kind kind);

struct ContinuationOptions {
  double initial_step = 0.01;  // scaled arclength
  double min_step = 1e-7;
  double max_step = 0.08;
  int max_points = 3000;
  int max_corrector_iterations = 8;
  double tolerance = 1e-11;    // scaled residual
  bool locate_events = true;
  // Stop at the first fold, grazing point or loss of stability that is not a period doubling.
  bool stop_at_first_event = false;
  // Reporting only: called with the parameter of each point the branch reaches (may be empty).
  std::function<void(double parameter)> on_point;
  std::optional<FieldError> IsValid() const;
};

struct ContinuedBranch {
  ContinuationParameter parameter;
  double fixed_value = 0.0;            // the amplitude [V] or frequency [Hz] held fixed
  std::vector<BranchPoint> points;
  std::vector<BranchEvent> events;     // in order along the branch
  std::string stopped_because;         // "range", "max_points", "corrector failed at p = ..."
};

// Follows the branch through `start` (a period-1 orbit at parameter p0, e.g. from Shoot) in the
// direction where the parameter first `increases` (or decreases), until the parameter leaves
// [p_min, p_max]. `cancel` is polled once per step.
ContinuedBranch ContinueBranch(const ActuatorModel& model, ContinuationParameter which, double fixed_value,
                               double p0, State start, double p_min, double p_max, bool increasing,
                               const ContinuationOptions& options = {}, const std::atomic<bool>* cancel = nullptr);

// Every period-1 orbit of the branch at parameter p: one per crossing of p by the branch, solved
// at p by Newton from the interpolated state (arclength bisection when Newton fails), in order
// along the branch.
std::vector<BranchPoint> SolutionsAt(const ActuatorModel& model, const ContinuedBranch& branch, double p);

// The grazing point of the non-contacting orbit family through `noncontacting`: the parameter at
// which the orbit of the model without stops first touches a stop, to 1e-12 relative (the family is
// smooth, so a secant search and Illinois regula falsi converge fast). nullopt if none is found.
std::optional<BranchPoint> LocateGrazing(const ActuatorModel& model, ContinuationParameter which, double fixed_value,
                                         const BranchPoint& noncontacting);

// The orbit at a fixed parameter value, with its figures and multipliers (Newton from `guess`).
std::optional<BranchPoint> SolveAt(const ActuatorModel& model, ContinuationParameter which, double fixed_value,
                                   double p, State guess, const ShootingOptions& options = {});

}  // namespace strokelab
