// `strokelab fit` on a campaign of broadband records: the output-error fit of broadband_fit.h with its
// start values from the records themselves.
//
//   1. Start of the linear part: paper Eq. 3 (FitLinearFrf) fitted to the H1 estimate of the FRF of
//      the record with the smallest drive (the least touched by the stop), S_yu / S_uu over one Hann
//      window of the whole record, at the frequencies where the drive's power is within 20 dB of its
//      largest; a kinematic response's FRF is first turned into the blocked force's
//      (EquivalentForceFrf). k_p, c_p, g are then fitted to time series with the stop taken away (a
//      linear model: one valley): of every record that shows no impact where another record shows
//      impacts, else (or where the records reject that fit) of the quietest record if it shows none.
//   2. The stop (paper model): free only when a record shows impacts (fourth differences of the response,
//      or of its differences for velocity and displacement, far out of their noise; broadband_fit.h);
//      d starts at the median of the linear model's displacement where the impacts set in below rest
//      (ImpactOnsetsM; the data sheet's where none does), k_s at the data sheet's (paper Table 2).
//   3. k_p, c_p, g, d (and k_s) fitted to every record's time series, m_p held at options.mass_kg. A fit
//      the records reject (chi-square beyond its 1e-3 tail) is tried again from d 3 % and 6 % either
//      side of its start, where no record shows an impact each also from a soft k_s (halfway in log
//      between k_p and the data sheet's); the first accepted, or the least chi-square, is the result.
//      Where no record shows an impact, the stop is fitted only if the records reject the fit without
//      it, and kept only if it lowers the chi-square by more than Akaike's penalty for d and k_s (4).
#pragma once

#include <nlohmann/json_fwd.hpp>

#include "strokelab/identify/broadband_fit.h"
#include "strokelab/identify/campaign.h"
#include "strokelab/identify/fit.h"

namespace strokelab {

struct BroadbandCampaignFit {
  FitModelKind model_kind = FitModelKind::kPaper;
  ResponseKind response = ResponseKind::kForce;
  bool absolute_scale = true;
  FrfFitSummary linear_start;  // step 1
  std::string start_record;    // the record it came from
  size_t linear_records = 0;   // step 1: records the linear part was refined on (0: not refined)
  ActuatorModel linear_model;  // step 1: the linear part the fit starts from (k_p, c_p, g; no stop)
  bool stop_free = false;      // steps 2, 3: the stop is fitted (a record shows impacts, or the fit keeps it)
  double stop_start_m = 0.0;   // step 2: d's start (lower_stop_m, below rest: negative) [m]
  size_t impact_onsets = 0;    // step 2: the impact onsets it is the median of (0: the data sheet's)
  int starts_tried = 0;        // step 3: stop positions tried (more than one where the records reject a fit)
  internal::BroadbandFitResult result;
  std::vector<std::string> warnings;
  double seconds = 0.0;  // wall time of the whole fit, every start included [s]
};

// The H1 estimate S_yu / S_uu of one record over one Hann window of the whole record (the finest
// resolution: a lightly damped resonance is a few tenths of a hertz wide), at the frequencies where the
// drive's power is within 20 dB of its largest (at most ~200 of them, evenly taken): the drive's band.
// Throws InputError naming a record of fewer than 256 samples.
std::vector<FrfSample> BroadbandFrf(const Recording& record);

// The samples of a record's impacts: ImpactSamples (broadband_fit.h) on its response turned into the
// blocked force's shape. An impact is a spike of force and acceleration, a kink of velocity and a corner of
// displacement; the spike shows in the differences of a kinematic response (one for velocity, two for
// displacement), whose own noise level the detection then measures.
std::vector<bool> RecordImpacts(const Recording& record, ResponseKind kind);

// Throws InputError for a campaign without broadband records, bad options, or bad records (named).
BroadbandCampaignFit FitBroadbandCampaign(const Campaign& campaign, const FitOptions& options);

// The parameters of a broadband (or joint) fit as reported: as fitted where the response's sensitivity
// is absolute; where it is only nominal, as the stepped fit reports them (fit.h): k_p, c_p and k_s as
// ratios to m_p (k_p/m_p, c_p/m_p, k_s/m_p, with their errors), g and d marked not identifiable (they
// carry the unknown sensitivity), and d/g with its error from their covariance (independent of it).
std::vector<FitParameter> ReportedBroadbandParameters(const internal::ExtendedFitResult& fit, bool absolute_scale);

// A broadband (or joint) fit's parameters (ReportedBroadbandParameters, by name, FitParameterJson),
// fitted_model (ModelToJson: a model file `sweep --model` takes), converged, rejected, report, chi2,
// residuals, residual_variance, iterations and records (name, noise_rms, offset, hum_amplitude,
// nrmse_initial, nrmse, chi2_per_sample, segments).
nlohmann::json BroadbandFitJson(const internal::BroadbandFitResult& fit, bool absolute_scale);

// kind "broadband", model, response, absolute_scale, parameters (by name, FitParameterJson), converged,
// rejected, report, chi2, residual_variance, residuals, iterations, linear_start, linear_records,
// stop_fitted, stop_start_m, impact_onsets, starts_tried, records, warnings, seconds.
nlohmann::json BroadbandCampaignFitToJson(const BroadbandCampaignFit& fit);

}  // namespace strokelab
