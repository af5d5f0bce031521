// Steady-state sweeps over an amplitude x frequency grid: periodic
// orbits by shooting, continued in frequency by pseudo-arclength continuation through folds; the
// saturation threshold per frequency (grazing amplitude and lowest contacting amplitude, by
// root-finding), the jump (bistable) intervals per amplitude, and the first-order FRFs of the up-
// and down-sweep branches (paper Fig. 4, 5, 10).
#pragma once

#include <atomic>
#include <complex>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "strokelab/base/errors.h"  // Cancelled
#include "strokelab/model/model.h"

namespace strokelab {

// An inclusive range sampled at `points` values, linearly or geometrically.
struct GridAxis {
  double from = 0.0, to = 0.0;
  int points = 1;
  bool geometric = false;  // true: from * (to/from)^(i/(points-1)) (paper Eq. 1 is geometric)
  std::vector<double> Values() const;
};

struct SweepSpec {
  ActuatorModel model;
  GridAxis frequency_hz{5.0, 50.0, 117, true};
  GridAxis amplitude_v{0.1, 0.6, 6, false};
  int threads = 1;
  // Locate the saturation threshold per frequency (a root search per column). The jump intervals
  // per amplitude come with the rows and are given either way.
  bool thresholds = true;
  // A row or column whose numerics fail (NumericalError) leaves a hole, listed in
  // SweepResult::failures (no steady states at that amplitude, NaN thresholds at that frequency),
  // instead of failing the whole sweep: for maps that are better with a hole than missing (the
  // diagnosis report's). Off: the first failure is thrown, as a job or `strokelab sweep` needs.
  bool skip_failed_units = false;
  // Nothing, or the wrong field (frequency_hz.to, amplitude_v.points, a model key, ...).
  std::optional<FieldError> IsValid() const;
};

enum class Branch { kUp, kDown, kUnstable };
const char* ToString(Branch branch);

// One steady state at one grid point on one branch.
struct SweepPoint {
  double frequency_hz = 0.0;
  double amplitude_v = 0.0;
  Branch branch = Branch::kUp;
  bool stable = true;
  int period = 1;                       // in drive periods; 0: aperiodic (no period found up to 16)
  std::complex<double> h;               // first-order FRF C1(f)/C1(v_in) [N/V] (paper Eq. 3 convention)
  double first_harmonic_force_n = 0.0;  // |C1(f)|
  double first_harmonic_phase_rad = 0.0;// arg H
  double min_displacement_m = 0.0;
  double max_displacement_m = 0.0;
  double peak_force_n = 0.0;
  double contacts_per_period = 0.0;     // impacts per drive period (averaged over the orbit's period)
  double max_multiplier = 0.0;          // largest |Floquet multiplier| of the orbit
};

// Per frequency: between the two amplitudes the actuator is bistable in amplitude.
struct SaturationThreshold {
  double frequency_hz = 0.0;
  double grazing_amplitude_v = 0.0;        // the non-contacting response first touches the stop
  double lowest_contact_amplitude_v = 0.0; // lowest amplitude with a stable contacting response
};

// Per amplitude, an interval of frequency where two stable periodic responses coexist, and what
// bounds it on each side ("fold", "grazing", "period-doubling", "grid" when it runs off the grid).
struct JumpInterval {
  double amplitude_v = 0.0;
  double bistable_from_hz = 0.0, bistable_to_hz = 0.0;
  std::string from_kind, to_kind;
};

struct SweepResult {
  std::vector<double> frequency_hz, amplitude_v;  // the grid
  std::vector<SweepPoint> points;  // by amplitude, then frequency, then branch (up, down, unstable...)
  std::vector<SaturationThreshold> saturation_threshold;  // one per grid frequency
  std::vector<JumpInterval> jump;
  // With SweepSpec::skip_failed_units, the rows and columns that failed: "row at 0.28 V: <what>",
  // "column at 9.5 Hz: <what>", in grid order. Empty otherwise.
  std::vector<std::string> failures;
  double wall_time_s = 0.0;
  double points_per_second = 0.0;  // grid points (frequency x amplitude) per second of wall time
};

// A sweep's progress in units of work: its grid points (frequency x amplitude; a row's count as its
// continuation in frequency passes them, so that a row of a smooth model, seconds long, moves the
// count point by point) and its threshold columns (one unit each).
struct SweepProgress {
  size_t done = 0, total = 0;
};

// The two units of work a sweep is made of (the service runs them as separate tasks):
// a row, every grid frequency at one amplitude (continuation in frequency, jump intervals) ...
struct SweepRowResult {
  std::vector<SweepPoint> points;   // by frequency, then branch
  std::vector<JumpInterval> jumps;
};
// `passed` (may be empty) hears how many grid frequencies the row's continuation has passed, each
// time that count grows (up to frequencies_hz.size()), from the calling thread.
SweepRowResult SweepRow(const ActuatorModel& model, double amplitude_v, const std::vector<double>& frequencies_hz,
                        const std::atomic<bool>* cancel = nullptr,
                        const std::function<void(size_t points)>& passed = {});
// ... and a column, the saturation threshold at one frequency.
SaturationThreshold SweepColumn(const ActuatorModel& model, double frequency_hz, const std::atomic<bool>* cancel = nullptr);

// Runs the sweep on spec.threads threads. Results do not depend on the thread count. `progress` is
// called from worker threads (serialise inside it if needed); `cancel` (without one, the calling
// thread's CancelScope flag, base/cancel.h) stops the units and the engines' loops within a few ms,
// and the call throws Cancelled. SweepRow and SweepColumn take the flag the same way.
SweepResult RunSweep(const SweepSpec& spec, const std::function<void(const SweepProgress&)>& progress = {},
                     const std::atomic<bool>* cancel = nullptr);

}  // namespace strokelab
