// A broadband diagnosis and its maps as plain data and back (diagnosis_data.h).
#include <cmath>

#include "data_json.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/json_number.h"
#include "strokelab/model/model_json.h"
#include "strokelab/report/diagnosis_data.h"

namespace strokelab::report {
namespace {

using namespace data_json;

constexpr size_t kMaxBroadbandBaseFitBytes = 16 << 20;  // the base fit's document, as a fit row's limit (task_rows.h)

json BroadbandMatchesOut(const std::vector<BroadbandRecordMatch>& matches) {
  json out = json::array();
  for (const BroadbandRecordMatch& m : matches)
    out.push_back({{"name", m.name}, {"drive_rms_v", JsonNumber(m.drive_rms_v)}, {"noise_rms", JsonNumber(m.noise_rms)},
                   {"nrmse", JsonNumber(m.nrmse)}, {"heldout_nrmse", JsonNumber(m.heldout_nrmse)},
                   {"chi2_per_sample", JsonNumber(m.chi2_per_sample)},
                   {"heldout_chi2_per_sample", JsonNumber(m.heldout_chi2_per_sample)}});
  return out;
}

std::vector<BroadbandRecordMatch> BroadbandMatchesIn(const json& object, const char* key, const std::string& at) {
  return ItemsIn(object, key, at, [](const json& v, const std::string& q) {
    return BroadbandRecordMatch{Text(v, "name", q),          Number(v, "drive_rms_v", q),
                                Number(v, "noise_rms", q),     Number(v, "nrmse", q),
                                Number(v, "heldout_nrmse", q), Number(v, "chi2_per_sample", q),
                                Number(v, "heldout_chi2_per_sample", q)};
  });
}

std::optional<BroadbandUnexplained> BroadbandUnexplainedIn(const json& object, const char* key, const std::string& at) {
  const json& v = Member(object, key, at);
  if (v.is_null()) return std::nullopt;
  const std::string q = at + "/" + key;
  BroadbandUnexplained u;
  u.parts = Text(v, "parts", q);
  if (u.parts != "held-out" && u.parts != "fit") throw InputError(q + "/parts", "must be \"held-out\" or \"fit\"");
  u.chi2 = Number(v, "chi2", q);
  u.dof = Number(v, "dof", q);
  u.threshold_chi2 = Number(v, "threshold_chi2", q);
  u.misfit_to_noise = Number(v, "misfit_to_noise", q);
  u.places = ItemsIn(v, "places", q, [](const json& w, const std::string& r) {
    return BroadbandUnexplained::Place{Text(w, "record", r), Number(w, "chi2_per_sample", r),
                                       Number(w, "peak_frequency_hz", r), Number(w, "near_contact_share", r),
                                       Number(w, "contact_time_share", r)};
  });
  u.description = Text(v, "description", q);
  return u;
}

// The base fit's document (BroadbandCampaignFitToJson), served as the result's "base" only as JSON: an
// object with its "parameters" object, within kMaxBroadbandBaseFitBytes (text parsed from JSON holds no
// infinities).
json BroadbandBaseFitIn(const json& object, const std::string& at) {
  const json& fit = Member(object, "fit", at);
  const std::string q = at + "/fit";
  if (!fit.is_object()) throw InputError(q, "must be an object");
  if (!fit.contains("parameters") || !fit["parameters"].is_object()) throw InputError(q + "/parameters", "must be an object");
  if (fit.dump().size() > kMaxBroadbandBaseFitBytes) throw InputError(q, "is larger than 16 MiB");
  return fit;
}

}  // namespace

json BroadbandDiagnosisDataToJson(const BroadbandDiagnosis& d, const DiagnosisMaps& maps) {
  const BroadbandCampaignFit& b = d.base;
  json base = {{"model_kind", ToString(b.model_kind)},
               {"response", ToString(b.response)},
               {"absolute_scale", b.absolute_scale},
               {"converged", b.result.fit.converged},
               {"rejected", b.result.rejected},
               {"parameters", ParametersOut(b.result.fit.parameters)},
               {"fit", BroadbandCampaignFitToJson(b)}};
  json diagnosis = {{"base", base},
                    {"heldout_every", d.heldout_every},
                    {"before", BroadbandMatchesOut(d.before)},
                    {"after", BroadbandMatchesOut(d.after)},
                    {"fit_before", FiguresOut(d.fit_before)},
                    {"fit_after", FiguresOut(d.fit_after)},
                    {"heldout_dof", JsonNumber(d.heldout_dof)},
                    {"evidence", EvidenceOut(d.evidence)},
                    {"candidates", CandidatesOut(d.candidates)},
                    {"missing_physics", EffectsOut(d.missing_physics)},
                    {"chosen", d.chosen},
                    {"model", ModelToJson(d.model)},
                    {"model_note", d.model_note},
                    {"unexplained", BroadbandUnexplainedToJson(d.unexplained)},
                    {"curves", CurvesToJson(d.curves)},
                    {"conclusion", d.conclusion},
                    {"warnings", d.warnings},
                    {"seconds", JsonNumber(d.seconds)}};
  return {{"diagnosis", diagnosis}, {"maps", MapsOut(maps)}};
}

BroadbandDiagnosisData BroadbandDiagnosisDataFromJson(const json& in) {
  BroadbandDiagnosisData out;
  BroadbandDiagnosis& d = out.diagnosis;
  const json& dj = Member(in, "diagnosis", "");
  const std::string at = "/diagnosis";

  const json& b = Member(dj, "base", at);
  const std::string bat = at + "/base";
  d.base.model_kind = ModelKindIn(b, bat);
  d.base.response = ResponseIn(b, bat);
  d.base.absolute_scale = Flag(b, "absolute_scale", bat);
  d.base.result.fit.converged = Flag(b, "converged", bat);
  d.base.result.rejected = Flag(b, "rejected", bat);
  d.base.result.fit.parameters = ParametersIn(b, "parameters", bat);
  out.base_fit = BroadbandBaseFitIn(b, bat);

  d.heldout_every = static_cast<int>(Integer(dj, "heldout_every", at, 2, 1 << 20));
  d.before = BroadbandMatchesIn(dj, "before", at);
  d.after = BroadbandMatchesIn(dj, "after", at);
  if (!d.after.empty() && d.after.size() != d.before.size())
    throw InputError(at + "/after", "must match /diagnosis/before record for record");
  d.fit_before = FiguresIn(dj, "fit_before", at);
  d.fit_after = FiguresIn(dj, "fit_after", at);
  d.heldout_dof = Number(dj, "heldout_dof", at);
  d.evidence = EvidenceIn(dj, "evidence", at);
  d.candidates = CandidatesIn(dj, "candidates", at);
  d.missing_physics = EffectsIn(dj, "missing_physics", at);
  d.chosen = ChosenIn(dj, at, d.candidates.size(), !d.missing_physics.empty());
  d.model = ModelIn(dj, "model", at);
  d.model_note = Text(dj, "model_note", at);
  d.unexplained = BroadbandUnexplainedIn(dj, "unexplained", at);
  d.curves = CurvesIn(dj, "curves", at);
  d.conclusion = Text(dj, "conclusion", at);
  d.warnings = Texts(dj, "warnings", at);
  d.seconds = Number(dj, "seconds", at);
  out.maps = MapsIn(in);
  return out;
}

}  // namespace strokelab::report
