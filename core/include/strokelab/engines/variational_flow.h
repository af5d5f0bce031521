// The flow of any model over a time interval, with exact first-order sensitivities: the state is
// integrated together with its variational equations,
//
//   s' = (df/dy) s + df/dp,   s(t0) = I (columns d/dy0) or 0 (columns d/dp),
//
// by the Dormand-Prince 8(5,3) pair with dense output (Hairer, Norsett and Wanner, "Solving Ordinary
// Differential Equations I", 2nd ed., Springer 1993, Sec. II.5-II.6; error control on the state and
// the sensitivity columns, not on the quadratures).
// The contact mode is tracked as the cvode engine tracks it (engine.h): every switching surface (stop
// entry through p = 0 or through a rising stop force, release where the stop force falls through 0,
// a grazing entry seen at an apex of x) is located on the dense output, the step is cut there, and
// every sensitivity column s gets the jump of a switch at a state-dependent instant tau,
//
//   s+ = s- - (f+ - f-) dtau,   dtau = -(grad(h) . s- + dh/dp) / (grad(h) . f-)
//
// (the saltation matrix S = I + (f+ - f-) grad(h)^T / (grad(h) . f-) for columns d/dy0; Mueller,
// "Calculation of Lyapunov exponents for dynamic systems with discontinuities", Chaos, Solitons &
// Fractals 5(9), 1995; Leine & Nijmeijer, "Dynamics and Bifurcations of Non-smooth Mechanical Systems",
// Springer 2004, ch. 7). The amplifier's clipping kinks are step boundaries (their instants are known;
// the force is continuous there, so no jump). Quadratures of x e^{-jhwt} (and of each sensitivity's x)
// are integrated as extra components: the orbit's harmonics and their derivatives, exact to the
// integrator's order.
#pragma once

#include <complex>
#include <cstddef>
#include <optional>
#include <vector>

#include "strokelab/engines/engine.h"
#include "strokelab/model/dynamics.h"
#include "strokelab/model/model.h"

namespace strokelab {

struct FlowRequest {
  bool monodromy = false;                           // columns d/d(initial state): x0, v0 (, F_e0)
  std::vector<double ActuatorModel::*> parameters;  // columns d/dp, in this order
  bool drive_amplitude = false;                     // then a column d/dV [per V]
  bool drive_frequency = false;                     // then a column d/df at fixed t [per Hz]
  int harmonics = 0;                                // N: int x e^{-jhwt} dt for h = 1..N
  bool harmonic_sensitivities = false;              // and the same of every column's x
  bool figures = false;                             // extrema of x, peak force
  // Samples of the state and the force m_p x'' at t = sample_start_s + k sample_interval_s, k = 0 ..
  // sample_count - 1, all within [t0, t1], from the dense output (7th order): a record's sample grid.
  int sample_count = 0;
  double sample_start_s = 0.0, sample_interval_s = 0.0;
  bool sample_sensitivities = false;  // and every column's x, v and force there (an output-error fit's Jacobian)
};

struct FlowOptions {
  double relative_tolerance = 1e-11;  // on the state: the map's residual is driven to 1e-11 (steady_state.h)
  // On the sensitivity columns (their absolute tolerances scale alike): Newton and the fits' Jacobians
  // need far fewer digits than the residual.
  double sensitivity_relative_tolerance = 1e-10;
  double absolute_tolerance_m = 1e-16;
  double absolute_tolerance_m_per_s = 1e-13;
  double absolute_tolerance_n = 1e-14;  // on the coil's force F_e (models with the coil's pole)
  double initial_step_s = 0.0;   // 0: a fraction of the shortest period (drive, suspension)
  long max_steps = 2'000'000;    // work budget per flow: NumericalError when spent
  // A sampled drive: the intervals where the mass is clear of every stop and the model is linear
  // there are stepped by their exact map (free_flight_map.h) instead of DOP853; false: DOP853
  // throughout (the tests' reference for that map).
  bool exact_free_flight = true;
  std::optional<FieldError> IsValid() const;
};

struct FlowResult {
  State end;
  State end_rate;              // d end / dt at t1 (x', x'') in the mode there
  // d end / d(initial state) when requested (ActuatorModel::StateSize columns), then d end / d p per
  // parameter, then d/dV, then d/df.
  std::vector<State> columns;
  // [h - 1]: int_t0^t1 x e^{-jhwt} dt [m s]; [c][h - 1] the same of column c's x.
  std::vector<std::complex<double>> harmonic_integrals;
  std::vector<std::vector<std::complex<double>>> harmonic_sensitivities;
  double min_displacement_m = 0.0, max_displacement_m = 0.0;
  double peak_force_n = 0.0;  // max |f| at extrema of x, switches and step ends
  int contacts = 0;           // stop entries after t0
  std::vector<State> samples;           // FlowRequest's sample instants
  std::vector<double> sample_force_n;   // m_p x'' there
  // With sample_sensitivities: [(n * columns + c) * 3 + {0, 1, 2}] = d x, d v, d(m_p x'') at sample n
  // per unit of column c (the columns' order above).
  std::vector<double> sample_slopes;
  long steps = 0, rejected_steps = 0;
  long exact_steps = 0;       // of `steps`, those taken by the exact free-flight map
  double last_step_s = 0.0;   // a good initial step for the next flow of the same orbit
};

// Flows `model` driven by `drive` from `start` at t0_s to t1_s. Throws InputError on a bad model,
// drive or options, NumericalError when the solution is not finite or the step budget is spent.
FlowResult Flow(const ActuatorModel& model, const SineDrive& drive, State start, double t0_s, double t1_s,
                const FlowRequest& request, const FlowOptions& options = {});
// The same driven by a record's sampled voltage (a broadband record): steps end at every sample. A
// sampled drive has no frequency, so `request` may ask for no harmonics and no drive columns.
FlowResult Flow(const ActuatorModel& model, const SampledDrive& drive, State start, double t0_s, double t1_s,
                const FlowRequest& request, const FlowOptions& options = {});

}  // namespace strokelab
