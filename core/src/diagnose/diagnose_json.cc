// DiagnosisToJson (diagnose.h).
#include <cmath>
#include <nlohmann/json.hpp>

#include "strokelab/base/json_number.h"
#include "diagnose_internal.h"
#include "strokelab/diagnose/diagnose.h"
#include "strokelab/model/model_json.h"

namespace strokelab {
namespace internal {

nlohmann::json Parameters(const std::vector<FitParameter>& parameters) {
  nlohmann::json out = nlohmann::json::object();
  for (const FitParameter& p : parameters) {
    out[p.name] = FitParameterJson(p);
    if (p.note.empty()) out[p.name].erase("note");
  }
  return out;
}

nlohmann::json Figures(const FitFigures& f) {
  return {{"nrmse", JsonNumber(f.nrmse)},
          {"heldout_nrmse", JsonNumber(f.heldout_nrmse)},
          {"chi2", JsonNumber(f.chi2)},
          {"heldout_chi2", JsonNumber(f.heldout_chi2)},
          {"residual_variance", JsonNumber(f.residual_variance)}};
}

nlohmann::json EvidenceJson(const Evidence& e) {
  nlohmann::json points = nlohmann::json::array();
  for (Effect effect : e.points_to) points.push_back(Info(effect).id);
  return {{"kind", e.kind},
          {"summary", e.summary},
          {"value", JsonNumber(e.value)},
          {"standard_error", JsonNumber(e.standard_error)},
          {"significance", JsonNumber(e.significance)},
          {"points_to", points}};
}

nlohmann::json MissingPhysicsJson(const std::vector<CandidateFit>& candidates, int chosen,
                                  const std::vector<Effect>& missing_physics, const std::vector<Evidence>& evidence) {
  nlohmann::json out = nlohmann::json::array();
  if (chosen < 0) return out;
  const CandidateFit& c = candidates[chosen];
  for (Effect effect : missing_physics) {
    nlohmann::json entry;
    entry["effect"] = Info(effect).id;
    std::vector<FitParameter> own;
    for (const FitParameter& p : c.effect_parameters)
      for (const char* key : Info(effect).parameters)
        if (p.name == key) own.push_back(p);
    entry["parameters"] = Parameters(own);
    entry["signature"] = Info(effect).signature;
    entry["evidence"] = nlohmann::json::array();
    for (const Evidence& e : evidence)
      for (Effect pointed : e.points_to)
        if (pointed == effect) entry["evidence"].push_back(EvidenceJson(e));
    entry["heldout_gain"] = JsonNumber(c.heldout_gain);
    entry["fit_gain"] = JsonNumber(c.fit_gain);
    entry["all_parameters"] = Parameters(c.parameters);
    out.push_back(entry);
  }
  return out;
}

nlohmann::json CandidatesJson(const std::vector<CandidateFit>& candidates, int chosen) {
  nlohmann::json out = nlohmann::json::array();
  for (size_t i = 0; i < candidates.size(); ++i) {
    const CandidateFit& c = candidates[i];
    out.push_back({{"label", c.label},
                   {"chosen", static_cast<int>(i) == chosen},
                   {"fitted", c.fitted},
                   {"converged", c.converged},
                   {"heldout_gain", JsonNumber(c.heldout_gain)},
                   {"fit_gain", JsonNumber(c.fit_gain)},
                   {"figures", Figures(c.figures)},
                   {"effect_parameters", Parameters(c.effect_parameters)},
                   {"passes", c.passes},
                   {"seconds", JsonNumber(c.seconds)},
                   {"note", c.note},
                   {"decision", c.decision}});
  }
  return out;
}

}  // namespace internal

namespace {

nlohmann::json Complexes(const std::vector<std::complex<double>>& values) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& c : values) out.push_back({{"re", JsonNumber(c.real())}, {"im", JsonNumber(c.imag())}});
  return out;
}

// Rows per x bin; null where a bin holds fewer than 2 samples.
nlohmann::json MissingForceToJson(const MissingForceSurface& s) {
  if (s.force_n.empty()) return {{"note", s.note}};
  const size_t columns = s.v_m_per_s.size();
  nlohmann::json force = nlohmann::json::array(), se = nlohmann::json::array(), samples = nlohmann::json::array();
  for (size_t r = 0; r < s.x_m.size(); ++r) {
    const auto row = [&](const std::vector<double>& v) {
      return JsonNumbers(std::vector<double>(v.begin() + r * columns, v.begin() + (r + 1) * columns));
    };
    force.push_back(row(s.force_n));
    se.push_back(row(s.standard_error_n));
    samples.push_back(std::vector<int>(s.samples.begin() + r * columns, s.samples.begin() + (r + 1) * columns));
  }
  return {{"x_m", JsonNumbers(s.x_m)},
          {"v_m_per_s", JsonNumbers(s.v_m_per_s)},
          {"force_n", force},
          {"standard_error_n", se},
          {"samples", samples},
          {"rms_n", JsonNumber(s.rms_n)},
          {"term", s.term},
          {"term_unit", s.term_unit},
          {"term_coefficient", JsonNumber(s.term_coefficient)},
          {"term_r2", JsonNumber(s.term_r2)},
          {"linear_r2", JsonNumber(s.linear_r2)}};
}

}  // namespace

nlohmann::json UnexplainedToJson(const std::optional<Unexplained>& u) {
  if (!u) return nullptr;
  nlohmann::json places = nlohmann::json::array();
  for (const Unexplained::Place& p : u->places)
    places.push_back({{"record", p.record},
                      {"frequency_hz", JsonNumber(p.frequency_hz)},
                      {"amplitude_v", JsonNumber(p.amplitude_v)},
                      {"heldout", p.heldout},
                      {"chi2_per_residual", JsonNumber(p.chi2_per_residual)},
                      {"worst_harmonic", p.worst_harmonic},
                      {"worst_harmonic_hz", JsonNumber(p.worst_harmonic_hz)},
                      {"residual_peak_phase_deg", JsonNumber(p.residual_peak_phase_deg)},
                      {"impact_phase_deg", JsonNumber(p.impact_phase_deg)},
                      {"ring_frequency_hz", JsonNumber(p.ring_frequency_hz)},
                      {"ring_damping_ratio", JsonNumber(p.ring_damping_ratio)},
                      {"ring_amplitude", JsonNumber(p.ring_amplitude)},
                      {"ring_to_noise", JsonNumber(p.ring_to_noise)}});
  return {{"heldout_chi2", JsonNumber(u->heldout_chi2)},
          {"heldout_residuals", u->heldout_residuals},
          {"expected_chi2", JsonNumber(u->expected_chi2)},
          {"threshold_chi2", JsonNumber(u->threshold_chi2)},
          {"p_value", JsonNumber(u->p_value)},
          {"misfit_to_noise", JsonNumber(u->misfit_to_noise)},
          {"places", places},
          {"harmonic_chi2_per_residual", JsonNumbers(u->harmonic_chi2_per_residual)},
          {"description", u->description},
          {"missing_force", MissingForceToJson(u->missing_force)}};
}

nlohmann::json CurvesToJson(const std::vector<EffectCurve>& curves) {
  nlohmann::json out = nlohmann::json::array();
  for (const EffectCurve& c : curves)
    out.push_back({{"effect", Info(c.effect).id}, {"id", c.id}, {"title", c.title}, {"x_label", c.x_label},
                   {"y_label", c.y_label}, {"x", JsonNumbers(c.x)}, {"y", JsonNumbers(c.y)}, {"y_se", JsonNumbers(c.y_se)},
                   {"base_y", JsonNumbers(c.base_y)}, {"range", c.range}});
  return out;
}

nlohmann::json DiagnosisToJson(const Diagnosis& d) {
  nlohmann::json out;
  out["conclusion"] = d.conclusion;
  out["missing_physics"] = internal::MissingPhysicsJson(d.candidates, d.chosen, d.missing_physics, d.signatures.evidence);
  out["unexplained"] = UnexplainedToJson(d.unexplained);
  out["curves"] = CurvesToJson(d.curves);
  out["model"] = ModelToJson(d.model);
  out["model_note"] = d.model_note;
  out["fit_before"] = internal::Figures(d.fit_before);
  out["fit_after"] = internal::Figures(d.fit_after);
  out["base_parameters"] = internal::Parameters(d.base.parameters);
  out["base_model"] = ModelToJson(d.base.model);
  out["base_warnings"] = d.base.warnings;
  out["heldout_records"] = nlohmann::json::array();
  for (size_t i : d.heldout) out["heldout_records"].push_back(d.before[i].name);

  out["candidates"] = internal::CandidatesJson(d.candidates, d.chosen);
  out["selection_rounds"] = d.selection_rounds;
  out["coil_round"] = d.coil_round;

  nlohmann::json signatures;
  signatures["evidence"] = nlohmann::json::array();
  for (const Evidence& e : d.signatures.evidence) signatures["evidence"].push_back(internal::EvidenceJson(e));
  signatures["hotspots"] = nlohmann::json::array();
  for (const auto& h : d.signatures.hotspots)
    signatures["hotspots"].push_back({{"record", h.record},
                                      {"frequency_hz", JsonNumber(h.frequency_hz)},
                                      {"amplitude_v", JsonNumber(h.amplitude_v)},
                                      {"harmonic", h.harmonic},
                                      {"magnitude_error", JsonNumber(h.magnitude_error)},
                                      {"phase_error_rad", JsonNumber(h.phase_error_rad)},
                                      {"chi2_per_residual", JsonNumber(h.chi2_per_residual)}});
  signatures["levels"] = nlohmann::json::array();
  for (const auto& l : d.signatures.levels)
    signatures["levels"].push_back({{"amplitude_v", JsonNumber(l.amplitude_v)},
                                    {"clear_records", l.clear_records},
                                    {"resonance_hz", JsonNumber(l.resonance_hz)},
                                    {"resonance_se_hz", JsonNumber(l.resonance_se_hz)},
                                    {"second_harmonic_ratio", JsonNumber(l.second_harmonic_ratio)},
                                    {"third_harmonic_ratio", JsonNumber(l.third_harmonic_ratio)},
                                    {"mean_contact_time_s", JsonNumber(l.mean_contact_time_s)}});
  signatures["contact_window_s"] = JsonNumber(d.signatures.contact_window_s);
  signatures["residual_rms_near_contacts"] = JsonNumber(d.signatures.residual_rms_near_contacts);
  signatures["residual_rms_elsewhere"] = JsonNumber(d.signatures.residual_rms_elsewhere);
  out["signatures"] = signatures;

  out["records"] = nlohmann::json::array();
  for (size_t i = 0; i < d.before.size(); ++i) {
    const RecordMatch& b = d.before[i];
    const RecordMatch& a = i < d.after.size() ? d.after[i] : b;
    out["records"].push_back({{"name", b.name},
                              {"frequency_hz", JsonNumber(b.frequency_hz)},
                              {"amplitude_v", JsonNumber(b.amplitude_v)},
                              {"heldout", b.heldout},
                              {"clear", b.clear},
                              {"nrmse_before", JsonNumber(b.nrmse)},
                              {"nrmse_after", JsonNumber(a.nrmse)},
                              {"chi2_before", JsonNumber(b.chi2)},
                              {"model_period_before", b.model_period},
                              {"model_period_after", a.model_period},
                              {"model_contacts_before", JsonNumber(b.model_contacts_per_period)},
                              {"model_contacts_after", JsonNumber(a.model_contacts_per_period)},
                              {"chi2_after", JsonNumber(a.chi2)},
                              {"measured", Complexes(b.measured)},
                              {"model_before", Complexes(b.model)},
                              {"model_after", Complexes(a.model)}});
  }
  out["seconds"] = JsonNumber(d.seconds);
  return out;
}

}  // namespace strokelab
