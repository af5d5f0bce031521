// DiagnosisToJson (diagnose.h).
#include <cmath>
#include <nlohmann/json.hpp>

#include "strokelab/diagnose/diagnose.h"
#include "strokelab/model/model_json.h"

namespace strokelab {
namespace {

nlohmann::json Number(double value) { return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(nullptr); }

nlohmann::json Parameters(const std::vector<FitParameter>& parameters) {
  nlohmann::json out = nlohmann::json::object();
  for (const FitParameter& p : parameters) {
    out[p.name] = {{"value", Number(p.value)},
                   {"standard_error", Number(p.standard_error)},
                   {"unit", p.unit},
                   {"fixed", p.fixed},
                   {"identifiable", p.identifiable}};
    if (!p.note.empty()) out[p.name]["note"] = p.note;
  }
  return out;
}

nlohmann::json Figures(const FitFigures& f) {
  return {{"nrmse", Number(f.nrmse)},
          {"heldout_nrmse", Number(f.heldout_nrmse)},
          {"chi2", Number(f.chi2)},
          {"heldout_chi2", Number(f.heldout_chi2)},
          {"residual_variance", Number(f.residual_variance)}};
}

nlohmann::json EvidenceJson(const Evidence& e) {
  nlohmann::json points = nlohmann::json::array();
  for (Effect effect : e.points_to) points.push_back(Info(effect).id);
  return {{"kind", e.kind},
          {"summary", e.summary},
          {"value", Number(e.value)},
          {"standard_error", Number(e.standard_error)},
          {"significance", Number(e.significance)},
          {"points_to", points}};
}

nlohmann::json Complexes(const std::vector<std::complex<double>>& values) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& c : values) out.push_back({{"re", Number(c.real())}, {"im", Number(c.imag())}});
  return out;
}

}  // namespace

nlohmann::json DiagnosisToJson(const Diagnosis& d) {
  nlohmann::json out;
  out["conclusion"] = d.conclusion;
  out["missing_physics"] = nlohmann::json::array();
  if (d.chosen >= 0) {
    const CandidateFit& c = d.candidates[d.chosen];
    for (Effect effect : d.missing_physics) {
      nlohmann::json entry;
      entry["effect"] = Info(effect).id;
      std::vector<FitParameter> own;
      for (const FitParameter& p : c.effect_parameters)
        if (p.name == Info(effect).parameter) own.push_back(p);
      entry["parameters"] = Parameters(own);
      entry["signature"] = Info(effect).signature;
      entry["evidence"] = nlohmann::json::array();
      for (const Evidence& e : d.signatures.evidence)
        for (Effect pointed : e.points_to)
          if (pointed == effect) entry["evidence"].push_back(EvidenceJson(e));
      entry["heldout_gain"] = Number(c.heldout_gain);
      entry["fit_gain"] = Number(c.fit_gain);
      entry["all_parameters"] = Parameters(c.parameters);
      out["missing_physics"].push_back(entry);
    }
  }
  out["fit_before"] = Figures(d.fit_before);
  out["fit_after"] = Figures(d.fit_after);
  out["base_parameters"] = Parameters(d.base.parameters);
  out["base_model"] = ModelToJson(d.base.model);
  out["base_warnings"] = d.base.warnings;
  out["heldout_records"] = nlohmann::json::array();
  for (size_t i : d.heldout) out["heldout_records"].push_back(d.before[i].name);

  out["candidates"] = nlohmann::json::array();
  for (size_t i = 0; i < d.candidates.size(); ++i) {
    const CandidateFit& c = d.candidates[i];
    out["candidates"].push_back({{"label", c.label},
                                 {"chosen", static_cast<int>(i) == d.chosen},
                                 {"fitted", c.fitted},
                                 {"converged", c.converged},
                                 {"heldout_gain", Number(c.heldout_gain)},
                                 {"fit_gain", Number(c.fit_gain)},
                                 {"figures", Figures(c.figures)},
                                 {"effect_parameters", Parameters(c.effect_parameters)},
                                 {"passes", c.passes},
                                 {"seconds", Number(c.seconds)},
                                 {"note", c.note}});
  }

  nlohmann::json signatures;
  signatures["evidence"] = nlohmann::json::array();
  for (const Evidence& e : d.signatures.evidence) signatures["evidence"].push_back(EvidenceJson(e));
  signatures["hotspots"] = nlohmann::json::array();
  for (const auto& h : d.signatures.hotspots)
    signatures["hotspots"].push_back({{"record", h.record},
                                      {"frequency_hz", Number(h.frequency_hz)},
                                      {"amplitude_v", Number(h.amplitude_v)},
                                      {"harmonic", h.harmonic},
                                      {"magnitude_error", Number(h.magnitude_error)},
                                      {"phase_error_rad", Number(h.phase_error_rad)},
                                      {"chi2_per_residual", Number(h.chi2_per_residual)}});
  signatures["levels"] = nlohmann::json::array();
  for (const auto& l : d.signatures.levels)
    signatures["levels"].push_back({{"amplitude_v", Number(l.amplitude_v)},
                                    {"clear_records", l.clear_records},
                                    {"resonance_hz", Number(l.resonance_hz)},
                                    {"resonance_se_hz", Number(l.resonance_se_hz)},
                                    {"second_harmonic_ratio", Number(l.second_harmonic_ratio)},
                                    {"third_harmonic_ratio", Number(l.third_harmonic_ratio)},
                                    {"mean_contact_time_s", Number(l.mean_contact_time_s)}});
  signatures["contact_window_s"] = Number(d.signatures.contact_window_s);
  signatures["residual_rms_near_contacts"] = Number(d.signatures.residual_rms_near_contacts);
  signatures["residual_rms_elsewhere"] = Number(d.signatures.residual_rms_elsewhere);
  out["signatures"] = signatures;

  out["records"] = nlohmann::json::array();
  for (size_t i = 0; i < d.before.size(); ++i) {
    const RecordMatch& b = d.before[i];
    const RecordMatch& a = i < d.after.size() ? d.after[i] : b;
    out["records"].push_back({{"name", b.name},
                              {"frequency_hz", Number(b.frequency_hz)},
                              {"amplitude_v", Number(b.amplitude_v)},
                              {"heldout", b.heldout},
                              {"clear", b.clear},
                              {"nrmse_before", Number(b.nrmse)},
                              {"nrmse_after", Number(a.nrmse)},
                              {"chi2_before", Number(b.chi2)},
                              {"model_period_before", b.model_period},
                              {"model_period_after", a.model_period},
                              {"model_contacts_before", Number(b.model_contacts_per_period)},
                              {"model_contacts_after", Number(a.model_contacts_per_period)},
                              {"chi2_after", Number(a.chi2)},
                              {"measured", Complexes(b.measured)},
                              {"model_before", Complexes(b.model)},
                              {"model_after", Complexes(a.model)}});
  }
  out["seconds"] = Number(d.seconds);
  return out;
}

}  // namespace strokelab
