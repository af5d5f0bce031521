// The exact map of the variational flow (variational_flow.h) over one interval of a sampled drive
// where the mass touches no stop, the amplifier does not clip or clips throughout, and the model is
// linear there: the paper's model and every model whose terms outside the stops are affine in the state
// (coil pole, contact law and contact damping act only inside a stop). The packed vector Y
// (variational_field.h: the state and its sensitivity columns) then obeys
//
//   Y' = M Y + N u(t) + c + s b,   u(t) = u_k + (u_k+1 - u_k) (t - t_k) / h   (the drive's first-order hold),
//
// where s = 0 while the drive stays within the amplifier's limit L. Where it stays beyond it (s = +-1,
// both ends of the interval on the same side, so the hold's straight line too), the amplifier gives the
// constant s L in place of u, and the limit's column is forced by d(field)/dL = s b (the drive's own
// entry of the state's rows, s g / m_p or s g / tau_e through the coil). With the augmented state
// z = (Y, u, du, 1, s), z' = A z (u' = du / h, du' = 0, 1' = 0, s' = 0),
//
//   Y(t_k + h) = E_YY Y(t_k) + E_Yu u_k + E_Ydu (u_k+1 - u_k) + E_Y1 + s E_Ys,   E = exp(A h)
//
// (C. F. Van Loan, "Computing integrals involving the matrix exponential", IEEE Trans. Automatic
// Control 23(3), 395-404, 1978; the first-order-hold discretisation of G. F. Franklin, J. D. Powell
// and M. Workman, "Digital Control of Dynamic Systems", 3rd ed., Addison-Wesley 1998, Sec. 6.3.2).
// E is computed once per flow (Eigen's Pade approximant with scaling and squaring, accurate relative
// to the norm of A h: A is balanced first, each component in units of its size, else the columns'
// large entries (d/dm_p's k_p / m_p^2) leave errors of 1e-13 relative in the drive's small input
// entries, which add up over a record's steps); a step is then one matrix-vector product, where the
// DOP853 step it replaces evaluates the field 12 times (the interval of a 51.2 kHz record is 1e-3 of
// the suspension's period, so DOP853 takes one step per sample). M, N and c are read off the field itself (n + 2
// evaluations, and b one more of the clipped model), so the map and the integrator cannot disagree on
// the equations.
#pragma once

#include <vector>

#include "strokelab/engines/variational_flow.h"
#include "strokelab/model/model.h"
#include "variational_field.h"

namespace strokelab::variational {

class FreeFlightMap {
 public:
  // Whether the field is affine in Y and u outside the stops, while the amplifier does not clip, for
  // `model` with `request`'s columns: no smooth nonlinear term, and every parameter column's forcing
  // affine (a column d/dk3 is forced by -x^3 / m_p even at k3 = 0). Clipping is not affine in u: the
  // map serves only intervals that Covers.
  static bool Applies(const ActuatorModel& model, const FlowRequest& request);
  // Whether the drive's hold from u_k to u_k+1 [V] stays within the amplifier's limit, or beyond it on
  // one side, throughout (both ends do); an interval that crosses the limit is not one the map serves.
  bool Covers(double u_start_v, double u_end_v) const;

  // The map over `interval_s` for `model` and `request`'s columns (Applies must hold). `scale` holds
  // each component's size (in proportion to the flow's absolute tolerances), `voltage_scale_v` the drive's.
  FreeFlightMap(const ActuatorModel& model, const FlowRequest& request, double interval_s,
                const std::vector<double>& scale, double voltage_scale_v);

  // y_next = Y(t_k + h) from y = Y(t_k), the drive's u_k and u_k+1 [V] (Covers must hold); the first
  // n components.
  void Advance(const double* y, double u_start_v, double u_end_v, double* y_next) const;

 private:
  // Where u [V] lies: 1 beyond +L, -1 beyond -L, 0 within the limit (L itself included).
  int Side(double u_v) const;

  int n_;
  double limit_v_;                  // the amplifier's limit L [V] (+inf: none)
  std::vector<double> transition_;  // E_YY, row-major n x n
  std::vector<double> from_voltage_, from_voltage_change_, constant_;  // E_Yu, E_Ydu, E_Y1 (n each)
  std::vector<double> from_clipping_;                                   // E_Ys (n)
};

}  // namespace strokelab::variational
