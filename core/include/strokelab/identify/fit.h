// Fitting a model to a measurement campaign: the paper's procedure (section 4) made robust.
//
//   1. Per record (AnalyseRecord): the true drive from the voltage channel (EstimateDrive: frequency
//      refined from the nominal one, amplitude, phase), offsets and mains hum removed, the response's
//      harmonics up to order N by least squares over whole periods (of the response's, where it
//      repeats only every 2 or 3 drive periods: its subharmonics fitted beside), the first-order FRF
//      C_1(response) / C_1(v_in) (paper section 3), the noise level (from differences of the response
//      a whole number of periods apart, blind to the impacts), impact spikes (DetectSpikes) and
//      harmonic distortion.
//   2. Records clear of the stop (no spikes, small distortion): paper Eq. 3 fitted to their FRFs
//      (FitClearRecords -> FitLinearFrf), m_p held at the data-sheet value (paper section 4). FRFs of
//      acceleration, velocity or displacement are first turned into the equivalent blocked-force FRF
//      (EquivalentForceFrf).
//   3. Contact (EstimateContact): contact times of the spikes of contacting records give k_s by the
//      damped relation (paper Eq. 4-5, damped form: ContactStiffnessDamped), averaged, with its
//      spread; the stop position |d| is bracketed by the linear model's displacement amplitudes of the
//      records without spikes (below |d|) and of those with spikes (above, unless bistable).
//   4. Joint refinement (RefineParameters): Levenberg-Marquardt (Ceres) on (ln k_p, ln c_p, ln|g|,
//      ln|d|, ln k_s [, ln c_s]) against every record's complex harmonics 1..N. The model's harmonics
//      come from its periodic steady state at the record's estimated drive (Shoot on the PeriodMap,
//      warm-started from the orbit of the previous iterate; OrbitHarmonics in closed form), plus a
//      sampling correction: the orbit sampled on the record's own grid and analysed as the record was,
//      less its closed-form harmonics (the impacts' harmonics far above N alias and leak into C_1..C_N
//      by about half a standard error, which would bias k_s and d by several). Residuals are harmonic
//      differences over their standard error (RecordAnalysis::harmonic_se); Jacobian by central
//      differences; parameters bounded to a factor 3 (k_s, c_s: 30) around the staged estimates;
//      standard errors from (J^T J)^-1 scaled by the residual variance s^2 = SSR / (M - P) (M real
//      residuals, P parameters), propagated to the parameters by the delta method. On synthetic
//      campaigns (tests/core/fit_test.cc) the estimates scatter about the truth by 0.97-1.05 of these
//      standard errors.
//
// Identifiability. m_p never is (only ratios to it are): it is held at the data sheet's 0.032 kg, so
// k_p, c_p, k_s, c_s are "given m_p". With a force response g is absolute; with a kinematic response
// only g / m_p is. When the campaign's response scale is only nominal (absolute_scale false) the
// unknown sensitivity s multiplies g and d alike (the measured response is s times the true one):
// only k_p/m_p, c_p/m_p, k_s/m_p, c_s/m_p and d/g are identifiable, and the result says so.
// The `linear` model is a single-degree-of-freedom oscillator without a stop, reported in ratios
// (k_p/m_p, c_p/m_p) and the gain that the response's kind and scale allow.
//
// Reference: "Nonlinear vibrations of a stroke-saturated inertial actuator" (the paper in
// shared/paper/), Eq. 2-6 and section 4; conventions of shared/docs/paper-notes.md.
#pragma once

#include <complex>
#include <cstddef>
#include <limits>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "strokelab/base/errors.h"  // FieldError
#include "strokelab/identify/campaign.h"
#include "strokelab/identify/frf_fit.h"
#include "strokelab/model/model.h"
#include "strokelab/signal/signal.h"

namespace strokelab {

enum class FitModelKind {
  kPaper,   // paper Eq. 2: linear suspension, one linear end stop (k_s, optional c_s)
  kLinear,  // the same oscillator without a stop
};
FitModelKind ParseFitModel(std::string_view text);  // "paper" | "linear"; throws InputError("model")
const char* ToString(FitModelKind kind);

struct FitOptions {
  FitModelKind model = FitModelKind::kPaper;
  double mass_kg = 0.032;    // m_p [kg], data sheet (paper section 4); held fixed
  int harmonic_orders = 10;  // N: response harmonics analysed and fitted, >= 1
  // A record is clear of the stop when DetectSpikes finds no spike and its harmonic distortion
  // sqrt(sum_{h=2..N} |C_h|^2 - noise share) / |C_1| is below this (dimensionless). Loose enough
  // for a weakly nonlinear suspension (paper section 3.2), tight enough for any contact.
  double max_clear_distortion = 0.05;
  SpikeOptions spikes;  // impact spike detection (paper section 4.1)
  // Mains hum removed before the analysis: 0 removes both 50 and 60 Hz (each with two overtones,
  // unless a drive harmonic masks it), > 0 that frequency [Hz], < 0 leaves hum alone.
  double mains_frequency_hz = 0.0;
  bool fit_contact_damping = false;       // c_s in the refinement (else held at 0, paper Table 2)
  bool refine = true;                     // step 4 (false: stop at the staged estimates of steps 2-3)
  // Step 4 ends with solves that take the sampling correction's slopes (linearised_correction.h).
  // The diagnosis turns them off for its base fit, which must be the same estimator as its candidates'
  // extended fits, and those hold the correction frozen in each solve.
  bool sampling_slopes = true;
  int max_iterations = 50;                // Ceres iterations of the refinement, >= 1
  double max_refinement_seconds = 120.0;  // wall time of the refinement [s]; then reported as not converged
  // Nothing, or the first wrong field ("harmonic_orders", "spikes.threshold_sigmas", ...) and why.
  std::optional<FieldError> IsValid() const;
};

// One option of the fit (Options = FitOptions) or of the diagnosis (DiagnoseOptions) under each of
// its names, as ParameterInfo is for the model: the field as IsValid's FieldError names it, its key
// under a job's "options" (schema/job.schema.json) and its flag in `strokelab fit` and `strokelab
// diagnose`. Jobs read their options and point at their errors with it, the CLI parses its flags
// and names the flag of a wrong field with it. The model kind is not in it: a job gives it at the
// top ("/model"), the CLI as --model, both read by ParseFitModel.
template <class Options>
struct OptionInfo {
  const char* field;     // "harmonic_orders"
  const char* job_name;  // "harmonics"
  const char* flag;      // "--harmonics" (a switch for a bool); nullptr: no flag
  std::variant<int Options::*, double Options::*, bool Options::*> member;
  bool flag_clears = false;  // the switch sets the bool false (--no-refine); else true
};
// The options a job or the CLI can set, in the order the CLI reads its flags.
const std::vector<OptionInfo<FitOptions>>& FitOptionFields();

// The entry of `table` for an IsValid field, or nullptr.
template <class Options>
const OptionInfo<Options>* FindOption(const std::vector<OptionInfo<Options>>& table, std::string_view field) {
  for (const OptionInfo<Options>& info : table)
    if (field == info.field) return &info;
  return nullptr;
}

// ---- Step 1: one record ------------------------------------------------------------------------

// The drive as the voltage channel shows it: v(t) = offset_v + amplitude_v sin(2 pi f t + phase_rad),
// t = n / fs from the record's first sample.
struct DriveEstimate {
  double frequency_hz = 0.0;  // f [Hz], refined from the nominal value
  double amplitude_v = 0.0;   // V [V]
  double phase_rad = 0.0;     // phi [rad], in (-pi, pi]
  double offset_v = 0.0;      // DC of the voltage channel [V] (a measurement offset, not a drive)
  double noise_rms_v = 0.0;   // RMS of the voltage's residual about the fitted sine [V]
  int newton_steps = 0;       // phase-drift Newton steps taken
};
// The nominal frequency (manifest) is refined in two stages: the largest |C_1(f)| (least squares
// over the record) on a grid of spacing 1/(4T) within +-max(2/T, 1 %) of it, T the record length;
// then Newton steps on the phase drift: C_1 over four quarters of the record at the current f have
// phases phi_k = phi + 2 pi (f_true - f) t_k, so the least-squares slope over the quarter midpoints
// t_k gives f_true - f; stops when |df| < 1e-10 f or after 8 steps; last, the least-squares
// frequency (minimum residual of the sine fit over the record) by a parabola through f and
// f +- 0.001 / T. Throws InputError naming
// "voltage" (too short, constant, non-finite) or "nominal_frequency_hz".
DriveEstimate EstimateDrive(std::span<const double> voltage, double sample_rate_hz, double nominal_frequency_hz);

// Mains hum is fitted as its fundamental and this many orders in all (50, 100, 150 Hz).
constexpr int kHumOrders = 3;

// What one stepped-sine record shows. Response units are those of the campaign's ResponseKind.
struct RecordAnalysis {
  std::string name;
  double nominal_frequency_hz = 0.0, nominal_amplitude_v = 0.0;  // manifest [Hz], [V]
  double sample_rate_hz = 0.0;                                   // fs [Hz]
  DriveEstimate drive;
  SampleWindow window;           // whole periods of the estimated drive (and of the response), at the end
  // Drive periods after which the response repeats: 1, or 2 or 3 where its subharmonics stand out
  // of the noise (alternating impacts); the window then spans whole periods of the response, whose
  // harmonics are fitted beside the drive's (fit_record.cc, ResponsePeriods).
  int response_periods = 1;
  double response_offset = 0.0;  // DC of the response (removed)
  // Mains hum (50 and 60 Hz, kHumOrders orders each, unless the drive's fundamental masks them) is fitted and
  // removed; the stronger fundamental found [Hz] and its amplitude [response units] (0: none fitted).
  double hum_frequency_hz = 0.0;
  double hum_amplitude = 0.0;
  // C_h, h = 1..N, of the response relative to the drive phase: C_h(record) e^{-j h phi}, so that a
  // model driven by V sin(w t) (phase 0) has the same harmonics.
  std::vector<std::complex<double>> harmonics;
  // False for harmonics h (index h - 1) within half a frequency bin (1/T) of a mains hum overtone
  // when hum is removed: hum and drive harmonic cannot be told apart there, so those harmonics are
  // left out of every residual (with a 50 Hz mains, harmonic 10 of a 5 Hz record).
  std::vector<bool> usable;
  std::complex<double> frf;  // C_1(response) / C_1(v_in) [response units / V]
  // White-noise level of the response [response units]: 1.4826 MAD of y[n + L] - y[n] over sqrt(2),
  // L a lag of whole periods (the periodic part cancels, the few samples near impacts do not count;
  // the smallest over the lags, so that a period-2 response is not taken for noise).
  double noise_rms = 0.0;
  double harmonic_se = 0.0;  // standard error of Re C_h and of Im C_h: noise_rms sqrt(2 / n)
  double distortion = 0.0;   // dimensionless, see FitOptions::max_clear_distortion
  // Impact spikes of the response (force, acceleration) or of its derivatives (velocity,
  // displacement); spikes below a quarter of the record's largest are dropped as baseline artefacts.
  std::vector<Spike> spikes;
  bool clear = false;  // no spike and distortion below the limit
  size_t samples() const { return window.size(); }
};
// Throws InputError naming the record (channels of different lengths, non-finite samples, a record
// shorter than two drive periods, broadband records).
RecordAnalysis AnalyseRecord(const Recording& record, ResponseKind kind, const FitOptions& options);

// ---- Step 2: the linear parameters -------------------------------------------------------------

// The blocked-force FRF [N/V] equivalent to a measured FRF of `kind` at f [Hz]: force H;
// acceleration m_p H; velocity m_p j w H; displacement -m_p w^2 H (f = m_p x'', paper-notes).
std::complex<double> EquivalentForceFrf(std::complex<double> frf, ResponseKind kind, double frequency_hz,
                                        double mass_kg);

struct LinearStage {
  FrfFitSummary summary;        // paper Eq. 3 with m_p = options.mass_kg
  std::vector<size_t> records;  // indices (into the analyses) of the records used
  double distortion_limit = 0;  // the records' distortion limit: FitOptions' unless too few are clear
};
// Paper Eq. 3 fitted to the equivalent force FRFs of the clear records. With fewer than 3 of them,
// the spike-free records under the least distortion limit that admits 3 (a suspension nonlinearity
// can distort every record off the stop): a start that step 4 refines. Throws InputError("records")
// when fewer than 3 records are free of spikes.
LinearStage FitClearRecords(std::span<const RecordAnalysis> analyses, ResponseKind kind, const FitOptions& options);

// ---- Step 3: contact ---------------------------------------------------------------------------

struct ContactEstimate {
  std::vector<size_t> records;    // indices of the records not clear of the stop
  size_t spikes = 0;              // spikes whose contact time gave a k_s
  double contact_time_s = 0.0;    // mean over the spikes [s] (NaN: none)
  double contact_time_rsd = 0.0;  // paper Eq. 6 with the square root restored, dimensionless
  // k_s = ContactStiffnessDamped(m_p, dT, k_p, c_p) per spike, mean and standard deviation over the
  // spikes [N/m] (NaN: no spike).
  double stiffness_n_per_m = 0.0;
  double stiffness_spread_n_per_m = 0.0;
  bool lower_stop = true;  // the stop pushes the mass up (x < d): positive force spikes
  // Displacement amplitudes of the linear model (g V / |k_p - m_p w^2 + j c_p w|) [m]: the largest
  // over the clear records and the smallest over those with spikes, above the former (below it a
  // record may sit on the contacting branch of a bistable response, which bounds nothing; a record
  // distorted without spikes bounds neither: EstimateContact); NaN when there are none. With no spike
  // in the campaign: clear against not clear.
  double largest_clear_amplitude_m = 0.0;
  double smallest_contacting_amplitude_m = 0.0;
  // |d| to start the refinement from [m] (NaN: no contacting record): the bracket's geometric middle
  // (or an end when it is one-sided); FitAnalysed replaces it by the best of a grid over the bracket
  // (fit_internal::StopDistanceStart).
  double stop_distance_m = 0.0;
};
// `linear` is step 2's result (k_p, c_p, g at m_p = mass_kg).
ContactEstimate EstimateContact(std::span<const RecordAnalysis> analyses, ResponseKind kind,
                                const FrfFitSummary& linear, const FitOptions& options);

// ---- Step 4 and the result ---------------------------------------------------------------------

// One reported parameter. Non-identifiable ones (scaled by an unknown sensitivity) are listed with
// identifiable = false; fixed ones (m_p, c_s when not fitted) with standard_error 0.
struct FitParameter {
  std::string name;  // "k_p", "k_p/m_p", "d/g", ...
  std::string unit;
  double value = 0.0;
  double standard_error = 0.0;  // same unit; 0 when fixed
  bool fixed = false;
  bool identifiable = true;
  std::string note;
};

struct RefinementSummary {
  bool ran = false;           // false when options.refine is false
  // Ceres converged and the covariance exists, or exists for all but a stop no orbit depends on (below)
  bool converged = false;
  int iterations = 0;         // Ceres iterations over all passes
  int correction_passes = 0;  // solves with refreshed sampling corrections
  size_t branch_switches = 0; // records moved to a better-matching coexisting orbit between passes
  double initial_cost = 0.0;  // SSR / 2 in units of the harmonic standard errors
  double final_cost = 0.0;
  size_t residuals = 0;            // M real residuals
  size_t parameters = 0;           // P
  double residual_variance = 0.0;  // s^2 = SSR / (M - P): ~1 when model and noise estimate are right
  // Per principal direction of the covariance, largest first: the Jacobian's variance over the one
  // reported, where the chi-square rose more slowly along it than J said (secant_covariance.h); 1: as J.
  std::vector<double> secant_ratios;
  bool ended_on_bound = false;     // a parameter ended on its bound: the model does not fit the records
  // Where the Jacobian is rank deficient: the parameters ("k_p", "c_p", "g", "d", "k_s", "c_s") that take
  // part in its null space (a stop no orbit reaches: d, k_s). They are reported without an error, the
  // others with the errors of the problem that holds them. Where only the stop's are (d, k_s, c_s), the
  // fit converges on the others and those keep their staged values (a warning says so).
  std::vector<std::string> unidentified;
  // Where the stop is held so: the fitted orbits' largest displacement toward it over the refined
  // records, on their sample grids [m]. Any |d| above it leaves those orbits as they are. NaN otherwise.
  double largest_excursion_m = std::numeric_limits<double>::quiet_NaN();
  double seconds = 0.0;
  std::string report;  // Ceres' brief report; why not converged
};

// How the fitted model matches one record.
struct RecordFit {
  std::string name;
  double frequency_hz = 0.0, amplitude_v = 0.0, phase_rad = 0.0;  // estimated drive
  double nominal_frequency_hz = 0.0, nominal_amplitude_v = 0.0;
  bool clear = false;
  size_t spikes = 0;
  double contact_time_s = 0.0;  // mean over the record's spikes [s] (NaN: none)
  double distortion = 0.0;
  double noise_rms = 0.0;         // [response units]
  double hum_frequency_hz = 0.0;  // mains hum removed (0: none) [Hz]
  double hum_amplitude = 0.0;     // [response units]
  int response_periods = 1;       // RecordAnalysis::response_periods
  std::complex<double> frf;       // measured C_1(response) / C_1(v_in)
  bool used_linear = false;       // step 2
  bool used_contact = false;      // step 3 (spikes gave contact times)
  bool used_refinement = false;   // step 4
  // sqrt(sum_h |C_h - C_h^model|^2 / sum_h |C_h|^2) over h = 1..N: the normalised RMS of the
  // response residual within the fitted harmonics, before (staged estimates) and after refinement.
  double nrmse_initial = 0.0;
  double nrmse = 0.0;
  double chi2 = 0.0;     // sum_h |(C_h - C_h^model) / se|^2 / 2N: ~1 when only noise remains
  int model_period = 1;  // of the model's steady state (drive periods; 0 aperiodic)
  double model_contacts_per_period = 0.0;
  // The fitted model's C_h as the record's sampling sees them, relative to the drive phase.
  std::vector<std::complex<double>> model_harmonics;
};

struct FitResult {
  FitModelKind model_kind = FitModelKind::kPaper;
  ResponseKind response = ResponseKind::kForce;
  bool absolute_scale = true;
  double mass_kg = 0.032;                // m_p held fixed [kg]
  std::vector<FitParameter> parameters;  // what is reported (see the header comment)
  // The fitted model at m_p = mass_kg; with absolute_scale false its g and d carry the unknown
  // sensitivity (it reproduces the response in the recorded units).
  ActuatorModel model;
  std::string identifiability;  // what could and could not be identified, in words
  ActuatorModel staged;         // steps 2-3's estimates, where step 4 starts
  LinearStage linear;
  ContactEstimate contact;
  RefinementSummary refinement;
  std::vector<RecordFit> records;  // every analysed record, in campaign order
  double nrmse_initial = 0.0;      // over all records, as RecordFit::nrmse
  double nrmse = 0.0;
  std::vector<std::string> warnings;
  double seconds = 0.0;  // wall time of the whole fit [s]
  // The named parameter, or nullptr.
  const FitParameter* Find(std::string_view name) const;
};

// The joint refinement (step 4) from the staged model `start` (m_p, stop side and contact law
// taken from it). Records listed in `used` enter the fit; every record gets a RecordFit. Fills
// result->model, ->parameters, ->refinement, ->records, ->nrmse*.
void RefineParameters(std::span<const RecordAnalysis> analyses, ResponseKind kind, const ActuatorModel& start,
                      const std::vector<size_t>& used, const FitOptions& options, FitResult* result);

// Step 1 on every stepped-sine record of the campaign (side by side, one thread per core), in campaign
// order; broadband records are skipped with a warning, drives far from the manifest's frequency
// warned about (warnings may be null). Throws InputError as FitCampaign.
std::vector<RecordAnalysis> AnalyseCampaign(const Campaign& campaign, const FitOptions& options,
                                            std::vector<std::string>* warnings);

// Steps 2-4 on analysed records (of one campaign: `response` and `absolute_scale` are its).
FitResult FitAnalysed(std::span<const RecordAnalysis> analyses, ResponseKind response, bool absolute_scale,
                      const FitOptions& options);

// Steps 1-4 on a campaign. Throws InputError for bad options, an empty campaign, a campaign without
// stepped-sine records, bad records (naming the record), fewer than 3 records clear of the stop.
FitResult FitCampaign(const Campaign& campaign, const FitOptions& options = {});

// One JSON object: model, response, absolute_scale, mass_kg, identifiability, parameters (by name,
// FitParameterJson), fitted_model (model_json.h), stages (linear; contact: records_not_clear,
// records_with_spikes, spikes (theirs, the sum of records[].spikes), spikes_with_contact_time, ...;
// refinement), records, nrmse_initial, nrmse, warnings, seconds. Non-finite numbers are written as
// null.
nlohmann::json FitResultToJson(const FitResult& result);

// The contact stage's counts as reported (FitResultToJson's stages.contact, strokelab fit): the records
// not clear of the stop (impact spikes, or distortion above the limit), those of them with impact
// spikes, and all their spikes (the sum of RecordFit::spikes; ContactEstimate::spikes counts those of
// them whose contact time gave a k_s, the others being too wide for any stop of the model).
struct ContactCounts {
  size_t records_not_clear = 0, records_with_spikes = 0, spikes = 0;
};
ContactCounts CountContacts(const FitResult& result);

// One reported parameter: value, standard_error (null for a fixed parameter, and where there is
// none), unit, fixed, identifiable (estimated from these records: false for a fixed one), note.
nlohmann::json FitParameterJson(const FitParameter& parameter);

}  // namespace strokelab
