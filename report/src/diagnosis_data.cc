// A diagnosis and its maps as plain data and back (diagnosis_data.h).
#include "strokelab/report/diagnosis_data.h"

#include <cmath>
#include <limits>
#include <type_traits>

#include "strokelab/base/errors.h"
#include "strokelab/base/json_number.h"
#include "strokelab/model/model_json.h"
#include "strokelab/report/sweep_tables.h"

namespace strokelab::report {
namespace {

using nlohmann::json;

constexpr size_t kMaxItems = 100'000;   // any array: records, points, candidates, ...
constexpr size_t kMaxHarmonics = 64;    // complex coefficients per record and model
constexpr size_t kMaxSurfaceBins = 64;  // per axis of the missing-force surface (it has 12)
constexpr size_t kMaxTextBytes = 64 << 10;

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

json ComplexesOut(const std::vector<std::complex<double>>& values) {
  json out = json::array();
  for (const auto& c : values) out.push_back({JsonNumber(c.real()), JsonNumber(c.imag())});
  return out;
}

json EffectsOut(const std::vector<Effect>& effects) {
  json out = json::array();
  for (Effect e : effects) out.push_back(Info(e).id);
  return out;
}

json MatchesOut(const std::vector<RecordMatch>& matches) {
  json out = json::array();
  for (const RecordMatch& m : matches)
    out.push_back({{"name", m.name}, {"frequency_hz", JsonNumber(m.frequency_hz)},
                   {"amplitude_v", JsonNumber(m.amplitude_v)}, {"heldout", m.heldout}, {"clear", m.clear},
                   {"power", JsonNumber(m.power)}, {"nrmse", JsonNumber(m.nrmse)}, {"chi2", JsonNumber(m.chi2)},
                   {"measured", ComplexesOut(m.measured)}, {"model", ComplexesOut(m.model)},
                   {"model_period", m.model_period},
                   {"model_contacts_per_period", JsonNumber(m.model_contacts_per_period)},
                   {"harmonic_chi2", JsonNumbers(m.harmonic_chi2)}, {"residuals", m.residuals}});
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
                  size_t limit = kMaxItems) {
  *pointer = at + "/" + key;
  const json& v = Member(object, key, at);
  if (!v.is_array()) throw InputError(*pointer, "must be an array");
  if (v.size() > limit) throw InputError(*pointer, "has more than " + std::to_string(limit) + " items");
  return v;
}

// Each item of the array at `key`, read by read(item, the item's pointer), within `limit` items.
template <class Read>
auto ItemsIn(const json& object, const char* key, const std::string& at, Read read, size_t limit = kMaxItems) {
  std::string p;
  const json& items = Array(object, key, at, &p, limit);
  std::vector<std::invoke_result_t<Read, const json&, const std::string&>> out;
  out.reserve(items.size());
  for (size_t i = 0; i < items.size(); ++i) out.push_back(read(items[i], p + "/" + std::to_string(i)));
  return out;
}

std::vector<std::string> Texts(const json& object, const char* key, const std::string& at) {
  return ItemsIn(object, key, at, [](const json& v, const std::string& q) { return Text(v, q); });
}

// Finite numbers; with `null_is_nan`, nulls too (read as NaN).
std::vector<double> Numbers(const json& object, const char* key, const std::string& at, bool null_is_nan = false) {
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

std::vector<std::complex<double>> ComplexesIn(const json& object, const char* key, const std::string& at) {
  auto read = [](const json& v, const std::string& q) {
    if (!v.is_array() || v.size() != 2) throw InputError(q, "must be [re, im]");
    const json pair = {{"re", v[0]}, {"im", v[1]}};
    return std::complex<double>(Number(pair, "re", q), Number(pair, "im", q));
  };
  return ItemsIn(object, key, at, read, kMaxHarmonics);
}

ActuatorModel ModelIn(const json& object, const char* key, const std::string& at) {
  return ModelFromJson(Member(object, key, at), at + "/" + key);
}

std::vector<RecordMatch> MatchesIn(const json& object, const char* key, const std::string& at) {
  return ItemsIn(object, key, at, [](const json& v, const std::string& q) {
    RecordMatch m;
    m.name = Text(v, "name", q);
    m.frequency_hz = Number(v, "frequency_hz", q);
    m.amplitude_v = Number(v, "amplitude_v", q);
    m.heldout = Flag(v, "heldout", q);
    m.clear = Flag(v, "clear", q);
    m.power = Number(v, "power", q);
    m.nrmse = Number(v, "nrmse", q);
    m.chi2 = Number(v, "chi2", q);
    m.measured = ComplexesIn(v, "measured", q);
    m.model = ComplexesIn(v, "model", q);
    m.model_period = static_cast<int>(Integer(v, "model_period", q, -1, 1 << 20));
    m.model_contacts_per_period = Number(v, "model_contacts_per_period", q);
    m.harmonic_chi2 = Numbers(v, "harmonic_chi2", q);
    if (m.harmonic_chi2.size() > kMaxHarmonics) throw InputError(q + "/harmonic_chi2", "has too many harmonics");
    m.residuals = static_cast<int>(Integer(v, "residuals", q, 0, 2 * kMaxHarmonics));
    return m;
  });
}

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

MissingForceSurface MissingForceIn(const json& v, const std::string& at) {
  MissingForceSurface s;
  if (!v.contains("force_n")) {
    s.note = Text(v, "note", at);
    return s;
  }
  std::string p;
  s.x_m = NullableNumbers(Array(v, "x_m", at, &p, kMaxSurfaceBins), p);
  s.v_m_per_s = NullableNumbers(Array(v, "v_m_per_s", at, &p, kMaxSurfaceBins), p);
  // Rows per x bin, each of v_m_per_s.size() columns.
  const auto grid = [&](const char* key) {
    std::string rows_at;
    const json& rows = Array(v, key, at, &rows_at, kMaxSurfaceBins);
    if (rows.size() != s.x_m.size()) throw InputError(rows_at, "must have one row per x bin");
    std::vector<double> out;
    for (size_t r = 0; r < rows.size(); ++r) {
      const std::string row_at = rows_at + "/" + std::to_string(r);
      if (!rows[r].is_array() || rows[r].size() != s.v_m_per_s.size())
        throw InputError(row_at, "must be an array of one item per v bin");
      const std::vector<double> row = NullableNumbers(rows[r], row_at);
      out.insert(out.end(), row.begin(), row.end());
    }
    return out;
  };
  s.force_n = grid("force_n");
  s.standard_error_n = grid("standard_error_n");
  for (double count : grid("samples")) {
    if (!(count >= 0 && count <= kMaxItems * kMaxHarmonics && count == std::floor(count)))
      throw InputError(at + "/samples", "must hold whole numbers from 0 to " + std::to_string(kMaxItems * kMaxHarmonics));
    s.samples.push_back(static_cast<int>(count));
  }
  s.rms_n = Number(v, "rms_n", at);
  s.term = Text(v, "term", at);
  s.term_unit = Text(v, "term_unit", at);
  s.term_coefficient = Number(v, "term_coefficient", at);
  s.term_r2 = Number(v, "term_r2", at);
  s.linear_r2 = Number(v, "linear_r2", at);
  return s;
}

std::optional<Unexplained> UnexplainedIn(const json& object, const char* key, const std::string& at) {
  const json& v = Member(object, key, at);
  if (v.is_null()) return std::nullopt;
  const std::string q = at + "/" + key;
  Unexplained u;
  u.heldout_chi2 = Number(v, "heldout_chi2", q);
  u.heldout_residuals = static_cast<int>(Integer(v, "heldout_residuals", q, 0, 2 * kMaxHarmonics * kMaxItems));
  u.expected_chi2 = Number(v, "expected_chi2", q);
  u.threshold_chi2 = Number(v, "threshold_chi2", q);
  u.p_value = Number(v, "p_value", q);
  u.misfit_to_noise = Number(v, "misfit_to_noise", q);
  std::string p;
  const json& places = Array(v, "places", q, &p);
  for (size_t i = 0; i < places.size(); ++i) {
    const std::string r = p + "/" + std::to_string(i);
    const json& w = places[i];
    u.places.push_back({Text(w, "record", r), Number(w, "frequency_hz", r), Number(w, "amplitude_v", r),
                        Flag(w, "heldout", r), Number(w, "chi2_per_residual", r),
                        static_cast<int>(Integer(w, "worst_harmonic", r, 1, kMaxHarmonics)),
                        Number(w, "worst_harmonic_hz", r), Number(w, "residual_peak_phase_deg", r),
                        Number(w, "impact_phase_deg", r)});
    // The ringing figures: absent from diagnoses stored before they were added.
    Unexplained::Place& place = u.places.back();
    if (w.contains("ring_frequency_hz")) {
      place.ring_frequency_hz = Number(w, "ring_frequency_hz", r);
      place.ring_damping_ratio = Number(w, "ring_damping_ratio", r);
      place.ring_amplitude = Number(w, "ring_amplitude", r);
      place.ring_to_noise = Number(w, "ring_to_noise", r);
    }
  }
  const json& per_order = Array(v, "harmonic_chi2_per_residual", q, &p);  // null: no residual of that order
  if (per_order.size() > kMaxHarmonics) throw InputError(p, "has too many harmonics");
  u.harmonic_chi2_per_residual = NullableNumbers(per_order, p);
  u.description = Text(v, "description", q);
  // Absent from diagnoses stored before it was added.
  if (v.contains("missing_force")) u.missing_force = MissingForceIn(Member(v, "missing_force", q), q + "/missing_force");
  return u;
}

void RequireIndex(int64_t index, size_t size, const std::string& at) {
  if (index < 0 || static_cast<size_t>(index) >= size) throw InputError(at, "is not an index into its list");
}

}  // namespace

json DiagnosisDataToJson(const Diagnosis& d, const DiagnosisMaps& maps) {
  json base = {{"model_kind", ToString(d.base.model_kind)}, {"response", ToString(d.base.response)},
               {"absolute_scale", d.base.absolute_scale}, {"parameters", ParametersOut(d.base.parameters)},
               {"model", ModelToJson(d.base.model)}, {"identifiability", d.base.identifiability},
               {"warnings", d.base.warnings}};
  json evidence = json::array(), hotspots = json::array(), levels = json::array();
  for (const Evidence& e : d.signatures.evidence)
    evidence.push_back({{"kind", e.kind}, {"summary", e.summary}, {"value", JsonNumber(e.value)},
                        {"standard_error", JsonNumber(e.standard_error)}, {"significance", JsonNumber(e.significance)},
                        {"points_to", EffectsOut(e.points_to)}});
  for (const auto& h : d.signatures.hotspots)
    hotspots.push_back({{"record", h.record}, {"frequency_hz", JsonNumber(h.frequency_hz)},
                        {"amplitude_v", JsonNumber(h.amplitude_v)}, {"harmonic", h.harmonic},
                        {"magnitude_error", JsonNumber(h.magnitude_error)},
                        {"phase_error_rad", JsonNumber(h.phase_error_rad)},
                        {"chi2_per_residual", JsonNumber(h.chi2_per_residual)}});
  for (const auto& l : d.signatures.levels)
    levels.push_back({{"amplitude_v", JsonNumber(l.amplitude_v)}, {"clear_records", l.clear_records},
                      {"resonance_hz", JsonNumber(l.resonance_hz)}, {"resonance_se_hz", JsonNumber(l.resonance_se_hz)},
                      {"second_harmonic_ratio", JsonNumber(l.second_harmonic_ratio)},
                      {"third_harmonic_ratio", JsonNumber(l.third_harmonic_ratio)},
                      {"mean_contact_time_s", JsonNumber(l.mean_contact_time_s)}});
  json candidates = json::array();
  for (const CandidateFit& c : d.candidates)
    candidates.push_back({{"effects", EffectsOut(c.effects)}, {"label", c.label}, {"fitted", c.fitted},
                          {"converged", c.converged}, {"parameters", ParametersOut(c.parameters)},
                          {"effect_parameters", ParametersOut(c.effect_parameters)}, {"model", ModelToJson(c.model)},
                          {"figures", FiguresOut(c.figures)}, {"heldout_gain", JsonNumber(c.heldout_gain)},
                          {"fit_gain", JsonNumber(c.fit_gain)}, {"passes", c.passes},
                          {"seconds", JsonNumber(c.seconds)}, {"note", c.note}, {"decision", c.decision}});
  json diagnosis = {{"base", base},
                    {"heldout", d.heldout},
                    {"before", MatchesOut(d.before)},
                    {"after", MatchesOut(d.after)},
                    {"fit_before", FiguresOut(d.fit_before)},
                    {"fit_after", FiguresOut(d.fit_after)},
                    {"signatures",
                     {{"evidence", evidence}, {"hotspots", hotspots}, {"levels", levels},
                      {"contact_window_s", JsonNumber(d.signatures.contact_window_s)},
                      {"residual_rms_near_contacts", JsonNumber(d.signatures.residual_rms_near_contacts)},
                      {"residual_rms_elsewhere", JsonNumber(d.signatures.residual_rms_elsewhere)}}},
                    {"candidates", candidates},
                    {"missing_physics", EffectsOut(d.missing_physics)},
                    {"chosen", d.chosen},
                    {"model", ModelToJson(d.model)},
                    {"model_note", d.model_note},
                    {"unexplained", UnexplainedToJson(d.unexplained)},
                    {"curves", CurvesToJson(d.curves)},
                    {"conclusion", d.conclusion},
                    {"seconds", JsonNumber(d.seconds)}};
  json map_json = {{"frequency_hz", AxisOut(maps.frequency_hz)}, {"amplitude_v", AxisOut(maps.amplitude_v)},
                   {"base", SweepOut(maps.base)}, {"diagnosed", SweepOut(maps.diagnosed)},
                   {"base_note", maps.base_note}, {"diagnosed_note", maps.diagnosed_note},
                   {"same_model", maps.same_model}, {"note", maps.note}, {"seconds", JsonNumber(maps.seconds)}};
  return {{"diagnosis", diagnosis}, {"maps", map_json}};
}

DiagnosisData DiagnosisDataFromJson(const json& in) {
  DiagnosisData out;
  Diagnosis& d = out.diagnosis;
  const json& dj = Member(in, "diagnosis", "");
  const std::string at = "/diagnosis";
  std::string p;

  const json& b = Member(dj, "base", at);
  const std::string bat = at + "/base";
  const std::string kind = Text(b, "model_kind", bat);
  if (kind != ToString(FitModelKind::kPaper) && kind != ToString(FitModelKind::kLinear))
    throw InputError(bat + "/model_kind", "is not a fit model kind");
  d.base.model_kind = kind == ToString(FitModelKind::kPaper) ? FitModelKind::kPaper : FitModelKind::kLinear;
  try {
    d.base.response = ParseResponseKind(Text(b, "response", bat));
  } catch (const InputError& e) {
    throw InputError(bat + "/response", e.bare_message());
  }
  d.base.absolute_scale = Flag(b, "absolute_scale", bat);
  d.base.parameters = ParametersIn(b, "parameters", bat);
  d.base.model = ModelIn(b, "model", bat);
  d.base.identifiability = Text(b, "identifiability", bat);
  d.base.warnings = Texts(b, "warnings", bat);

  d.before = MatchesIn(dj, "before", at);
  d.after = MatchesIn(dj, "after", at);
  if (!d.after.empty() && d.after.size() != d.before.size())
    throw InputError(at + "/after", "must match /diagnosis/before record for record");
  const json& heldout = Array(dj, "heldout", at, &p);
  for (size_t i = 0; i < heldout.size(); ++i) {
    const std::string q = p + "/" + std::to_string(i);
    if (!heldout[i].is_number_integer()) throw InputError(q, "must be a record index");
    RequireIndex(heldout[i].get<int64_t>(), d.before.size(), q);
    d.heldout.push_back(heldout[i].get<size_t>());
  }
  d.fit_before = FiguresIn(dj, "fit_before", at);
  d.fit_after = FiguresIn(dj, "fit_after", at);

  const json& sj = Member(dj, "signatures", at);
  const std::string sat = at + "/signatures";
  const json& evidence = Array(sj, "evidence", sat, &p);
  for (size_t i = 0; i < evidence.size(); ++i) {
    const std::string q = p + "/" + std::to_string(i);
    const json& v = evidence[i];
    d.signatures.evidence.push_back({Text(v, "kind", q), Text(v, "summary", q), Number(v, "value", q),
                                     Number(v, "standard_error", q), Number(v, "significance", q),
                                     EffectsIn(v, "points_to", q)});
  }
  const json& hotspots = Array(sj, "hotspots", sat, &p);
  for (size_t i = 0; i < hotspots.size(); ++i) {
    const std::string q = p + "/" + std::to_string(i);
    const json& v = hotspots[i];
    d.signatures.hotspots.push_back({Text(v, "record", q), Number(v, "frequency_hz", q), Number(v, "amplitude_v", q),
                                     static_cast<int>(Integer(v, "harmonic", q, 1, kMaxHarmonics)),
                                     Number(v, "magnitude_error", q), Number(v, "phase_error_rad", q),
                                     Number(v, "chi2_per_residual", q)});
  }
  const json& levels = Array(sj, "levels", sat, &p);
  for (size_t i = 0; i < levels.size(); ++i) {
    const std::string q = p + "/" + std::to_string(i);
    const json& v = levels[i];
    d.signatures.levels.push_back({Number(v, "amplitude_v", q),
                                   static_cast<size_t>(Integer(v, "clear_records", q, 0, kMaxItems)),
                                   Number(v, "resonance_hz", q), Number(v, "resonance_se_hz", q),
                                   Number(v, "second_harmonic_ratio", q), Number(v, "third_harmonic_ratio", q),
                                   Number(v, "mean_contact_time_s", q)});
  }
  d.signatures.contact_window_s = Number(sj, "contact_window_s", sat);
  d.signatures.residual_rms_near_contacts = Number(sj, "residual_rms_near_contacts", sat);
  d.signatures.residual_rms_elsewhere = Number(sj, "residual_rms_elsewhere", sat);

  const json& candidates = Array(dj, "candidates", at, &p);
  for (size_t i = 0; i < candidates.size(); ++i) {
    const std::string q = p + "/" + std::to_string(i);
    const json& v = candidates[i];
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
    d.candidates.push_back(std::move(c));
  }
  d.missing_physics = EffectsIn(dj, "missing_physics", at);
  d.chosen = static_cast<int>(Integer(dj, "chosen", at, -1, static_cast<int64_t>(d.candidates.size()) - 1));
  if ((d.chosen < 0) != d.missing_physics.empty())
    throw InputError(at + "/chosen", "names a candidate exactly when missing_physics is not empty");
  d.model = ModelIn(dj, "model", at);
  d.model_note = Text(dj, "model_note", at);
  d.unexplained = UnexplainedIn(dj, "unexplained", at);
  d.curves = CurvesIn(dj, "curves", at);
  d.conclusion = Text(dj, "conclusion", at);
  d.seconds = Number(dj, "seconds", at);

  const json& mj = Member(in, "maps", "");
  DiagnosisMaps& m = out.maps;
  m.frequency_hz = AxisIn(mj, "frequency_hz", "/maps");
  m.amplitude_v = AxisIn(mj, "amplitude_v", "/maps");
  m.base = SweepIn(mj, "base", "/maps");
  m.diagnosed = SweepIn(mj, "diagnosed", "/maps");
  m.base_note = Text(mj, "base_note", "/maps");
  m.diagnosed_note = Text(mj, "diagnosed_note", "/maps");
  m.same_model = Flag(mj, "same_model", "/maps");
  m.note = Text(mj, "note", "/maps");
  m.seconds = Number(mj, "seconds", "/maps");
  return out;
}

}  // namespace strokelab::report
