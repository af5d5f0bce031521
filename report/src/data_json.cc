// The JSON helpers both diagnoses' data share (data_json.h).
#include "data_json.h"

#include <cmath>
#include <limits>

#include "strokelab/base/errors.h"
#include "strokelab/base/json_number.h"
#include "strokelab/model/model_json.h"
#include "strokelab/report/sweep_tables.h"

namespace strokelab::report::data_json {

// ---- Writing ----

json ParametersOut(const std::vector<FitParameter>& parameters) {
  json out = json::array();
  for (const FitParameter& p : parameters)
    out.push_back({{"name", p.name}, {"unit", p.unit}, {"value", JsonNumber(p.value)},
                   {"standard_error", JsonNumber(p.standard_error)}, {"fixed", p.fixed},
                   {"identifiable", p.identifiable}, {"note", p.note}});
  return out;
}

json FiguresOut(const FitFigures& f) {
  return {{"nrmse", JsonNumber(f.nrmse)}, {"heldout_nrmse", JsonNumber(f.heldout_nrmse)}, {"chi2", JsonNumber(f.chi2)},
          {"heldout_chi2", JsonNumber(f.heldout_chi2)}, {"residual_variance", JsonNumber(f.residual_variance)}};
}

json EffectsOut(const std::vector<Effect>& effects) {
  json out = json::array();
  for (Effect e : effects) out.push_back(Info(e).id);
  return out;
}

json SweepOut(const std::optional<SweepResult>& sweep) {
  if (!sweep) return nullptr;
  json points = json::array(), thresholds = json::array(), jumps = json::array();
  for (const SweepPoint& p : sweep->points) points.push_back(RowToJson(p));
  for (const SaturationThreshold& t : sweep->saturation_threshold) thresholds.push_back(RowToJson(t));
  for (const JumpInterval& j : sweep->jump) jumps.push_back(RowToJson(j));
  return {{"frequency_hz", sweep->frequency_hz}, {"amplitude_v", sweep->amplitude_v}, {"points", points},
          {"saturation_threshold", thresholds}, {"jump", jumps}, {"failures", sweep->failures},
          {"wall_time_s", JsonNumber(sweep->wall_time_s)}, {"points_per_second", JsonNumber(sweep->points_per_second)}};
}

json AxisOut(const GridAxis& axis) {
  return {{"from", JsonNumber(axis.from)}, {"to", JsonNumber(axis.to)}, {"points", axis.points}, {"geometric", axis.geometric}};
}

// ---- Reading, each member checked and named by its JSON pointer ----

const json& Member(const json& object, const char* key, const std::string& at) {
  if (!object.is_object()) throw InputError(at, "must be an object");
  const auto it = object.find(key);
  if (it == object.end()) throw InputError(at + "/" + key, "is missing");
  return *it;
}

double Number(const json& object, const char* key, const std::string& at) {
  const json& v = Member(object, key, at);
  if (v.is_null()) return std::numeric_limits<double>::quiet_NaN();
  if (!v.is_number() || !std::isfinite(v.get<double>())) throw InputError(at + "/" + key, "must be a finite number or null");
  return v.get<double>();
}

int64_t Integer(const json& object, const char* key, const std::string& at, int64_t min, int64_t max) {
  const json& v = Member(object, key, at);
  if (!v.is_number_integer() || v.get<int64_t>() < min || v.get<int64_t>() > max)
    throw InputError(at + "/" + key, "must be a whole number from " + std::to_string(min) + " to " + std::to_string(max));
  return v.get<int64_t>();
}

bool Flag(const json& object, const char* key, const std::string& at) {
  const json& v = Member(object, key, at);
  if (!v.is_boolean()) throw InputError(at + "/" + key, "must be true or false");
  return v.get<bool>();
}

std::string Text(const json& value, const std::string& at) {
  if (!value.is_string()) throw InputError(at, "must be a string");
  if (value.get_ref<const std::string&>().size() > kMaxTextBytes) throw InputError(at, "is longer than 64 KiB");
  return value.get<std::string>();
}
std::string Text(const json& object, const char* key, const std::string& at) {
  return Text(Member(object, key, at), at + "/" + key);
}

// The array at `key` (its pointer in *pointer), within `limit` items.
const json& Array(const json& object, const char* key, const std::string& at, std::string* pointer,
                  size_t limit) {
  *pointer = at + "/" + key;
  const json& v = Member(object, key, at);
  if (!v.is_array()) throw InputError(*pointer, "must be an array");
  if (v.size() > limit) throw InputError(*pointer, "has more than " + std::to_string(limit) + " items");
  return v;
}

std::vector<std::string> Texts(const json& object, const char* key, const std::string& at) {
  return ItemsIn(object, key, at, [](const json& v, const std::string& q) { return Text(v, q); });
}

// Finite numbers; with `null_is_nan`, nulls too (read as NaN).
std::vector<double> Numbers(const json& object, const char* key, const std::string& at, bool null_is_nan) {
  return ItemsIn(object, key, at, [null_is_nan](const json& v, const std::string& q) {
    if (null_is_nan && v.is_null()) return static_cast<double>(NAN);
    if (!v.is_number() || !std::isfinite(v.get<double>()))
      throw InputError(q, null_is_nan ? "must be a finite number or null" : "must be a finite number");
    return v.get<double>();
  });
}

// An effect's id at `at`; an unknown id is refused naming that pointer.
Effect EffectAt(const json& value, const std::string& at) {
  try {
    return ParseEffect(Text(value, at));
  } catch (const InputError& e) {
    throw InputError(at, e.bare_message());
  }
}

std::vector<Effect> EffectsIn(const json& object, const char* key, const std::string& at) {
  return ItemsIn(object, key, at, EffectAt);
}

std::vector<FitParameter> ParametersIn(const json& object, const char* key, const std::string& at) {
  return ItemsIn(object, key, at, [](const json& v, const std::string& q) {
    return FitParameter{Text(v, "name", q),           Text(v, "unit", q),         Number(v, "value", q),
                        Number(v, "standard_error", q), Flag(v, "fixed", q),        Flag(v, "identifiable", q),
                        Text(v, "note", q)};
  });
}

FitFigures FiguresIn(const json& object, const char* key, const std::string& at) {
  const json& v = Member(object, key, at);
  const std::string q = at + "/" + key;
  return {Number(v, "nrmse", q), Number(v, "heldout_nrmse", q), Number(v, "chi2", q), Number(v, "heldout_chi2", q),
          Number(v, "residual_variance", q)};
}

ActuatorModel ModelIn(const json& object, const char* key, const std::string& at) {
  return ModelFromJson(Member(object, key, at), at + "/" + key);
}

namespace {

template <class Row>
std::vector<Row> RowsIn(const json& object, const char* key, const std::string& at) {
  return ItemsIn(object, key, at, [](const json& v, const std::string& q) {
    if (v.is_object())  // RowFromJson would take an infinity as a number
      for (auto it = v.begin(); it != v.end(); ++it)
        if (it->is_number() && !std::isfinite(it->template get<double>())) throw InputError(q + "/" + it.key(), "must be finite");
    try {
      return RowFromJson<Row>(v);
    } catch (const InputError& e) {
      throw InputError(q + "/" + e.field(), e.bare_message());
    } catch (const json::exception& e) {
      throw InputError(q, e.what());
    }
  });
}

}  // namespace

std::optional<SweepResult> SweepIn(const json& object, const char* key, const std::string& at) {
  const json& v = Member(object, key, at);
  if (v.is_null()) return std::nullopt;
  const std::string q = at + "/" + key;
  SweepResult s;
  s.frequency_hz = Numbers(v, "frequency_hz", q);
  s.amplitude_v = Numbers(v, "amplitude_v", q);
  s.points = RowsIn<SweepPoint>(v, "points", q);
  s.saturation_threshold = RowsIn<SaturationThreshold>(v, "saturation_threshold", q);
  s.jump = RowsIn<JumpInterval>(v, "jump", q);
  s.failures = Texts(v, "failures", q);
  s.wall_time_s = Number(v, "wall_time_s", q);
  s.points_per_second = Number(v, "points_per_second", q);
  return s;
}

GridAxis AxisIn(const json& object, const char* key, const std::string& at) {
  const json& v = Member(object, key, at);
  const std::string q = at + "/" + key;
  GridAxis axis;
  axis.from = Number(v, "from", q);
  axis.to = Number(v, "to", q);
  axis.points = static_cast<int>(Integer(v, "points", q, 0, 1 << 20));
  axis.geometric = Flag(v, "geometric", q);
  return axis;
}

std::vector<EffectCurve> CurvesIn(const json& object, const char* key, const std::string& at) {
  return ItemsIn(object, key, at, [](const json& v, const std::string& q) {
    EffectCurve c;
    c.effect = EffectAt(Member(v, "effect", q), q + "/effect");
    c.id = Text(v, "id", q);
    c.title = Text(v, "title", q);
    c.x_label = Text(v, "x_label", q);
    c.y_label = Text(v, "y_label", q);
    c.x = Numbers(v, "x", q);
    c.y = Numbers(v, "y", q, true);
    c.y_se = Numbers(v, "y_se", q, true);
    c.base_y = Numbers(v, "base_y", q, true);
    c.range = Text(v, "range", q);
    if (c.y.size() != c.x.size() || c.y_se.size() != c.x.size() || c.base_y.size() != c.x.size())
      throw InputError(q, "x, y, y_se and base_y must have the same length");
    return c;
  });
}

// The items of array `v` (at pointer `at`): finite numbers, or null read as NaN.
std::vector<double> NullableNumbers(const json& v, const std::string& at) {
  std::vector<double> out;
  for (size_t i = 0; i < v.size(); ++i) {
    const json& x = v[i];
    if (!x.is_null() && !(x.is_number() && std::isfinite(x.get<double>())))
      throw InputError(at + "/" + std::to_string(i), "must be a finite number or null");
    out.push_back(x.is_null() ? std::numeric_limits<double>::quiet_NaN() : x.get<double>());
  }
  return out;
}

void RequireIndex(int64_t index, size_t size, const std::string& at) {
  if (index < 0 || static_cast<size_t>(index) >= size) throw InputError(at, "is not an index into its list");
}

// ---- What both diagnoses hold ----

FitModelKind ModelKindIn(const json& object, const std::string& at) {
  const std::string kind = Text(object, "model_kind", at);
  if (kind != ToString(FitModelKind::kPaper) && kind != ToString(FitModelKind::kLinear))
    throw InputError(at + "/model_kind", "is not a fit model kind");
  return kind == ToString(FitModelKind::kPaper) ? FitModelKind::kPaper : FitModelKind::kLinear;
}

ResponseKind ResponseIn(const json& object, const std::string& at) {
  try {
    return ParseResponseKind(Text(object, "response", at));
  } catch (const InputError& e) {
    throw InputError(at + "/response", e.bare_message());
  }
}

json CandidatesOut(const std::vector<CandidateFit>& candidates) {
  json out = json::array();
  for (const CandidateFit& c : candidates)
    out.push_back({{"effects", EffectsOut(c.effects)}, {"label", c.label}, {"fitted", c.fitted},
                   {"converged", c.converged}, {"parameters", ParametersOut(c.parameters)},
                   {"effect_parameters", ParametersOut(c.effect_parameters)}, {"model", ModelToJson(c.model)},
                   {"figures", FiguresOut(c.figures)}, {"heldout_gain", JsonNumber(c.heldout_gain)},
                   {"fit_gain", JsonNumber(c.fit_gain)}, {"passes", c.passes},
                   {"seconds", JsonNumber(c.seconds)}, {"note", c.note}, {"decision", c.decision}});
  return out;
}

std::vector<CandidateFit> CandidatesIn(const json& object, const char* key, const std::string& at) {
  return ItemsIn(object, key, at, [](const json& v, const std::string& q) {
    CandidateFit c;
    c.effects = EffectsIn(v, "effects", q);
    c.label = Text(v, "label", q);
    c.fitted = Flag(v, "fitted", q);
    c.converged = Flag(v, "converged", q);
    c.parameters = ParametersIn(v, "parameters", q);
    c.effect_parameters = ParametersIn(v, "effect_parameters", q);
    c.model = ModelIn(v, "model", q);
    c.figures = FiguresIn(v, "figures", q);
    c.heldout_gain = Number(v, "heldout_gain", q);
    c.fit_gain = Number(v, "fit_gain", q);
    c.passes = static_cast<int>(Integer(v, "passes", q, 0, 1 << 20));
    c.seconds = Number(v, "seconds", q);
    c.note = Text(v, "note", q);
    c.decision = Text(v, "decision", q);
    return c;
  });
}

json EvidenceOut(const std::vector<Evidence>& evidence) {
  json out = json::array();
  for (const Evidence& e : evidence)
    out.push_back({{"kind", e.kind}, {"summary", e.summary}, {"value", JsonNumber(e.value)},
                   {"standard_error", JsonNumber(e.standard_error)}, {"significance", JsonNumber(e.significance)},
                   {"points_to", EffectsOut(e.points_to)}});
  return out;
}

std::vector<Evidence> EvidenceIn(const json& object, const char* key, const std::string& at) {
  return ItemsIn(object, key, at, [](const json& v, const std::string& q) {
    return Evidence{Text(v, "kind", q), Text(v, "summary", q), Number(v, "value", q), Number(v, "standard_error", q),
                    Number(v, "significance", q), EffectsIn(v, "points_to", q)};
  });
}

int ChosenIn(const json& object, const std::string& at, size_t candidates, bool named) {
  const int chosen = static_cast<int>(Integer(object, "chosen", at, -1, static_cast<int64_t>(candidates) - 1));
  if ((chosen < 0) == named) throw InputError(at + "/chosen", "names a candidate exactly when missing_physics is not empty");
  return chosen;
}

json MapsOut(const DiagnosisMaps& maps) {
  return {{"frequency_hz", AxisOut(maps.frequency_hz)}, {"amplitude_v", AxisOut(maps.amplitude_v)},
          {"base", SweepOut(maps.base)}, {"diagnosed", SweepOut(maps.diagnosed)},
          {"base_note", maps.base_note}, {"diagnosed_note", maps.diagnosed_note},
          {"same_model", maps.same_model}, {"note", maps.note}, {"seconds", JsonNumber(maps.seconds)}};
}

DiagnosisMaps MapsIn(const json& in) {
  const json& mj = Member(in, "maps", "");
  DiagnosisMaps m;
  m.frequency_hz = AxisIn(mj, "frequency_hz", "/maps");
  m.amplitude_v = AxisIn(mj, "amplitude_v", "/maps");
  m.base = SweepIn(mj, "base", "/maps");
  m.diagnosed = SweepIn(mj, "diagnosed", "/maps");
  m.base_note = Text(mj, "base_note", "/maps");
  m.diagnosed_note = Text(mj, "diagnosed_note", "/maps");
  m.same_model = Flag(mj, "same_model", "/maps");
  m.note = Text(mj, "note", "/maps");
  m.seconds = Number(mj, "seconds", "/maps");
  return m;
}

}  // namespace strokelab::report::data_json
