// The joint fit of a campaign of stepped-sine and broadband records (identify/mixed_campaign.h).
#include "strokelab/identify/mixed_campaign.h"

#include <algorithm>
#include <chrono>
#include <nlohmann/json.hpp>

#include "strokelab/base/errors.h"
#include "strokelab/base/json_number.h"
#include "strokelab/identify/broadband_campaign.h"

namespace strokelab {

namespace {

// The joint fit's free parameters, started at the stepped fit's model (its ranges as the stepped
// refinement's: a factor 3, and 30 for the contact's).
std::vector<internal::FreeParameter> JointParameters(const ActuatorModel& m, bool contact_damping) {
  using internal::LogParameter;
  std::vector<internal::FreeParameter> out = {
      LogParameter("k_p", "N/m", &ActuatorModel::stiffness_n_per_m, m.stiffness_n_per_m, 3.0),
      LogParameter("c_p", "N s/m", &ActuatorModel::damping_n_s_per_m, m.damping_n_s_per_m, 3.0),
      LogParameter("g", "N/V", &ActuatorModel::gain_n_per_v, m.gain_n_per_v, 3.0)};
  if (!m.HasLowerStop() && !m.HasUpperStop()) return out;
  double ActuatorModel::*stop = m.HasLowerStop() ? &ActuatorModel::lower_stop_m : &ActuatorModel::upper_stop_m;
  out.push_back(LogParameter("d", "m", stop, m.*stop, 3.0));
  out.push_back(LogParameter("k_s", "N/m", &ActuatorModel::contact_stiffness, m.contact_stiffness, 30.0));
  if (contact_damping && m.contact_damping_n_s_per_m > 0)
    out.push_back(LogParameter("c_s", "N s/m", &ActuatorModel::contact_damping_n_s_per_m,
                               m.contact_damping_n_s_per_m, 30.0));
  return out;
}

}  // namespace

CampaignFitKind FitKindOf(const Campaign& campaign) {
  const size_t broadband = static_cast<size_t>(
      std::count_if(campaign.records.begin(), campaign.records.end(), [](const Recording& r) { return r.broadband; }));
  if (broadband == 0) return CampaignFitKind::kSteppedSine;
  return broadband == campaign.records.size() ? CampaignFitKind::kBroadband : CampaignFitKind::kMixed;
}

CampaignFitKind FitKindOf(const Campaign& campaign, const FitOptions& options) {
  const CampaignFitKind kind = FitKindOf(campaign);
  if (options.refine) return kind;
  if (kind == CampaignFitKind::kBroadband)
    throw InputError("refine", "a campaign of broadband records only has no staged estimates to stop at: its fit by "
                               "the time series is the refinement (fit it without turning the refinement off)");
  return CampaignFitKind::kSteppedSine;
}

MixedCampaignFit FitMixedCampaign(const Campaign& campaign, const FitOptions& options) {
  const auto clock_start = std::chrono::steady_clock::now();
  Validate(options);
  MixedCampaignFit out;
  out.model_kind = options.model;
  out.response = campaign.response;
  out.absolute_scale = campaign.absolute_scale;
  Campaign stepped = campaign;
  std::erase_if(stepped.records, [](const Recording& r) { return r.broadband; });
  std::vector<const Recording*> broadband;
  for (const Recording& r : campaign.records)
    if (r.broadband) broadband.push_back(&r);
  if (stepped.records.empty() || broadband.empty())
    throw InputError("records", "a joint fit needs stepped-sine and broadband records (this campaign holds " +
                                    std::to_string(stepped.records.size()) + " and " +
                                    std::to_string(broadband.size()) + ")");

  // 1. The stepped records alone.
  const std::vector<RecordAnalysis> analyses = AnalyseCampaign(stepped, options, &out.warnings);
  out.stepped = FitAnalysed(analyses, campaign.response, campaign.absolute_scale, options);
  std::vector<const RecordAnalysis*> used;
  for (size_t i = 0; i < analyses.size(); ++i)
    if (out.stepped.records[i].used_refinement) used.push_back(&analyses[i]);
  out.stepped_used = used.size();
  if (!out.stepped.refinement.converged)
    out.warnings.push_back("the stepped records' own fit did not converge: the joint fit starts from where it ended");

  // 2. The joint fit from there.
  internal::ExtendedProblem problem;
  problem.base = out.stepped.model;
  problem.parameters = JointParameters(out.stepped.model, options.fit_contact_damping);
  internal::BroadbandFitOptions fit_options;
  fit_options.max_iterations = options.max_iterations;
  fit_options.max_seconds = std::max(1.0, options.max_refinement_seconds - out.stepped.seconds);
  fit_options.stepped = used;
  fit_options.stepped_orders = options.harmonic_orders;
  out.result = internal::FitBroadband(broadband, campaign.response, problem, fit_options);
  if (!campaign.absolute_scale)
    out.warnings.push_back("the sensitivity is nominal: g and d carry its unknown factor (only ratios are identifiable)");
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return out;
}

nlohmann::json MixedCampaignFitToJson(const MixedCampaignFit& fit) {
  using nlohmann::json;
  json stepped_start = json::object();
  for (const FitParameter& p : fit.stepped.parameters) stepped_start[p.name] = FitParameterJson(p);
  json stepped_records = json::array();
  for (const internal::SteppedRecordFit& x : fit.result.stepped)
    stepped_records.push_back({{"name", x.name}, {"chi2", JsonNumber(x.chi2)}, {"residuals", x.residuals}});
  json out = BroadbandFitJson(fit.result, fit.absolute_scale);
  out.update(json{{"kind", "mixed"},
                  {"model", ToString(fit.model_kind)},
                  {"response", ToString(fit.response)},
                  {"absolute_scale", fit.absolute_scale},
                  {"stepped_start", stepped_start},
                  {"stepped_records", stepped_records},
                  {"warnings", fit.warnings},
                  {"seconds", JsonNumber(fit.seconds)}});
  return out;
}

}  // namespace strokelab
