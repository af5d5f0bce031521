// The vector field of variational_flow.h: the equation of motion (dynamics.h) with its variational
// equations and quadratures packed into one flat vector, and the switching surfaces with the
// derivatives that the jump of the sensitivities at a switch needs.
//
// Layout of the packed vector y (n components), with d = ActuatorModel::StateSize() (2: x, v; 3: and F_e):
//   y[0 .. d-1]                  the state: x [m], v [m/s] (, F_e [N])
//   y[d + dc .. d + dc + d-1]    column c of the sensitivities: d(state)/d(initial state) first (d
//                                columns) when the monodromy is asked for, then d(state)/d(parameter)
//   quadrature(k)                Re, Im of int x e^{-j(k+1)wt} dt, k = 0 .. N-1
//   quadrature_sensitivity(c, k) Re, Im of int (column c's x) e^{-j(k+1)wt} dt
// The state and the columns take part in the error control.
#pragma once

#include <string>
#include <vector>

#include "strokelab/engines/variational_flow.h"
#include "strokelab/model/dynamics.h"
#include "strokelab/model/model.h"

namespace strokelab::variational {

// The drive as the flow sees it: the paper's sine, or a record's sampled voltage (dynamics.h).
struct Drive {
  SineDrive sine;                        // when `sampled` is null
  const SampledDrive* sampled = nullptr;  // not owned

  double Voltage(double t_s) const { return sampled ? sampled->Voltage(t_s) : sine.Voltage(t_s); }
  double AngularFrequency() const { return sampled ? 0.0 : sine.AngularFrequency(); }
  double PeakV() const { return sampled ? sampled->PeakV() : sine.amplitude_v; }
  std::string Describe() const;  // "12 Hz, 0.3 V" or "sampled at 51200 Hz"
};

struct Layout {
  int state_size = 2;     // d
  int state_columns = 0;  // d with the monodromy, else 0
  int parameter_columns = 0;
  int amplitude_column = -1, frequency_column = -1;  // -1: not asked for
  int columns = 0;        // state columns + parameters + drive columns
  int harmonics = 0;
  bool harmonic_sensitivities = false;
  int size = 2;

  Layout(const FlowRequest& request, int state_size);
  int Column(int c) const { return state_size * (1 + c); }
  int Quadrature(int k) const { return state_size * (1 + columns) + 2 * k; }
  int QuadratureSensitivity(int c, int k) const { return Quadrature(harmonics) + 2 * (c * harmonics + k); }
};

class Field {
 public:
  Field(const ActuatorModel& model, const Drive& drive, const FlowRequest& request);
  const Layout& layout() const { return layout_; }
  const ActuatorModel& model() const { return model_; }

  // dy/dt at t in `mode`, given cos(wt) and sin(wt) (a step rotates them from its start instead of
  // calling sin and cos at every stage: they were a third of the time). Returns the blocked force [N].
  // `quadratures` false leaves the harmonic integrals' derivatives unwritten (a stage whose derivative
  // the integrator never weights: dop853::kStageIsWeighted).
  double Evaluate(double t_s, double cos_wt, double sin_wt, const double* y, double* dy, ContactMode mode,
                  bool quadratures) const;
  double Evaluate(double t_s, const double* y, double* dy, ContactMode mode) const;
  double omega_rad_per_s() const { return omega_rad_per_s_; }
  double Force(double t_s, const double* y, ContactMode mode) const;

 private:
  // Evaluate for a model with (kCoilPole) or without the coil's third state: the two-state field,
  // which every sweep runs, keeps no test for the third component in its inner loops.
  template <bool kCoilPole>
  double EvaluateWith(double t_s, double cos_wt, double sin_wt, const double* y, double* dy, ContactMode mode,
                      bool quadratures) const;

  ActuatorModel model_;
  Drive drive_;
  std::vector<double ActuatorModel::*> parameters_;
  Layout layout_;
  double inverse_mass_per_kg_;
  double omega_rad_per_s_, cos_phase_, sin_phase_;
};

// (cos theta, sin theta) for |theta| <= 0.5 by their Taylor series to theta^17 (error < 1e-20).
void SmallAngleCosSin(double theta, double* cos_theta, double* sin_theta);

// The state in y[0 .. d-1].
State StateOf(const double* y, int state_size);

// One switching surface h(x, v) = 0 of one stop: its penetration p, or its stop force before the
// clamp (dynamics.h, StopForceUnclamped).
struct StopSurface {
  bool upper = false;  // which stop
  bool force = false;  // the stop force; else the penetration

  double Value(const ActuatorModel& m, double x_m, double v_m_per_s) const;
  // grad(h) = (dh/dx, dh/dv).
  void Gradient(const ActuatorModel& m, double x_m, double v_m_per_s, double* dh_dx, double* dh_dv) const;
  // dh/dp at a fixed state for a parameter named by its field.
  double ParameterDerivative(const ActuatorModel& m, double ActuatorModel::*parameter, double x_m,
                             double v_m_per_s) const;
};

}  // namespace strokelab::variational
