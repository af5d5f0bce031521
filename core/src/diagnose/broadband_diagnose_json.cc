// BroadbandDiagnosisToJson and BroadbandUnexplainedToJson (diagnose/broadband_diagnose.h).
#include <utility>

#include <nlohmann/json.hpp>

#include "diagnose_internal.h"
#include "strokelab/base/json_number.h"
#include "strokelab/diagnose/broadband_diagnose.h"
#include "strokelab/model/model_json.h"

namespace strokelab {

nlohmann::json BroadbandUnexplainedToJson(const std::optional<BroadbandUnexplained>& u) {
  if (!u) return nullptr;
  nlohmann::json places = nlohmann::json::array();
  for (const BroadbandUnexplained::Place& p : u->places)
    places.push_back({{"record", p.record},
                      {"chi2_per_sample", JsonNumber(p.chi2_per_sample)},
                      {"peak_frequency_hz", JsonNumber(p.peak_frequency_hz)},
                      {"near_contact_share", JsonNumber(p.near_contact_share)},
                      {"contact_time_share", JsonNumber(p.contact_time_share)}});
  return {{"parts", u->parts},
          {"chi2", JsonNumber(u->chi2)},
          {"dof", JsonNumber(u->dof)},
          {"threshold_chi2", JsonNumber(u->threshold_chi2)},
          {"misfit_to_noise", JsonNumber(u->misfit_to_noise)},
          {"places", places},
          {"description", u->description}};
}

nlohmann::json BroadbandDiagnosisToJson(const BroadbandDiagnosis& d) {
  return BroadbandDiagnosisToJson(d, BroadbandCampaignFitToJson(d.base));
}

nlohmann::json BroadbandDiagnosisToJson(const BroadbandDiagnosis& d, nlohmann::json base_fit) {
  nlohmann::json out;
  out["kind"] = "broadband";
  out["conclusion"] = d.conclusion;
  out["missing_physics"] = internal::MissingPhysicsJson(d.candidates, d.chosen, d.missing_physics, d.evidence);
  out["unexplained"] = BroadbandUnexplainedToJson(d.unexplained);
  out["curves"] = CurvesToJson(d.curves);
  out["model"] = ModelToJson(d.model);
  out["model_note"] = d.model_note;
  out["fit_before"] = internal::Figures(d.fit_before);
  out["fit_after"] = internal::Figures(d.fit_after);
  out["heldout_every"] = d.heldout_every;
  out["heldout_dof"] = JsonNumber(d.heldout_dof);
  out["base"] = std::move(base_fit);
  out["candidates"] = internal::CandidatesJson(d.candidates, d.chosen);
  out["evidence"] = nlohmann::json::array();
  for (const Evidence& e : d.evidence) out["evidence"].push_back(internal::EvidenceJson(e));
  out["records"] = nlohmann::json::array();
  for (size_t i = 0; i < d.before.size(); ++i) {
    const BroadbandRecordMatch& b = d.before[i];
    const BroadbandRecordMatch& a = i < d.after.size() ? d.after[i] : b;
    out["records"].push_back({{"name", b.name},
                              {"drive_rms_v", JsonNumber(b.drive_rms_v)},
                              {"noise_rms", JsonNumber(b.noise_rms)},
                              {"nrmse_before", JsonNumber(b.nrmse)},
                              {"nrmse_after", JsonNumber(a.nrmse)},
                              {"heldout_nrmse_before", JsonNumber(b.heldout_nrmse)},
                              {"heldout_nrmse_after", JsonNumber(a.heldout_nrmse)},
                              {"chi2_per_sample_before", JsonNumber(b.chi2_per_sample)},
                              {"chi2_per_sample_after", JsonNumber(a.chi2_per_sample)},
                              {"heldout_chi2_per_sample_before", JsonNumber(b.heldout_chi2_per_sample)},
                              {"heldout_chi2_per_sample_after", JsonNumber(a.heldout_chi2_per_sample)}});
  }
  out["warnings"] = d.warnings;
  out["coil_round"] = d.coil_round;
  out["seconds"] = JsonNumber(d.seconds);
  return out;
}

}  // namespace strokelab
