// The diagnosis's parts (diagnose.h), shared by diagnose.cc, effects.cc, diagnose_signatures.cc.
#pragma once

#include <cmath>
#include <functional>
#include <limits>
#include <nlohmann/json_fwd.hpp>
#include <span>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "strokelab/identify/broadband_fit.h"
#include "strokelab/identify/extended_fit.h"
#include "strokelab/identify/campaign.h"
#include "strokelab/diagnose/diagnose.h"
#include "strokelab/diagnose/open_world.h"
#include "strokelab/diagnose/selection.h"

namespace strokelab::internal {

// A figure for the report's sentences: `digits` significant digits, "-" when not finite.
inline std::string FormatFigure(double value, int digits = 3) {
  if (!std::isfinite(value)) return "-";
  std::ostringstream out;
  out.precision(digits);
  out << value;
  return out.str();
}

// What the base fit tells about the campaign's scales, for the effects' start values.
struct EffectContext {
  double stop_distance_m = 1e-3;  // |d| (or the model's length scale without a stop)
  double min_displacement_m = 0;  // smallest x of the base model's orbits over the fit records
  double max_displacement_m = 0;  // largest x of the base model's orbits over the fit records
  double max_velocity_m_per_s = 0;  // largest pi f (x_max - x_min) of those orbits: their peak velocity scale
  double penetration_m = 0;       // typical (median) stop penetration of the contacting orbits
  double max_penetration_m = 0;   // the deepest (0: no contact)
  double min_amplitude_v = 0, max_amplitude_v = 0;  // drive amplitudes of the campaign
  double min_frequency_hz = 0, max_frequency_hz = 0;  // drive frequencies of the campaign
  bool contacts = false;          // some record reaches the stop
  // Whether the base fit identified the stop's d and k_s. The broadband base fit fits them wherever the
  // records show impacts, which its model may never reach (a coil's campaign whose few impacts the model
  // without the coil misses, tuning campaign 8302); then every candidate holds them, and fits nothing
  // that only the stop's contacts tell (c_s, a Hertzian k_s, the back-EMF's part of c_p), but for a
  // second stop's candidates: its impacts tell k_s and c_s, which both stops share.
  bool stop_identified = true;
  // The stiffest (linear) contact the records resolve: one whose natural frequency sqrt(k_s / m_p) / 2pi
  // reaches the Nyquist frequency fs / 2 of the records sampled slowest, k_s = m_p (pi fs)^2. A stiffer
  // stop rings between samples; the records cannot tell it from a rigid one.
  double max_contact_stiffness_n_per_m = std::numeric_limits<double>::infinity();
  // Where the records hit a stop on the positive side that the base model lacks (NaN: none seen): a
  // second stop's start (BuildProblem). The broadband diagnosis's only (UpperImpactOnset).
  double upper_impact_onset_m = std::numeric_limits<double>::quiet_NaN();
};

// The refinement problem of the base parameters (from `start`) extended by `effects`. Effect
// parameters that `start` already carries (a pair built on a fitted single) start from its values.
// `variant` picks one of the effect's start values (0 .. StartVariants - 1) for effects whose
// response is flat at some starts (a stop or a clipping level out of reach).
ExtendedProblem BuildProblem(const ActuatorModel& start, FitModelKind kind, std::span<const Effect> effects,
                             const EffectContext& context, int variant);
int StartVariants(std::span<const Effect> effects, const EffectContext& context);

// Whether the effect acts only in contact with a stop (Hertzian contact, contact damping, second stop).
bool ActsAtTheStop(Effect effect);
// Whether the effect can show in this campaign at all (contact effects need contacts and a stop, and
// those at the stop the base model has, that stop identified).
bool Applicable(Effect effect, FitModelKind kind, const EffectContext& context);

// The effect's own parameters among the fitted ones.
std::vector<FitParameter> EffectParameters(std::span<const Effect> effects, const std::vector<FitParameter>& all);
// Where `problem` (BuildProblem's) holds the coil's c_emf (no impacts at an identified stop), the
// parameters the records then know only together with it (tau_e, k_p, c_p, g and the other mechanical
// force terms) get c_emf's spread over its physical range in their errors and covariance, and a note.
void ChargeHeldBackEmf(std::span<const Effect> effects, const ExtendedProblem& problem, const ActuatorModel& fitted,
                       std::vector<FitParameter>* parameters, std::vector<double>* covariance);

// Evidence from the base model's matches (before) and the records.
Signatures MeasureSignatures(const Campaign& campaign, std::span<const RecordAnalysis> analyses,
                             const std::vector<RecordMatch>& before, const ActuatorModel& base, ResponseKind kind,
                             const FitOptions& options);

// Broadband signatures (broadband_signatures.cc; broadband_diagnose.h step 3) from `fits` of `parts`
// (each with its series: BroadbandFitOptions::keep_series) at `model`.
std::vector<Evidence> BroadbandSignatures(std::span<const Recording> parts, std::span<const BroadbandRecordFit> fits,
                                          const ActuatorModel& model);
// The frequency where a part's residual power stands furthest above its noise level [Hz].
double ResidualPeakFrequencyHz(const Recording& part, const BroadbandRecordFit& fit);

// The JSON pieces both diagnoses write (diagnose_json.cc): parameters by name, error figures, one
// evidence, missing_physics (the chosen candidate's effects, each with its parameters and the evidence
// that points to it) and the candidates' table.
nlohmann::json Parameters(const std::vector<FitParameter>& parameters);
nlohmann::json Figures(const FitFigures& f);
nlohmann::json EvidenceJson(const Evidence& e);
nlohmann::json MissingPhysicsJson(const std::vector<CandidateFit>& candidates, int chosen,
                                  const std::vector<Effect>& missing_physics, const std::vector<Evidence>& evidence);
nlohmann::json CandidatesJson(const std::vector<CandidateFit>& candidates, int chosen);

// Least-squares line y = a + b x over the points: (b, its standard error), NaN for fewer than 3
// (diagnose_signatures.cc).
std::pair<double, double> LineSlope(const std::vector<double>& x, const std::vector<double>& y);

// Whether the options let the effect be a candidate at all: coil_inductance on request only.
inline bool Requested(const EffectInfo& info, const DiagnoseOptions& options) {
  return info.effect != Effect::kCoilInductance || options.coil_inductance;
}

// The report's maps, when the options ask for them: a diagnosis's last two progress stages.
inline int MapStages(const DiagnoseOptions& options) {
  return options.map_frequency_points > 0 && options.map_amplitude_points > 0 ? 2 : 0;
}

}  // namespace strokelab::internal
