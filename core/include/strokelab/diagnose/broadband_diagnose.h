// Diagnosis of a broadband campaign (strokelab diagnose on noise, multisine or sweep records): the
// stepped-sine diagnosis's choice among the same effects (diagnose.h steps 4-6) on fits by the records'
// time series (identify/broadband_fit.h) instead of their harmonics.
//
//   1. Split: the first or the last 1 / heldout_every of every record is held out of all fits: the end
//      that holds some of the record's impacts but not all (of two such, the one whose share of them is
//      nearer its share of the samples), else the last (the first where the last holds all of them). A
//      multisine's period is its record, so its held-out part carries the same lines at fresh noise; a
//      noise record's held-out part is fresh drive as well. A multisine's impacts gather at its
//      envelope's peaks, which the last part alone can miss: a contact effect would then not be seen
//      where it is judged.
//   2. Base fit (identify/broadband_campaign.h) on the records' fit parts; then the base model
//      evaluated on every part, with only each part's segment starts, offset and hum fitted
//      (FitBroadband with no free parameter; held-out parts as in step 4): the residuals the signatures
//      read, and the base's figures. From here on every fit and evaluation weights a part by its
//      record's noise level, estimated once from the whole record: four times the samples of a
//      held-out part make the open-world test's limit tighter, and every chi-square shares one scale.
//   3. Signatures (broadband_signatures.cc), needing no harmonics: the residual's chi-square per sample
//      where the base model's motion is far out in displacement, slow, fast, or near a contact, against
//      the rest of the record; the residual's coherence with the drive; its spectrum's excess over the
//      noise floor.
//   4. Candidates: the base model extended by each effect (as diagnose.h), every parameter free, fitted
//      by the time series of the fit parts from the base fit's segment starts, offsets and hum (a
//      warm start: broadband_fit.h), in up to 4 times options.fit.max_iterations. A second stop starts
//      at the median of the base model's displacement at the onsets of the records' impacts where it is
//      positive (up to an impact the model follows the records, so it stands at the stop there). A candidate's held-out chi-square is its evaluation on the held-out
//      parts (their starts, offsets and hum fitted, the model held), from the motion continued from the
//      fit parts (the state the model reaches at the end of each record's fit part) and from a fresh
//      start, the lower of the two; the base model's likewise.
//   5. Choice: as diagnose.h step 5, the same rules and numbers (diagnose/selection.h), the look-ahead
//      where broadband_fit.h's test of the fit parts rejects the chosen model, and the coil's round:
//      where step 6 finds the misfit unexplained and coil_inductance was not a candidate, steps 5 and
//      6 run again with it (DiagnoseOptions::coil_when_unexplained). The coil's pole adds
//      its force as a state of every segment, started where it settles. The back-EMF's part of c_p is
//      fitted only where the base model's stop meets the records' impacts (effects.cc); clear of them
//      it is held at 0.
//   6. Open world: the chosen model's held-out chi-square against its 1e-3 upper tail under noise alone,
//      the noise levels' own spread included (broadband_fit.h's rejection test). Beyond it, the misfit is
//      "unexplained", with the parts where it lives and the residual's dominant frequency there. Its
//      effects must then stand with their standard errors scaled by the misfit's ratio to noise, as in
//      the stepped diagnosis (selection.h SignificantUnderMisfit). A named
//      model must also explain the parts it was fitted to by the same test: where it does not, it is
//      named only if it removed more of the fit parts' excess than it leaves (else, as for the held-out
//      parts, "unexplained", with that candidate's share). Records with hard impacts can hold a fit in a
//      valley away from its optimum, where a second effect "explains" part of what the fit left.
#pragma once

#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "strokelab/diagnose/diagnose.h"
#include "strokelab/identify/broadband_campaign.h"

namespace strokelab {

// How one model matches one record: its fit part and its held-out part.
struct BroadbandRecordMatch {
  std::string name;
  double drive_rms_v = 0.0;
  double noise_rms = 0.0;  // the record's white-noise level [response units] (BroadbandParts::noise_rms)
  double nrmse = 0.0, heldout_nrmse = 0.0;  // rms(residual) / rms(response - offset)
  double chi2_per_sample = 0.0, heldout_chi2_per_sample = 0.0;  // 1 is noise
};

struct BroadbandUnexplained {
  // The parts where the misfit is beyond noise: "held-out", or "fit" where the held-out parts pass but
  // the model leaves the parts it was fitted to beyond noise (a fit stopped in a valley of the misfit
  // away from its optimum, as records with hard impacts can make it, or physics the model lacks).
  std::string parts = "held-out";
  double chi2 = 0.0;            // the diagnosed model's chi-square on those parts
  double dof = 0.0;             // what noise alone gives on average
  double threshold_chi2 = 0.0;  // flagged beyond: its 1e-3 upper tail
  double misfit_to_noise = 0.0; // sqrt(chi2 / dof): misfit RMS over noise's (1: noise)
  // Parts whose own chi-square per sample is beyond noise (Bonferroni over the parts at the same
  // 1e-3), worst first.
  struct Place {
    std::string record;
    double chi2_per_sample = 0.0;
    double peak_frequency_hz = 0.0;  // where the residual's spectrum stands furthest above the noise floor
    // Of the residual's excess chi-square, the share within 2 ms of a contact: the model's, or an impact
    // the record shows (where the model misses one, e.g. at a stop it lacks).
    double near_contact_share = 0.0;
    double contact_time_share = 0.0; // of the samples there (NaN: no contact, the model's or the record's)
  };
  std::vector<Place> places;
  std::string description;
};

struct BroadbandDiagnosis {
  BroadbandCampaignFit base;  // on the fit parts
  int heldout_every = 4;      // the last 1 / heldout_every of each record is held out
  std::vector<BroadbandRecordMatch> before, after;  // the base and the diagnosed model on every record
  FitFigures fit_before, fit_after;
  // What noise alone gives the held-out chi-square on average: the held-out misfit beyond noise is
  // heldout_chi2 - heldout_dof (the normalised RMS error of a noisy record is mostly its noise's).
  double heldout_dof = 0.0;
  std::vector<Evidence> evidence;        // step 3, on the base model's residuals
  std::vector<CandidateFit> candidates;  // every candidate tried, singles best held-out gain first
  std::vector<Effect> missing_physics;   // named effects, best first (empty: nothing missing)
  int chosen = -1;                       // index into candidates (-1: nothing named)
  ActuatorModel model;                   // the diagnosed model (as Diagnosis::model)
  std::string model_note;
  std::optional<BroadbandUnexplained> unexplained;
  std::vector<EffectCurve> curves;
  std::string conclusion;
  std::vector<std::string> warnings;
  // Whether the selection ran once more with coil_inductance (DiagnoseOptions::coil_when_unexplained).
  bool coil_round = false;
  int progress_stages = 0;  // as Diagnosis::progress_stages
  double seconds = 0.0;
};

// Step 1's parts: each broadband record's first part (fit) and its last 1 / heldout_every (held out), as
// records of their own ("NAME (fit part)", "NAME (held-out part)"), in the campaign's order; which end is
// held out as step 1 says, by the record's impacts (RecordImpacts). Stepped-sine records are left out (a warning each, when
// `warnings` is given). Throws InputError naming a record too short to hold out 256 samples, or
// "records" when none is broadband.
struct BroadbandParts {
  std::vector<std::string> names;  // the records'
  std::vector<Recording> fit, heldout;
  std::vector<bool> heldout_first;  // the record's first part is held out
  // The record's white-noise level [response units], from the whole record: both parts are weighted
  // by it (internal::ResponseNoiseRms).
  std::vector<double> noise_rms;
};
BroadbandParts SplitBroadbandRecords(const Campaign& campaign, int heldout_every,
                                     std::vector<std::string>* warnings = nullptr);

namespace internal {
// Of a part's residual excess chi-square (`fit` with its series: BroadbandFitOptions::keep_series), the
// share within 2 ms of a contact, the model's or an impact the part's response of `kind` shows
// (RecordImpacts: one the model misses is where a stop it lacks lives), and the share of the samples
// there (both NaN where there is neither): BroadbandUnexplained::Place's figures.
std::pair<double, double> NearContactShares(const Recording& part, ResponseKind kind, const BroadbandRecordFit& fit,
                                            const ActuatorModel& model);
}  // namespace internal

// Throws InputError for bad options, a campaign without broadband records, or records too short to
// hold a part out (named).
BroadbandDiagnosis DiagnoseBroadbandCampaign(const Campaign& campaign, const DiagnoseOptions& options = {});

// kind "broadband", missing_physics (effect, parameters), model, model_note, fit_before, fit_after, heldout_dof,
// base (BroadbandCampaignFitToJson), evidence, candidates, records (before and after), unexplained
// (null or its figures), curves, conclusion, warnings, seconds.
nlohmann::json BroadbandDiagnosisToJson(const BroadbandDiagnosis& diagnosis);
// Its "unexplained": null, or the figures, the places and the description.
nlohmann::json BroadbandUnexplainedToJson(const std::optional<BroadbandUnexplained>& unexplained);
// The same with `base_fit` as its "base": the document of a base fit that came as data
// (report/diagnosis_data.h), where the diagnosis holds only part of its base fit.
nlohmann::json BroadbandDiagnosisToJson(const BroadbandDiagnosis& diagnosis, nlohmann::json base_fit);

}  // namespace strokelab
