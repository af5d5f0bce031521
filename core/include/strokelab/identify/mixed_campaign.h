// `strokelab fit` on a campaign that holds stepped-sine and broadband records: one joint fit of both.
//
//   1. The stepped-sine records alone, by the stepped-sine fit (fit.h, FitCampaign's steps 1-4): the
//      start, and the records its refinement used.
//   2. k_p, c_p, g (and, where the stepped fit has a stop, d and k_s; c_s with fit_contact_damping)
//      refined on every record at once: the broadband records by their time series (multiple shooting,
//      broadband_fit.h) and the stepped records by their harmonics over their standard errors, in one
//      nonlinear least-squares problem sharing the model's parameters (BroadbandFitOptions::stepped).
//      m_p is held at options.mass_kg. Standard errors are from the joint Jacobian at the solution.
#pragma once

#include <nlohmann/json_fwd.hpp>

#include "strokelab/identify/broadband_fit.h"
#include "strokelab/identify/campaign.h"
#include "strokelab/identify/fit.h"

namespace strokelab {

// Which fit a campaign takes, by its records: stepped sines only (fit.h, FitCampaign; also a campaign
// without records, which it refuses), broadband only (broadband_campaign.h) or both (FitMixedCampaign).
// `strokelab fit` and the service's fit job both ask.
enum class CampaignFitKind { kSteppedSine, kBroadband, kMixed };
CampaignFitKind FitKindOf(const Campaign& campaign);
// The fit `options` ask of the campaign: as above, except without the refinement (options.refine false,
// "stop at the staged estimates"), which only the stepped-sine fit has: a mixed campaign then takes the
// stepped-sine fit of its stepped sines (FitCampaign warns of each broadband record left out), and a
// campaign of broadband records only is refused (InputError, field "refine").
CampaignFitKind FitKindOf(const Campaign& campaign, const FitOptions& options);

struct MixedCampaignFit {
  FitModelKind model_kind = FitModelKind::kPaper;
  ResponseKind response = ResponseKind::kForce;
  bool absolute_scale = true;
  FitResult stepped;                    // step 1: the stepped records alone
  size_t stepped_used = 0;              // the stepped records the joint fit takes (step 1's refinement's)
  internal::BroadbandFitResult result;  // step 2: the joint fit
  std::vector<std::string> warnings;
  double seconds = 0.0;  // wall time of both steps [s]
};

// Throws InputError for a campaign without records of both kinds, bad options or bad records (named),
// as FitCampaign and FitBroadband.
MixedCampaignFit FitMixedCampaign(const Campaign& campaign, const FitOptions& options);

// kind "mixed", model, response, absolute_scale, parameters (the joint fit's, by name), stepped_start
// (the stepped fit's parameters, by name), converged, rejected, report, chi2, residual_variance,
// residuals, iterations, records (the broadband records, as the broadband fit's JSON), stepped_records
// (name, chi2, residuals), warnings, seconds.
nlohmann::json MixedCampaignFitToJson(const MixedCampaignFit& fit);

}  // namespace strokelab
