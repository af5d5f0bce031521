#include "strokelab/model/model.h"

#include "strokelab/base/parse.h"

#include <charconv>
#include <cmath>
#include <sstream>

namespace strokelab {
namespace {

std::string FormatDouble(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

std::optional<FieldError> Finite(double value, const char* field) {
  if (!std::isfinite(value)) return FieldError{field, "must be a finite number, got " + FormatDouble(value)};
  return std::nullopt;
}

std::optional<FieldError> Positive(double value, const char* field) {
  if (auto error = Finite(value, field)) return error;
  if (value <= 0) return FieldError{field, "must be > 0, got " + FormatDouble(value)};
  return std::nullopt;
}

std::optional<FieldError> NonNegative(double value, const char* field) {
  if (auto error = Finite(value, field)) return error;
  if (value < 0) return FieldError{field, "must be >= 0, got " + FormatDouble(value)};
  return std::nullopt;
}

// Beyond the signs: the bounds of ModelBounds (why each: model.h), each naming its field.
std::optional<FieldError> PhysicalBoundsError(const ActuatorModel& model) {
  const double mass_kg = model.mass_kg;
  if (mass_kg < ModelBounds::kMinMassKg || mass_kg > ModelBounds::kMaxMassKg)
    return FieldError{"m_p", "must lie within [" + FormatDouble(ModelBounds::kMinMassKg) + ", " +
                                 FormatDouble(ModelBounds::kMaxMassKg) + "] kg, got " + FormatDouble(mass_kg)};
  const double two_pi = 2.0 * 3.14159265358979323846;
  const double k_p = model.stiffness_n_per_m;
  auto frequency_error = [&](double stiffness, const char* field, const char* what) -> std::optional<FieldError> {
    const double frequency_hz = std::sqrt(stiffness / mass_kg) / two_pi;
    if (frequency_hz <= ModelBounds::kMaxNaturalFrequencyHz) return std::nullopt;
    return FieldError{field, std::string("makes the ") + what + " natural frequency sqrt(k / m_p) / 2pi " +
                                 FormatDouble(frequency_hz) + " Hz, above the limit of " +
                                 FormatDouble(ModelBounds::kMaxNaturalFrequencyHz) + " Hz"};
  };
  auto damping_error = [&](double damping, double stiffness, const char* field,
                           const char* what) -> std::optional<FieldError> {
    const double ratio = damping / (2.0 * std::sqrt(stiffness * mass_kg));
    if (damping == 0 || ratio <= ModelBounds::kMaxDampingRatio) return std::nullopt;
    return FieldError{field, std::string("makes the ") + what + " damping ratio c / (2 sqrt(k m_p)) " +
                                 FormatDouble(ratio) + ", above the limit of " +
                                 FormatDouble(ModelBounds::kMaxDampingRatio)};
  };
  auto ratio_error = [&](double stiffness, const char* field, const char* what) -> std::optional<FieldError> {
    const double ratio = std::abs(stiffness) / k_p;
    if (ratio <= ModelBounds::kMaxStiffnessRatio) return std::nullopt;
    return FieldError{field, std::string("makes ") + what + " " + FormatDouble(ratio) +
                                 " times the suspension stiffness k_p, above the limit of " +
                                 FormatDouble(ModelBounds::kMaxStiffnessRatio)};
  };
  if (auto error = frequency_error(k_p, "k_p", "suspension's")) return error;
  if (model.HasCoilPole()) {
    const double pole_hz = 1.0 / (two_pi * model.coil_time_constant_s);
    const double limit_hz = ModelBounds::kMaxCoilPoleRatio * std::sqrt(k_p / mass_kg) / two_pi;
    if (pole_hz > limit_hz)
      return FieldError{"tau_e", "puts the coil's pole 1 / (2pi tau_e) at " + FormatDouble(pole_hz) +
                                     " Hz, above the limit of " + FormatDouble(ModelBounds::kMaxCoilPoleRatio) +
                                     " times the suspension's natural frequency (" + FormatDouble(limit_hz) +
                                     " Hz; use 0 to ignore the pole)"};
  }
  if (auto error = damping_error(model.damping_n_s_per_m, k_p, "c_p", "suspension's")) return error;
  const double length_m = LengthScaleM(model);
  if (auto error = ratio_error(model.quadratic_stiffness_n_per_m2 * length_m, "k2", "k2 L (L: the length scale)"))
    return error;
  if (auto error = ratio_error(model.cubic_stiffness_n_per_m3 * length_m * length_m, "k3",
                               "k3 L^2 (L: the length scale)"))
    return error;
  if (!model.HasLowerStop() && !model.HasUpperStop()) return std::nullopt;
  const double k_s = EffectiveContactStiffnessNPerM(model);
  if (auto error = ratio_error(k_s, "k_s", "the stop's stiffness")) return error;
  if (auto error = frequency_error(k_s, "k_s", "stop's")) return error;
  return damping_error(model.contact_damping_n_s_per_m, k_s, "c_s", "stop's");
}

}  // namespace

double EffectiveContactStiffnessNPerM(const ActuatorModel& model) {
  if (model.contact_law == ContactLaw::kLinear) return model.contact_stiffness;
  return model.contact_stiffness * std::sqrt(LengthScaleM(model));
}

bool ActuatorModel::IsPiecewiseLinear() const { return NonlinearTerms().empty(); }

std::string ActuatorModel::NonlinearTerms() const {
  std::string terms;
  auto add = [&](const char* term) { terms += terms.empty() ? term : std::string(", ") + term; };
  if (quadratic_stiffness_n_per_m2 != 0) add("k2 (quadratic stiffness)");
  if (cubic_stiffness_n_per_m3 != 0) add("k3 (cubic stiffness)");
  if (contact_law == ContactLaw::kHertzian && (HasLowerStop() || HasUpperStop())) add("Hertzian contact");
  if (friction_force_n != 0) add("friction_n (dry friction)");
  if (quadratic_damping_n_s2_per_m2 != 0) add("c2 (quadratic damping)");
  if (force_factor_b1_per_m != 0 || force_factor_b2_per_m2 != 0) add("b1, b2 (force factor over the stroke)");
  if (HasCoilPole()) add("tau_e (the coil's pole, a third state)");
  return terms;
}

ActuatorModel PaperModel() { return ActuatorModel{}; }

double LengthScaleM(const ActuatorModel& model) {
  if (model.HasLowerStop() && model.lower_stop_m != 0.0) return std::abs(model.lower_stop_m);
  if (model.HasUpperStop() && model.upper_stop_m != 0.0) return std::abs(model.upper_stop_m);
  return 1e-3;
}

std::vector<std::string> PresetNames() { return {"paper", "linear"}; }

ActuatorModel PresetModel(std::string_view name) {
  if (name == "paper") return PaperModel();
  if (name == "linear") {
    ActuatorModel model = PaperModel();
    model.lower_stop_m = ActuatorModel::kNoLowerStop;
    return model;
  }
  throw InputError("model", "unknown model preset '" + std::string(name) + "' (known: paper, linear)");
}

std::optional<FieldError> ActuatorModel::IsValid() const {
  if (auto error = Positive(mass_kg, "m_p")) return error;
  if (auto error = NonNegative(damping_n_s_per_m, "c_p")) return error;
  if (auto error = Positive(stiffness_n_per_m, "k_p")) return error;
  if (auto error = Finite(quadratic_stiffness_n_per_m2, "k2")) return error;
  if (auto error = Finite(cubic_stiffness_n_per_m3, "k3")) return error;
  if (auto error = Finite(gain_n_per_v, "g")) return error;
  if (auto error = Finite(force_factor_b1_per_m, "b1")) return error;
  if (auto error = Finite(force_factor_b2_per_m2, "b2")) return error;
  if (auto error = NonNegative(back_emf_damping_n_s_per_m, "c_emf")) return error;
  if (auto error = NonNegative(coil_time_constant_s, "tau_e")) return error;
  if (std::isnan(lower_stop_m) || lower_stop_m == ActuatorModel::kNoLimit)
    return FieldError{"d", "must be a finite position <= 0 or -inf (no stop), got " + FormatDouble(lower_stop_m)};
  if (lower_stop_m > 0)
    return FieldError{"d", "the lower stop must lie at or below the rest position (<= 0), got " +
                              FormatDouble(lower_stop_m)};
  if (std::isnan(upper_stop_m) || upper_stop_m == ActuatorModel::kNoLowerStop)
    return FieldError{"d_upper", "must be a finite position >= 0 or +inf (no stop), got " + FormatDouble(upper_stop_m)};
  if (upper_stop_m < 0)
    return FieldError{"d_upper", "the upper stop must lie at or above the rest position (>= 0), got " +
                                    FormatDouble(upper_stop_m)};
  if (HasLowerStop() && HasUpperStop() && upper_stop_m <= lower_stop_m)
    return FieldError{"d_upper", "must lie above the lower stop d"};
  if (HasLowerStop() || HasUpperStop())
    if (auto error = Positive(contact_stiffness, "k_s")) return error;
  if (auto error = NonNegative(contact_damping_n_s_per_m, "c_s")) return error;
  if (auto error = NonNegative(friction_force_n, "friction_n")) return error;
  if (auto error = Positive(friction_velocity_m_per_s, "friction_velocity")) return error;
  if (auto error = NonNegative(quadratic_damping_n_s2_per_m2, "c2")) return error;
  if (std::isnan(amplifier_limit_v) || amplifier_limit_v <= 0)
    return FieldError{"amplifier_limit_v", "must be > 0 or +inf (no limit), got " + FormatDouble(amplifier_limit_v)};
  return PhysicalBoundsError(*this);
}

const std::vector<ParameterInfo>& Parameters() {
  static const std::vector<ParameterInfo> table = {
      {"m_p", "mass_kg", "kg", "proof mass", &ActuatorModel::mass_kg},
      {"c_p", "damping_n_s_per_m", "N s/m", "suspension damping (with back-EMF)", &ActuatorModel::damping_n_s_per_m},
      {"k_p", "stiffness_n_per_m", "N/m", "suspension stiffness", &ActuatorModel::stiffness_n_per_m},
      {"k2", "quadratic_stiffness_n_per_m2", "N/m^2", "quadratic (asymmetric) suspension stiffness",
       &ActuatorModel::quadratic_stiffness_n_per_m2},
      {"k3", "cubic_stiffness_n_per_m3", "N/m^3", "cubic suspension stiffness (>0 hardening)",
       &ActuatorModel::cubic_stiffness_n_per_m3},
      {"g", "gain_n_per_v", "N/V", "force per drive volt (amplifier x coil)", &ActuatorModel::gain_n_per_v},
      {"b1", "force_factor_b1_per_m", "1/m", "force factor's slope over the stroke, g(x) = g (1 + b1 x + b2 x^2)",
       &ActuatorModel::force_factor_b1_per_m},
      {"b2", "force_factor_b2_per_m2", "1/m^2", "force factor's curvature (< 0: falls off both ways)",
       &ActuatorModel::force_factor_b2_per_m2},
      {"c_emf", "back_emf_damping_n_s_per_m", "N s/m", "the back-EMF part of c_p, following the force factor squared",
       &ActuatorModel::back_emf_damping_n_s_per_m},
      {"tau_e", "coil_time_constant_s", "s", "the coil's electrical time constant L / R (0: ignored)",
       &ActuatorModel::coil_time_constant_s},
      {"d", "lower_stop_m", "m", "lower end stop position (-inf: none)", &ActuatorModel::lower_stop_m},
      {"d_upper", "upper_stop_m", "m", "upper end stop position (+inf: none)", &ActuatorModel::upper_stop_m},
      {"k_s", "contact_stiffness", "N/m or N/m^1.5", "end-stop contact stiffness", &ActuatorModel::contact_stiffness},
      {"c_s", "contact_damping_n_s_per_m", "N s/m", "end-stop contact damping (only pushes)",
       &ActuatorModel::contact_damping_n_s_per_m},
      {"friction_n", "friction_force_n", "N", "dry friction level", &ActuatorModel::friction_force_n},
      {"friction_velocity", "friction_velocity_m_per_s", "m/s", "friction smoothing velocity",
       &ActuatorModel::friction_velocity_m_per_s},
      {"c2", "quadratic_damping_n_s2_per_m2", "N s^2/m^2", "quadratic damping, force c2 v|v|",
       &ActuatorModel::quadratic_damping_n_s2_per_m2},
      {"amplifier_limit_v", "amplifier_limit_v", "V", "drive clipping level (+inf: none)",
       &ActuatorModel::amplifier_limit_v},
  };
  return table;
}

const ParameterInfo& FindParameter(std::string_view key) {
  for (const ParameterInfo& info : Parameters())
    if (key == info.key || key == info.json_name) return info;
  std::string known;
  for (const ParameterInfo& info : Parameters()) known += std::string(known.empty() ? "" : ", ") + info.key;
  throw InputError(std::string(key), "unknown model parameter (known: " + known + ", contact_law)");
}

double ParseNumber(std::string_view text, const std::string& field) {
  std::string s(text);
  if (s == "inf" || s == "+inf") return std::numeric_limits<double>::infinity();
  if (s == "-inf") return -std::numeric_limits<double>::infinity();
  double value = 0;
  const char* end = s.data() + s.size();
  auto [ptr, ec] = std::from_chars(s.data(), end, value);
  if (ec != std::errc() || ptr != end || s.empty())
    throw InputError(field, "expected a number, got '" + s + "'");
  if (std::isnan(value)) throw InputError(field, "must not be NaN");
  return value;
}

void ApplyOverride(ActuatorModel* model, std::string_view assignment) {
  const size_t eq = assignment.find('=');
  if (eq == std::string_view::npos)
    throw InputError("--set", "expected key=value, got '" + std::string(assignment) + "'");
  const std::string_view key = assignment.substr(0, eq);
  const std::string_view value = assignment.substr(eq + 1);
  if (key == "contact_law") {
    model->contact_law = ParseContactLaw(value);
    return;
  }
  const ParameterInfo& info = FindParameter(key);
  model->*info.field = ParseNumber(value, info.key);
}

ContactLaw ParseContactLaw(std::string_view text) {
  if (text == "linear") return ContactLaw::kLinear;
  if (text == "hertzian" || text == "hertz") return ContactLaw::kHertzian;
  throw InputError("contact_law", "expected 'linear' or 'hertzian', got '" + std::string(text) + "'");
}

const char* ToString(ContactLaw law) { return law == ContactLaw::kLinear ? "linear" : "hertzian"; }

}  // namespace strokelab
