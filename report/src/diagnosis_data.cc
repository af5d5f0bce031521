// A diagnosis and its maps as plain data and back (diagnosis_data.h).
#include "strokelab/report/diagnosis_data.h"

#include <cmath>
#include <limits>

#include "data_json.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/json_number.h"
#include "strokelab/model/model_json.h"

namespace strokelab::report {
namespace {

using namespace data_json;

constexpr size_t kMaxHarmonics = 64;    // complex coefficients per record and model
constexpr size_t kMaxSurfaceBins = 64;  // per axis of the missing-force surface (it has 12)

json ComplexesOut(const std::vector<std::complex<double>>& values) {
  json out = json::array();
  for (const auto& c : values) out.push_back({JsonNumber(c.real()), JsonNumber(c.imag())});
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

std::vector<std::complex<double>> ComplexesIn(const json& object, const char* key, const std::string& at) {
  auto read = [](const json& v, const std::string& q) {
    if (!v.is_array() || v.size() != 2) throw InputError(q, "must be [re, im]");
    const json pair = {{"re", v[0]}, {"im", v[1]}};
    return std::complex<double>(Number(pair, "re", q), Number(pair, "im", q));
  };
  return ItemsIn(object, key, at, read, kMaxHarmonics);
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

}  // namespace

json DiagnosisDataToJson(const Diagnosis& d, const DiagnosisMaps& maps) {
  json base = {{"model_kind", ToString(d.base.model_kind)}, {"response", ToString(d.base.response)},
               {"absolute_scale", d.base.absolute_scale}, {"parameters", ParametersOut(d.base.parameters)},
               {"model", ModelToJson(d.base.model)}, {"identifiability", d.base.identifiability},
               {"warnings", d.base.warnings}};
  json hotspots = json::array(), levels = json::array();
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
  json diagnosis = {{"base", base},
                    {"heldout", d.heldout},
                    {"before", MatchesOut(d.before)},
                    {"after", MatchesOut(d.after)},
                    {"fit_before", FiguresOut(d.fit_before)},
                    {"fit_after", FiguresOut(d.fit_after)},
                    {"signatures",
                     {{"evidence", EvidenceOut(d.signatures.evidence)}, {"hotspots", hotspots}, {"levels", levels},
                      {"contact_window_s", JsonNumber(d.signatures.contact_window_s)},
                      {"residual_rms_near_contacts", JsonNumber(d.signatures.residual_rms_near_contacts)},
                      {"residual_rms_elsewhere", JsonNumber(d.signatures.residual_rms_elsewhere)}}},
                    {"candidates", CandidatesOut(d.candidates)},
                    {"selection_rounds", d.selection_rounds},
                    {"coil_round", d.coil_round},
                    {"missing_physics", EffectsOut(d.missing_physics)},
                    {"chosen", d.chosen},
                    {"model", ModelToJson(d.model)},
                    {"model_note", d.model_note},
                    {"unexplained", UnexplainedToJson(d.unexplained)},
                    {"curves", CurvesToJson(d.curves)},
                    {"conclusion", d.conclusion},
                    {"seconds", JsonNumber(d.seconds)}};
  return {{"diagnosis", diagnosis}, {"maps", MapsOut(maps)}};
}

DiagnosisData DiagnosisDataFromJson(const json& in) {
  DiagnosisData out;
  Diagnosis& d = out.diagnosis;
  const json& dj = Member(in, "diagnosis", "");
  const std::string at = "/diagnosis";
  std::string p;

  const json& b = Member(dj, "base", at);
  const std::string bat = at + "/base";
  d.base.model_kind = ModelKindIn(b, bat);
  d.base.response = ResponseIn(b, bat);
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
  d.signatures.evidence = EvidenceIn(sj, "evidence", sat);
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

  d.candidates = CandidatesIn(dj, "candidates", at);
  d.selection_rounds = static_cast<int>(Integer(dj, "selection_rounds", at, 1, 2));
  d.coil_round = dj.contains("coil_round") && Flag(dj, "coil_round", at);  // absent before 0.26.0
  d.missing_physics = EffectsIn(dj, "missing_physics", at);
  d.chosen = ChosenIn(dj, at, d.candidates.size(), !d.missing_physics.empty());
  d.model = ModelIn(dj, "model", at);
  d.model_note = Text(dj, "model_note", at);
  d.unexplained = UnexplainedIn(dj, "unexplained", at);
  d.curves = CurvesIn(dj, "curves", at);
  d.conclusion = Text(dj, "conclusion", at);
  d.seconds = Number(dj, "seconds", at);

  out.maps = MapsIn(in);
  return out;
}

}  // namespace strokelab::report
