// The library of candidate effects (diagnose.h) and the refinement problems they make.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "diagnose_internal.h"
#include "strokelab/base/errors.h"

namespace strokelab {

const std::vector<EffectInfo>& EffectLibrary() {
  static const std::vector<EffectInfo> library = {
      {Effect::kCubicStiffness, "cubic_stiffness", {"k3"},
       "odd harmonics (mostly the 3rd) in records clear of the stop, growing with the displacement "
       "amplitude, and a resonance that moves with amplitude (up: hardening, down: softening): a "
       "restoring force k3 x^3 stiffens or softens the suspension as the stroke grows"},
      {Effect::kQuadraticStiffness, "quadratic_stiffness", {"k2"},
       "even harmonics (mostly the 2nd) and a DC shift in records clear of the stop: k2 x^2 pushes the "
       "same way on both half-strokes, so the response is no longer symmetric"},
      {Effect::kHertzianContact, "hertzian_contact", {"k_s"},
       "contact times that shorten as impacts get harder (k_s p^(3/2): the stop stiffens with "
       "penetration, dT ~ v^(-1/5)); a linear stop gives one contact time at every amplitude (paper Eq. 5)"},
      {Effect::kContactDamping, "contact_damping", {"c_s"},
       "mismatch concentrated in the time windows around impacts and in the high harmonics of contacting "
       "records, weaker rebounds (restitution below one) and skewed spikes: c_s p' dissipates while in contact"},
      {Effect::kSecondStop, "second_stop", {"d_upper"},
       "impact spikes of the opposite sign at the largest strokes, and a mismatch only in the records "
       "whose other half-stroke is long: the mass reaches a stop on the other side"},
      {Effect::kDryFriction, "dry_friction", {"friction_n"},
       "extra damping and odd harmonics that are largest, relative to the response, at the smallest "
       "amplitudes: a Coulomb force F_c tanh(x' / v_s) does not grow with the stroke"},
      {Effect::kAmplifierSaturation, "amplifier_saturation", {"amplifier_limit_v"},
       "odd harmonics and a first harmonic that falls short in proportion at the largest drive amplitudes "
       "at every frequency, clear of the stop or not: the drive is clipped before the coil (the voltage "
       "channel, measured before the amplifier, stays sinusoidal)"},
      {Effect::kQuadraticDamping, "quadratic_damping", {"c2"},
       "odd harmonics (mostly the 3rd) and a resonance peak that falls short in proportion as the "
       "velocity grows, clear of the stop or not: a mechanical resistance c2 v|v| damps fast motion "
       "more than slow (Klippel's R(v)); dry friction does the opposite, most at the smallest amplitudes"},
      {Effect::kForceFactor, "force_factor", {"b1", "b2"},
       "a drive force that falls short at the largest strokes (b2 < 0) or differs between the half-strokes "
       "(b1: even harmonics and a DC shift that follow the drive), clear of the stop or not: the coil "
       "leaves its gap's field, Bl(x) = Bl(0) (1 + b1 x + b2 x^2) (Klippel's Bl(x)), in the drive force and in "
       "the back-EMF damping alike"},
      {Effect::kCoilInductance, "coil_inductance", {"tau_e"},
       "a first harmonic whose phase lags the base model's more and more with frequency, in proportion at "
       "every amplitude (a linear effect, no harmonics of its own), and a resonance damped differently below "
       "and above it: the coil's inductance makes its current, and the drive force, lag the voltage through "
       "the pole L / R, and the back-EMF damping lags with it"},
  };
  return library;
}

const EffectInfo& Info(Effect effect) {
  for (const EffectInfo& info : EffectLibrary())
    if (info.effect == effect) return info;
  throw InputError("effect", "unknown effect");
}

Effect ParseEffect(std::string_view id) {
  std::string known;
  for (const EffectInfo& info : EffectLibrary()) {
    if (id == info.id) return info.effect;
    known += (known.empty() ? "" : ", ") + std::string(info.id);
  }
  throw InputError("effect", "unknown effect '" + std::string(id) + "' (known: " + known + ")");
}

namespace internal {
namespace {

constexpr double kBaseRange = 2.0;      // base parameters: theta within a factor 2 of the base fit
// Contact stiffness: a factor 1000 either way of the base fit's, and no stiffer than the records
// resolve (EffectContext). A base fit without the missing effect puts what it misses into the stop:
// on a campaign with a concealed k3 = 1.5e7 N/m^3 its k_s was 30 times the truth, so a factor 30 held
// the extended fit on its bound just above the truth.
constexpr double kContactRange = 1000.0;
// Start values of the effects whose response is flat where they do not act, as fractions of the
// campaign's scale (largest stroke, largest drive): the best of them (by chi-square) starts the fit.
constexpr double kStopStarts[] = {0.95, 0.85, 0.75, 0.65};
constexpr double kClipStarts[] = {0.95, 0.85, 0.75, 0.6};
// The coil's tau_e added to a model without one starts at omega tau_e = 0.1 or 1, omega the highest
// drive frequency's. The stepped diagnosis takes the start whose model fits best, as for the starts
// above; the broadband diagnosis fits a coil from both and keeps the better fit (broadband_diagnose.cc):
// on broadband coil 8435 (tau_e 6.67e-4 s, omega tau_e = 0.84 at 200 Hz) the first start's model
// fitted better at the start, but its fit stalled with c_emf on its bound (chi-square 72,193 over
// 18,377 degrees of freedom after 200 iterations, tau_e 5.8e-4 s), and the second's converged to the
// noise (17,993, tau_e 6.655e-4 s).
constexpr double kCoilStarts[] = {0.1, 1.0};

// The contact stiffness k_s from `start`, within kContactRange and at most `resolved` [N/m] as a
// linear stop's stiffness (a Hertzian one's at the typical penetration p: k_s,H p^(1/2)).
FreeParameter ContactStiffness(std::string unit, double start, double resolved) {
  FreeParameter p = LogParameter("k_s", std::move(unit), &ActuatorModel::contact_stiffness, start, kContactRange);
  p.theta_max = std::max(1.0, std::min(p.theta_max, 1.0 + std::log(resolved / start)));
  return p;
}

// The back-EMF part of c_p, which the force factor scales and the coil's pole delays (model.h): from
// half of c_p, within 0 .. c_p. Not an effect's own parameter (its zero is not the effect's absence).
FreeParameter BackEmfDamping(const ActuatorModel& start) {
  const double c_p = start.damping_n_s_per_m;
  const double c0 = start.back_emf_damping_n_s_per_m > 0 ? start.back_emf_damping_n_s_per_m : 0.5 * c_p;
  return LinearParameter("c_emf", "N s/m", &ActuatorModel::back_emf_damping_n_s_per_m, c0, 0.1 * c_p,
                         -c0 / (0.1 * c_p), (c_p - c0) / (0.1 * c_p));
}

bool Has(std::span<const Effect> effects, Effect e) { return std::find(effects.begin(), effects.end(), e) != effects.end(); }

}  // namespace

int StartVariants(std::span<const Effect> effects, const EffectContext& context) {
  int variants = 1;
  for (Effect e : effects) {
    if (e == Effect::kSecondStop && !std::isfinite(context.upper_impact_onset_m))
      variants = std::max<int>(variants, std::size(kStopStarts));
    if (e == Effect::kAmplifierSaturation) variants = std::max<int>(variants, std::size(kClipStarts));
    if (e == Effect::kCoilInductance) variants = std::max<int>(variants, std::size(kCoilStarts));
  }
  return variants;
}

bool ActsAtTheStop(Effect effect) {
  return effect == Effect::kHertzianContact || effect == Effect::kContactDamping || effect == Effect::kSecondStop;
}

bool Applicable(Effect effect, FitModelKind kind, const EffectContext& context) {
  if (!ActsAtTheStop(effect)) return true;
  return kind == FitModelKind::kPaper && context.contacts && (effect == Effect::kSecondStop || context.stop_identified);
}

ExtendedProblem BuildProblem(const ActuatorModel& start, FitModelKind kind, std::span<const Effect> effects,
                             const EffectContext& context, int variant) {
  ExtendedProblem problem;
  problem.base = start;
  std::vector<FreeParameter>& p = problem.parameters;
  const double k = start.stiffness_n_per_m, d = context.stop_distance_m;
  p.push_back(LogParameter("k_p", "N/m", &ActuatorModel::stiffness_n_per_m, k, kBaseRange));
  p.push_back(LogParameter("c_p", "N s/m", &ActuatorModel::damping_n_s_per_m, start.damping_n_s_per_m, kBaseRange));
  p.push_back(LogParameter("g", "N/V", &ActuatorModel::gain_n_per_v, start.gain_n_per_v, kBaseRange));
  // The stop's parameters where some impacts tell them: a stop the base fit could not identify is held,
  // but k_s (and c_s), which both stops share, are fitted beside a second stop from its impacts (the
  // broadband study's second-stop campaign 8403: held, its fit left 1.6 times the noise).
  const bool stop = kind == FitModelKind::kPaper && (start.HasLowerStop() || start.HasUpperStop()) &&
                    (context.stop_identified || Has(effects, Effect::kSecondStop));
  if (stop) {
    if (start.HasLowerStop() && context.stop_identified)
      p.push_back(LogParameter("d", "m", &ActuatorModel::lower_stop_m, start.lower_stop_m, kBaseRange));
    const bool hertz = Has(effects, Effect::kHertzianContact);
    if (hertz) {
      // Hertzian k_s [N/m^1.5] with the linear stop's force at the typical penetration p:
      // k_s,H p^(3/2) = k_s p.
      problem.base.contact_law = ContactLaw::kHertzian;
      const double hertz_start = start.contact_law == ContactLaw::kHertzian
                                     ? start.contact_stiffness
                                     : start.contact_stiffness / std::sqrt(std::max(context.penetration_m, 1e-9));
      const double resolved = context.max_contact_stiffness_n_per_m / std::sqrt(std::max(context.penetration_m, 1e-9));
      p.push_back(ContactStiffness("N/m^1.5", hertz_start, resolved));
    } else {
      p.push_back(ContactStiffness("N/m", start.contact_stiffness, context.max_contact_stiffness_n_per_m));
    }
    if (start.contact_damping_n_s_per_m > 0 || Has(effects, Effect::kContactDamping)) {
      // Linear in c_s from 2 % of the contact's critical damping 2 sqrt(k_s m_p), down to 0 (no
      // damping is the null a log scale could not reach), up to 3 times critical.
      // (The linear stiffness at the typical penetration p for a Hertzian stop: k_s,H p^(1/2).)
      const double linear_ks = start.contact_law == ContactLaw::kLinear || !Has(effects, Effect::kHertzianContact)
                                   ? start.contact_stiffness
                                   : start.contact_stiffness * std::sqrt(context.penetration_m);
      const double critical = 2.0 * std::sqrt(linear_ks) * std::sqrt(start.mass_kg);
      const double c0 = start.contact_damping_n_s_per_m > 0 ? start.contact_damping_n_s_per_m : 0.02 * critical;
      const double scale = 0.1 * critical;
      FreeParameter cs = LinearParameter("c_s", "N s/m", &ActuatorModel::contact_damping_n_s_per_m, c0, scale,
                                         -c0 / scale, (3.0 * critical - c0) / scale);
      p.push_back(cs);
    }
  }
  for (Effect e : effects) {
    switch (e) {
      case Effect::kCubicStiffness:
        // Scale: a tenth of the k3 whose force at |d| equals the suspension's, k3 d^3 = k_p d.
        p.push_back(LinearParameter("k3", "N/m^3", &ActuatorModel::cubic_stiffness_n_per_m3,
                                    start.cubic_stiffness_n_per_m3, 0.1 * k / (d * d), -10.0, 10.0));
        break;
      case Effect::kQuadraticStiffness:
        // Scale: a tenth of the k2 whose force at |d| equals the suspension's.
        p.push_back(LinearParameter("k2", "N/m^2", &ActuatorModel::quadratic_stiffness_n_per_m2,
                                    start.quadratic_stiffness_n_per_m2, 0.1 * k / d, -10.0, 10.0));
        break;
      case Effect::kDryFriction: {
        // Scale: 10 % of the smallest drive force; F_c >= 0.
        const double scale = 0.1 * std::abs(start.gain_n_per_v) * context.min_amplitude_v;
        const double f0 = start.friction_force_n;
        p.push_back(LinearParameter("friction_n", "N", &ActuatorModel::friction_force_n, f0, scale, -f0 / scale, 20.0));
        break;
      }
      case Effect::kQuadraticDamping: {
        // Scale: a tenth of the c2 whose force at the campaign's largest velocity v equals the
        // linear damping's, c2 v^2 = c_p v; c2 >= 0.
        const double scale = 0.1 * start.damping_n_s_per_m / std::max(context.max_velocity_m_per_s, 1e-6);
        const double c0 = start.quadratic_damping_n_s2_per_m2;
        p.push_back(LinearParameter("c2", "N s^2/m^2", &ActuatorModel::quadratic_damping_n_s2_per_m2, c0, scale,
                                    -c0 / scale, 20.0));
        break;
      }
      case Effect::kForceFactor: {
        // Scales: a tenth of the b1 and b2 that change the force factor by 100 % at the largest
        // stroke X (b1 X = 1, b2 X^2 = 1); either sign.
        const double x = std::max(context.max_displacement_m, 0.1 * d);
        p.push_back(LinearParameter("b1", "1/m", &ActuatorModel::force_factor_b1_per_m, start.force_factor_b1_per_m,
                                    0.1 / x, -10.0, 10.0));
        p.push_back(LinearParameter("b2", "1/m^2", &ActuatorModel::force_factor_b2_per_m2, start.force_factor_b2_per_m2,
                                    0.1 / (x * x), -10.0, 10.0));
        p.push_back(BackEmfDamping(start));
        break;
      }
      case Effect::kCoilInductance: {
        // tau_e = L / R from one of kCoilStarts, on the scale of omega tau_e = 0.1 at the highest drive
        // frequency (a lag of 0.1 rad); no longer than the one that lags by 1 rad at the lowest, and no
        // shorter than the one that lags by 0.01 rad at the highest (its pole 100 times above the
        // drive frequencies) nor than the model's bound (model.h). Below that floor the explicit
        // flow's steps follow tau_e and a fit costs ~100 s on 24 records where the others take 1 s (a
        // housing mode's campaign, open_world_test, ran tau_e to the model's bound, 1.7e-5 s, in
        // 104 s; 32 s at this floor, 1.4e-4 s). A coil with a shorter tau_e is not named (gen2 9954,
        // 1.3e-4 s: "unexplained" at 2.1 times the noise). A coil added to a model without one is
        // first looked at on the floor (diagnose.cc, RunCandidate's floor probe).
        const double scale = 0.1 / (2.0 * std::numbers::pi * context.max_frequency_hz);
        const double natural_hz = std::sqrt(k / start.mass_kg) / (2.0 * std::numbers::pi);
        const double floor = std::max(1.01 / (2.0 * std::numbers::pi * ModelBounds::kMaxCoilPoleRatio * natural_hz),
                                      0.1 * scale);
        const double ceiling = 1.0 / (2.0 * std::numbers::pi * context.min_frequency_hz);
        const double from_scale = 10.0 * kCoilStarts[variant % std::size(kCoilStarts)] * scale;
        const double t0 = std::max(start.HasCoilPole() ? start.coil_time_constant_s : from_scale, floor);
        p.push_back(LinearParameter("tau_e", "s", &ActuatorModel::coil_time_constant_s, t0, scale, (floor - t0) / scale,
                                    (std::max(ceiling, t0) - t0) / scale));
        // The back-EMF's part of c_p, c_emf, only where the model's stop meets the records' impacts.
        // Without them the response is linear, and the coil's transfer function has four coefficients (m_p
        // known) for g, k_p, c_p, tau_e and c_emf: one direction of the five is not identifiable (tuning
        // campaign 8302, a coil clear of the stop but for a few impacts the base model missed: every
        // standard error undefined). c_emf is then held at the start's (0 for a model without the coil:
        // the coil delays the drive only), and ChargeHeldBackEmf adds its spread to the errors it moves.
        if (!Has(effects, Effect::kForceFactor) && context.contacts && context.stop_identified)
          p.push_back(BackEmfDamping(start));
        break;
      }
      case Effect::kSecondStop: {
        // Where the records show impacts on that side, else each start of kStopStarts within the motion.
        const double u0 = start.HasUpperStop()                         ? start.upper_stop_m
                          : std::isfinite(context.upper_impact_onset_m) ? context.upper_impact_onset_m
                              : kStopStarts[variant % std::size(kStopStarts)] * context.max_displacement_m;
        p.push_back(LogParameter("d_upper", "m", &ActuatorModel::upper_stop_m, u0, kBaseRange));
        break;
      }
      case Effect::kAmplifierSaturation: {
        const double v0 = start.HasAmplifierLimit() ? start.amplifier_limit_v
                                                    : kClipStarts[variant % std::size(kClipStarts)] * context.max_amplitude_v;
        p.push_back(LogParameter("amplifier_limit_v", "V", &ActuatorModel::amplifier_limit_v, v0, kBaseRange));
        break;
      }
      case Effect::kHertzianContact:
      case Effect::kContactDamping:
        break;  // above, with the stop's parameters
    }
  }
  return problem;
}

ActuatorModel WithoutEffect(const ActuatorModel& model, Effect effect, const ActuatorModel& base) {
  ActuatorModel out = model;
  switch (effect) {
    case Effect::kCubicStiffness: out.cubic_stiffness_n_per_m3 = base.cubic_stiffness_n_per_m3; break;
    case Effect::kQuadraticStiffness: out.quadratic_stiffness_n_per_m2 = base.quadratic_stiffness_n_per_m2; break;
    case Effect::kHertzianContact:
      out.contact_law = base.contact_law;
      out.contact_stiffness = base.contact_stiffness;
      break;
    case Effect::kContactDamping: out.contact_damping_n_s_per_m = base.contact_damping_n_s_per_m; break;
    case Effect::kSecondStop: out.upper_stop_m = base.upper_stop_m; break;
    case Effect::kDryFriction: out.friction_force_n = base.friction_force_n; break;
    case Effect::kAmplifierSaturation: out.amplifier_limit_v = base.amplifier_limit_v; break;
    case Effect::kQuadraticDamping: out.quadratic_damping_n_s2_per_m2 = base.quadratic_damping_n_s2_per_m2; break;
    case Effect::kForceFactor:
      out.force_factor_b1_per_m = base.force_factor_b1_per_m;
      out.force_factor_b2_per_m2 = base.force_factor_b2_per_m2;
      break;
    case Effect::kCoilInductance: out.coil_time_constant_s = base.coil_time_constant_s; break;
  }
  return out;
}

void ChargeHeldBackEmf(std::span<const Effect> effects, const ExtendedProblem& problem, const ActuatorModel& fitted,
                       std::vector<FitParameter>* parameters, std::vector<double>* covariance) {
  if (!Has(effects, Effect::kCoilInductance)) return;
  if (std::ranges::any_of(problem.parameters, [](const FreeParameter& p) { return p.name == "c_emf"; })) return;
  // Without impacts the coil model's transfer function g m s^2 / (m tau s^3 + (m + (c_p - c_emf) tau) s^2 +
  // (c_p + k_p tau) s + k_p) (m_p known) fixes four ratios of five parameters. Along the family that keeps
  // them (differentiate a0/a3 = k/(m tau), a1/a3 = c/(m tau) + k/m, a2/a3 = 1/tau + (c - e)/m, b/a3 = g/tau):
  //   dtau/tau = dk/k = dg/g = tau de / (c tau - k tau^2 - m),  dc/c = (1 - k tau / c) dtau/tau,
  // about -tau de / m each; the other mechanical force terms scale as k_p does (to first order in tau the
  // equation of motion is (m - tau e) x'' + c x' + ... = g (u - tau u'), known only up to m - tau e). Over
  // c_emf uniform in its physical range [0, c_p], held at e0, the mean square of e - e0 is
  // c_p^2 / 3 - c_p e0 + e0^2; that spread joins the covariance as the rank-one term it makes.
  const double tau = fitted.coil_time_constant_s, m = fitted.mass_kg, c = fitted.damping_n_s_per_m;
  const double k = fitted.stiffness_n_per_m, e0 = problem.base.back_emf_damping_n_s_per_m;
  if (!(c > 0.0) || !(tau > 0.0)) return;
  const double per_e = tau / (c * tau - k * tau * tau - m);  // relative move per N s/m of c_emf
  const double spread = c * c / 3.0 - c * e0 + e0 * e0;      // mean square of c_emf - e0 [(N s/m)^2]
  const size_t n = parameters->size();
  std::vector<double> move(n, 0.0);  // each parameter's move per N s/m of c_emf, in its unit
  for (size_t i = 0; i < n; ++i) {
    const std::string& name = (*parameters)[i].name;
    const double value = (*parameters)[i].value;
    if ((*parameters)[i].fixed) continue;
    if (name == "tau_e" || name == "k_p" || name == "g" || name == "k2" || name == "k3" || name == "c2" ||
        name == "friction_n")
      move[i] = value * per_e;
    else if (name == "c_p")
      move[i] = value * (1.0 - k * tau / c) * per_e;
  }
  const bool has_covariance = covariance->size() == n * n;
  for (size_t i = 0; i < n; ++i) {
    FitParameter& p = (*parameters)[i];
    if (move[i] == 0.0) continue;
    p.standard_error = std::sqrt(p.standard_error * p.standard_error + move[i] * move[i] * spread);
    if (has_covariance)
      for (size_t j = 0; j < n; ++j) (*covariance)[i * n + j] += move[i] * move[j] * spread;
    const std::string held =
        p.name == "tau_e"
            ? "with c_emf held at " + FormatFigure(e0, 4) +
                  " N s/m (no impacts at an identified stop: the records cannot separate it from g, k_p, c_p and "
                  "tau_e); its error includes c_emf's spread over [0, c_p], which moves tau_e, k_p, c_p and g "
                  "together, by " + FormatFigure(100.0 * per_e * (c - e0), 2) + " % at c_emf = c_p"
            : "its error includes c_emf's spread over [0, c_p] (c_emf held: see tau_e)";
    p.note = p.note.empty() ? held : p.note + "; " + held;
  }
}

std::vector<FitParameter> EffectParameters(std::span<const Effect> effects, const std::vector<FitParameter>& all) {
  std::vector<FitParameter> out;
  for (Effect e : effects)
    for (const char* key : Info(e).parameters)
      for (const FitParameter& p : all)
        if (p.name == key) out.push_back(p);
  return out;
}

}  // namespace internal
}  // namespace strokelab
