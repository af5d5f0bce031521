// Periodic steady states by shooting on the period map, guarded against the traps of the paper's
// model: plain period iterations before Newton, a fall-back when Newton stalls, a linear start
// clipped into the stops' range, and the Floquet multipliers checked (period 2 past grazing).
//
// The period map P takes the state at t = 0 (drive phase 0) to the state one drive period later.
// For piecewise-linear models it is evaluated on the closed form (pwl_system.h) together with its
// Jacobian, the monodromy matrix
//
//   M = Phi_n S_n ... Phi_2 S_1 Phi_1,   S = I + (f+ - f-) grad(h)^T / (grad(h) . f- + dh/dt),
//
// Phi_i = exp(A_i tau_i) the transition through region i and S the saltation matrix at each switch
// (Mueller, "Calculation of Lyapunov exponents for dynamic systems with discontinuities", Chaos,
// Solitons & Fractals 5(9), 1995; Leine & Nijmeijer, "Dynamics and Bifurcations of Non-smooth
// Mechanical Systems", Springer 2004, ch. 7). Its eigenvalues are the Floquet multipliers. Other
// models use the variational flow (engines/variational_flow.h): the same monodromy, from the
// variational equations integrated with the state and the same saltation matrices at located switches.
//
// Harmonics of an orbit are exact: x(t) is a sum of complex exponentials in each region, so
// C_1(x) = (2 / T) int x e^{-jwt} dt is integrated in closed form (by the flow's quadratures for other
// models), and the blocked force has C_1(f) = -m_p w^2 C_1(x) (f = m_p x'' and x, x' are continuous
// and periodic).
#pragma once

#include <complex>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "strokelab/engines/engine.h"
#include "strokelab/model/model.h"

namespace strokelab {

// A square matrix on the state, ActuatorModel::StateSize() rows (x, v and, with the coil's pole,
// F_e): the monodromy. At most 3 x 3, so it lives on the stack.
using StateMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor, 3, 3>;
// Its eigenvalues: the Floquet multipliers of a monodromy (2 x 2 in closed form).
std::vector<std::complex<double>> Eigenvalues(const StateMatrix& m);
// The monodromy from a flow's first `size` sensitivity columns (d end / d(component c of y0)).
StateMatrix MonodromyFromColumns(const std::vector<State>& columns, int size);
// Solves (M - I) step = rhs for the state's components; nullopt where M - I is singular (Newton on
// P(y) - y; 2 x 2 by Cramer's rule).
std::optional<State> SolveShiftedByIdentity(const StateMatrix& m, const State& rhs);

// A drive parameter the map depends on (the continuation's parameter).
enum class DriveParameter { kFrequencyHz, kAmplitudeV };

// What one pass of the map over `periods` drive periods saw.
struct OrbitFigures {
  State end;                          // P^periods(y0)
  StateMatrix monodromy;              // d end / d y0
  State d_end_d_drive;                // d end / d(drive parameter) when asked for [per Hz or per V]
  std::complex<double> x1;            // C_1 of x over the pass [m], phase relative to the drive (t = 0)
  double min_displacement_m = 0.0;
  double max_displacement_m = 0.0;
  double peak_force_n = 0.0;          // max |f| at the extrema of x and at switches (approximate)
  int contacts = 0;                   // stop entries during the pass
};

class PeriodMap {
 public:
  // Throws InputError on a bad model or drive.
  PeriodMap(const ActuatorModel& model, double frequency_hz, double amplitude_v);
  ~PeriodMap();
  PeriodMap(PeriodMap&&) noexcept;

  const ActuatorModel& model() const;
  double frequency_hz() const { return frequency_hz_; }
  double amplitude_v() const { return amplitude_v_; }
  double period_s() const { return 1.0 / frequency_hz_; }

  // One drive period from y at phase 0.
  State Apply(State y) const;
  // `periods` drive periods, with the Jacobian and the orbit's figures; with `drive`, also
  // d end / d(drive parameter), the end of the pass moving with the frequency (exact from the
  // variational flow, a forward difference of relative step 1e-7 on the closed form).
  OrbitFigures Trace(State y, int periods = 1, std::optional<DriveParameter> drive = std::nullopt) const;
  // The same with only `end`, `monodromy`, `d_end_d_drive` and `contacts` filled in (the displacement
  // extrema and the first harmonic are about half a closed-form trace): for Newton steps whose
  // figures are not kept.
  OrbitFigures Linearize(State y, int periods = 1, std::optional<DriveParameter> drive = std::nullopt) const;
  // The state of the linear (no-contact) steady state at phase 0, clipped into the stops' range:
  // the shooting start (a start inside the stop does not converge).
  State ClippedLinearStart() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  double frequency_hz_, amplitude_v_;
};

struct ShootingOptions {
  int plain_iterations = 3;          // period iterations before Newton (it can cycle)
  int max_newton_iterations = 30;
  double tolerance = 1e-11;          // on the scaled residual |P^k(y) - y| (x / L, v / (w L)), L = length scale
  int settle_periods = 400;          // plain iterations when Newton fails, to reach an attractor (at most)
  int max_period = 16;               // longest period searched for
  std::optional<FieldError> IsValid() const;
};

struct SteadyState {
  State start;                        // on the orbit at phase 0
  int period = 1;                     // drive periods; 0: aperiodic (no period up to max_period)
  std::vector<std::complex<double>> multipliers;  // of P^period, one per state component
  bool stable = false;
  OrbitFigures figures;               // over `period` periods (or max_period for aperiodic)
  int newton_iterations = 0;
  double MaxMultiplier() const;
  // First-order FRF C_1(f) / C_1(v_in) [N/V], averaged over the orbit's periods.
  std::complex<double> Frf(const PeriodMap& map) const;
  double ContactsPerPeriod() const;
};

// Newton on P^period(y) - y from `guess`; nullopt if it does not converge. Multipliers and figures
// of the orbit found; `stable` from the multipliers.
std::optional<SteadyState> Shoot(const PeriodMap& map, State guess, int period = 1, const ShootingOptions& options = {});

// The attractor reached from `guess`: plain iterations, Newton on period 1, and when the period-1
// orbit is unstable or Newton fails, period 2, 4, ... or long plain iteration and a period search;
// `aperiodic` (period 0) when none is found. Never reports an unstable orbit as the response.
SteadyState SolveAttractor(const PeriodMap& map, State guess, const ShootingOptions& options = {});

// The attractor whose basin holds `guess`, as a test rig or a time simulation reaches it: settle_periods
// plain periods first (fewer once the motion repeats with period 1 or 2), then the period of the
// settled motion and Newton on that period. SolveAttractor tries Newton on period 1 early and can land
// on a coexisting stable period-1 orbit instead (e.g. just past grazing a second stop, where a period-2
// orbit and a two-contact period-1 orbit coexist); nullopt when the settled motion has no stable
// period up to max_period.
std::optional<SteadyState> SettledAttractor(const PeriodMap& map, State guess, const ShootingOptions& options = {});

// Harmonics C_h, h = 1..orders, of x over `period` drive periods from `start` (on the orbit at phase 0):
// x(t) ~ c_0 + sum_h Re(C_h e^{jhwt}), C_h = (2 / pT) int_0^{pT} x e^{-jhwt} dt [m], phases relative to
// the drive. Closed form for piecewise-linear models (as OrbitFigures::x1, which equals C_1), the
// variational flow's quadratures otherwise. The blocked force has C_h(f) = -m_p (hw)^2 C_h(x)
// over a periodic orbit (x and x' are continuous). Throws InputError if period < 1 or orders < 1.
std::vector<std::complex<double>> OrbitHarmonics(const PeriodMap& map, State start, int period, int orders);

}  // namespace strokelab
