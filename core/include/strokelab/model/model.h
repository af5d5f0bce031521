// The actuator model: a proof mass on a suspension, driven by a coil, stopped by end stops.
//
// Paper Eq. 2 in its continuous form, i.e. with its slip at contact corrected (as printed, Eq. 2
// makes the suspension force jump by k_p*d at contact; here the suspension keeps acting, k_p x, and
// the stop adds k_s (x - d)), extended by composable force terms:
//
//   m_p x'' = g u(t) - [k_p x + k2 x^2 + k3 x^3 + c_p x'] - F_friction(x') + F_stops(x, x')
//
//   u(t)        drive voltage, clipped to +-amplifier_limit_v (the amplifier's limit)
//   F_stops     each stop pushes with k_s p^n + c_s p' when the penetration p > 0, clamped at zero so
//               that the stop only pushes (n = 1 linear, paper Eq. 2; n = 3/2 Hertzian)
//   F_friction  F_c tanh(x' / v_s): dry friction, smoothed
//
// Output is the blocked force f = m_p x'' (the sign of paper Eq. 3 and of H_p = -H / (m_p w^2) in
// its section 3.2), the displacement x (positive away from the lower stop) and the velocity x'.
//
// Reference: "Nonlinear vibrations of a stroke-saturated inertial actuator", Eq. 2 and
// Table 2 for the `paper` preset.
#pragma once

#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "strokelab/base/errors.h"

namespace strokelab {

enum class ContactLaw {
  kLinear,     // F = k_s p          [k_s in N/m]      paper Eq. 2
  kHertzian,   // F = k_s p^(3/2)    [k_s in N/m^1.5]  Hertz contact of curved bodies
};

struct ActuatorModel {
  double mass_kg = 0.032;                       // m_p [kg]
  double damping_n_s_per_m = 1.3;               // c_p [N s/m], includes back-EMF
  double stiffness_n_per_m = 124.0;             // k_p [N/m]
  double quadratic_stiffness_n_per_m2 = 0.0;    // k2 [N/m^2], asymmetric suspension
  double cubic_stiffness_n_per_m3 = 0.0;        // k3 [N/m^3], > 0 hardening, < 0 softening
  double gain_n_per_v = 0.3;                    // g [N/V], amplifier x coil
  // The coil's force factor over the stroke, Bl(x) = Bl(0) phi(x), phi = 1 + b1 x + b2 x^2: b1 [1/m]
  // an offset of the coil in its gap, b2 [1/m^2] < 0 a symmetric fall-off (Klippel's Bl(x), 2006, to
  // second order). Under voltage drive the coil's force is Bl i with i = (u - Bl v) / R: the drive
  // force g u and the back-EMF damping c_emf v (c_emf = Bl(0)^2 / R, the part of c_p that is the
  // coil's) both follow it, g phi u - c_emf phi^2 v (dynamics.cc).
  double force_factor_b1_per_m = 0.0;
  double force_factor_b2_per_m2 = 0.0;
  double back_emf_damping_n_s_per_m = 0.0;  // c_emf [N s/m] >= 0, physically at most c_p; acts only with phi != 1
                                            // or with the coil's pole
  // The coil's electrical pole, tau_e = L / R [s] (0: ignored, the current follows the voltage at
  // once). Then the coil's force at phi = 1 is a third state F_e, relaxing to what it is without the pole,
  //   tau_e F_e' = g u - c_emf phi v - F_e,   coil force phi F_e,
  // and c_p v keeps only the mechanical part: (c_p - c_emf) v (the lumped voice-coil model, e.g.
  // Klippel, J. Audio Eng. Soc. 54(10), 2006, Fig. 1, with the current as F_e = Bl(0) i).
  double coil_time_constant_s = 0.0;
  double lower_stop_m = -1e-3;                  // d [m]; -inf: no lower stop
  double upper_stop_m = kNoUpperStop;           // [m]; +inf: no upper stop
  double contact_stiffness = 1.3e6;             // k_s [N/m] (linear) or [N/m^1.5] (Hertzian)
  double contact_damping_n_s_per_m = 0.0;       // c_s [N s/m]
  ContactLaw contact_law = ContactLaw::kLinear;
  double friction_force_n = 0.0;                // F_c [N], Coulomb level
  double friction_velocity_m_per_s = 1e-3;      // v_s [m/s], tanh smoothing width
  double quadratic_damping_n_s2_per_m2 = 0.0;   // c2 [N s^2/m^2], force c2 v|v|: a mechanical resistance
                                                // growing with velocity, the R_ms(v) of W. Klippel, "Tutorial:
                                                // Loudspeaker nonlinearities - causes, parameters, symptoms",
                                                // J. Audio Eng. Soc. 54(10), 907-939 (2006), to first order
  double amplifier_limit_v = kNoLimit;          // [V] on the drive before the gain; +inf: none

  static constexpr double kNoLimit = std::numeric_limits<double>::infinity();
  static constexpr double kNoUpperStop = std::numeric_limits<double>::infinity();
  static constexpr double kNoLowerStop = -std::numeric_limits<double>::infinity();

  bool HasLowerStop() const { return lower_stop_m > kNoLowerStop; }
  bool HasUpperStop() const { return upper_stop_m < kNoUpperStop; }
  bool HasAmplifierLimit() const { return amplifier_limit_v < kNoLimit; }
  bool HasCoilPole() const { return coil_time_constant_s > 0; }
  // Components of the state (dynamics.h): x and v, and the coil's force F_e with the coil's pole.
  int StateSize() const { return HasCoilPole() ? 3 : 2; }

  // True when every region between switching surfaces is a linear ODE with sinusoidal or constant
  // forcing, which is what the closed-form engine needs.
  bool IsPiecewiseLinear() const;
  // Why the model is not piecewise linear (empty when it is).
  std::string NonlinearTerms() const;
  // Physical sense: nothing, or the first offending field by its key (m_p, d, k_s, ...).
  std::optional<FieldError> IsValid() const;
};

// Physical bounds beyond the signs, checked by ActuatorModel::IsValid (issue 15: a model of k_s = 1e40
// N/m or m_p = 1e-300 kg is accepted by the signs alone and then runs any engine for ever, its contacts
// lasting less than the resolution of a double in time). Each bound sits orders of magnitude beyond the
// real actuators this tool serves (the paper's 32 g and k_s/k_p ~ 1e4, the diagnosis's extended models:
// cubic/quadratic stiffness, Hertzian contact up to k_s ~ 1e12 N/m^1.5, contact stiffnesses of 4e10 N/m,
// friction, clipping) and far inside where the engines stop meaning anything:
//   coil pole      1 / (2pi tau_e) at most 1e3 times the suspension's natural frequency: real voice coils
//                  (L 0.05-10 mH over R 2-8 Ohm) put it 10-1000 times above a proof-mass actuator's 10-50 Hz.
//                  The pole acts all the time (a stop only during contacts), and the variational flow is
//                  explicit: its steps follow tau_e (~0.5 tau_e, where the error estimate of the pole's
//                  fast relaxation binds), ~1e4 per suspension period at this bound.
//   mass           a 1 mg MEMS proof mass to a 1 t building shaker.
//   stiffness      a stop (or k2 |d|, k3 d^2) 1e9 times the suspension's: the stop's time scale is then
//   ratios         3e4 times shorter than the suspension's, already far past any rigid stop; beyond it
//                  the contact regions' exponentials and the shooting Jacobians lose all their digits.
//   natural        sqrt(k / m_p) / 2pi of the suspension and of a stop at most 1 MHz: a contact lasts
//   frequencies    at least 0.5 us, so a second of motion holds at most a few million contacts and the
//                  engines' work budgets (strokelab/engines/work_budget.h) suffice for every real model.
//   damping        c / (2 sqrt(k m_p)) at most 1e3: a thousand times critical already makes the
//   ratios         region's eigenvalues 4e6 apart; beyond it the suspension or stop is a pure damper.
// A Hertzian stop (k_s p^1.5) counts as its secant stiffness at the model's length scale, k_s |d|^(1/2),
// which overstates the stiffness at the micrometre penetrations of real contacts (a conservative test).
struct ModelBounds {
  static constexpr double kMinMassKg = 1e-6;
  static constexpr double kMaxMassKg = 1e3;
  static constexpr double kMaxStiffnessRatio = 1e9;
  static constexpr double kMaxNaturalFrequencyHz = 1e6;
  static constexpr double kMaxDampingRatio = 1e3;
  static constexpr double kMaxCoilPoleRatio = 1e3;
};

// A stop's stiffness as a linear one [N/m]: k_s, or a Hertzian k_s's secant k_s L^(1/2) at the length
// scale L = LengthScaleM(model).
double EffectiveContactStiffnessNPerM(const ActuatorModel& model);

// The model's length scale [m], used to scale residuals and tolerances: |d| or the upper stop, else 1 mm.
double LengthScaleM(const ActuatorModel& model);

// Paper Table 2 with the one-sided stop at d = -1 mm.
ActuatorModel PaperModel();

// Named presets: "paper" (Table 2), "linear" (Table 2 without stops).
std::vector<std::string> PresetNames();
ActuatorModel PresetModel(std::string_view name);  // throws InputError on an unknown name

// One scalar model parameter, addressable by a short key (`--set k3=4e7`) and a JSON name.
struct ParameterInfo {
  const char* key;        // short key, as in the paper: m_p, c_p, k_p, k2, k3, g, d, ...
  const char* json_name;  // field name in model JSON files and job specs
  const char* unit;
  const char* description;
  double ActuatorModel::*field;
};
const std::vector<ParameterInfo>& Parameters();
// Finds a parameter by short key or JSON name; throws InputError listing the valid keys.
const ParameterInfo& FindParameter(std::string_view key_or_name);
// Applies "key=value"; throws InputError naming the key or value that is wrong.
void ApplyOverride(ActuatorModel* model, std::string_view assignment);

ContactLaw ParseContactLaw(std::string_view text);  // "linear" | "hertzian"
const char* ToString(ContactLaw law);

}  // namespace strokelab
