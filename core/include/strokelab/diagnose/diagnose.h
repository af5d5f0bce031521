// Diagnosis: where a fitted model and a campaign disagree, which physics the model left out, and how
// much better the model fits with it added (strokelab diagnose).
//
//   1. Split: every `heldout_every`-th stepped-sine record is held out of all fits, counted by drive
//      amplitude, then frequency, whatever the campaign's order, so that the held-out set spans the
//      amplitudes and frequencies (HeldOutRecords).
//   2. Base fit (fit.h) on the other records; the base model is then evaluated on every record.
//   3. Signatures of the mismatch (Signatures): per record and harmonic, even and odd harmonics of the
//      records clear of the stop versus amplitude, the resonance (paper Eq. 3 per amplitude level)
//      versus amplitude, contact times and spike polarity versus impact strength, and the time-domain
//      residual in windows around contacts against the rest of the period.
//   4. Candidates (EffectLibrary): the base model extended by each effect, fitted with every base
//      parameter free by identify/extended_fit.h (one least-squares problem on the variational flow's
//      exact Jacobians), from the base fit. Where that ended with a parameter on its bound and no
//      candidate fits the fit records within noise, steps 4 and 5 run again with each single also
//      fitted from the staged estimates (the better of its two fits counts).
//   5. Choice, by forward selection: a single is accepted when it lowers the held-out chi-square
//      (harmonic residuals over their standard errors, scaled by the candidate's residual variance on
//      the fit records) by more than `min_heldout_gain`, the fit records' chi-square by more than the
//      Akaike penalty 2 k (k its new parameters), and its parameter lies beyond two standard errors of
//      zero (for effects whose absence is a zero parameter; an amplifier limit, beyond two standard
//      errors below the campaign's largest drive; a second stop or a Hertzian stop, a parameter the records
//      identify). The best accepted single is taken; then
//      every other fitted effect is added in turn (up to three effects; not only the accepted ones:
//      beside a large first effect a second one's single fit can do worse than the base), the best
//      that beats the current model by the same rules is kept if dropping any of its effects again
//      costs more than noise (backward check), and so on. For the check, the current model is also
//      refitted from the larger one's solution with the added effect taken out, and the better of its
//      two fits counts: a fit from the base can end short of its optimum, and a second effect then
//      takes up only what that fit left. Where the model so chosen (or the base, when none was)
//      still fails the fit records' noise test (FitFigures::beyond_noise), the selection looks ahead:
//      from each model on its path, forward selection again from that model's extension with the
//      largest fit-records gain, whose model is taken if it beats the base by the same rules, fits
//      its fit records within noise, and beats the model chosen so far by more than
//      `min_heldout_gain` on the held-out records. With two effects missing, either one's fit alone
//      can do worse on the held-out records (selection.h).
//   6. Open world (Unexplained): the chosen model's held-out chi-square against noise alone. When it
//      is beyond noise, the report says where, and its effects must stand again with their standard
//      errors scaled by the misfit's ratio to noise (selection.h SignificantUnderMisfit; the best part
//      of the model whose effects do answers instead); when the chosen effects removed less of the
//      excess than they leave, they are not named (the misfit is "unexplained", with the best
//      candidate's share).
//      Where it is unexplained and coil_inductance was not a candidate, steps 4-6 run again with it
//      (DiagnoseOptions::coil_when_unexplained; fits done before are not repeated). The coil added to a
//      model without one is first looked at with tau_e on its floor (effects.cc): where a Gauss-Newton
//      step from there lowers tau_e, its fit stops there and is scored so (extended_fit.h floor_probe).
//      The model is also looked at above the fitted harmonics: where the residual rings after the
//      impacts at one mode's frequency (open_world.h FindRingAboveHarmonics), effects at the stop are
//      not named (they may stand in for the mode: selection.h BestWithoutStopEffects answers), and a
//      model that passes the harmonics is unexplained all the same.
//
// Reference: "Nonlinear vibrations of a stroke-saturated inertial actuator", Eq. 2-6
// (Eq. 2 in its continuous form, model.h; Eq. 6 with its square root restored, signal.h).
#pragma once

#include <complex>
#include <functional>
#include <limits>
#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "strokelab/base/errors.h"  // FieldError
#include "strokelab/base/progress.h"
#include "strokelab/identify/campaign.h"
#include "strokelab/identify/fit.h"
#include "strokelab/model/dynamics.h"
#include "strokelab/model/model.h"

namespace strokelab {

enum class Effect {
  kCubicStiffness,       // k3 x^3 in the suspension (hardening > 0, softening < 0)
  kQuadraticStiffness,   // k2 x^2: an asymmetric suspension
  kHertzianContact,      // the stop pushes with k_s p^(3/2)
  kContactDamping,       // c_s p' while in contact: restitution below one
  kSecondStop,           // an upper end stop
  kDryFriction,          // F_c tanh(x' / v_s)
  kAmplifierSaturation,  // the drive clipped at +-limit before the gain
  kQuadraticDamping,     // c2 x'|x'|: a mechanical resistance growing with velocity
  kForceFactor,          // g (1 + b1 x + b2 x^2): the coil's force factor over the stroke
  kCoilInductance,       // tau_e = L / R: the coil's current lags the voltage (a third state)
};

struct EffectInfo {
  Effect effect;
  const char* id;         // "cubic_stiffness", ... (the JSON ids)
  std::vector<const char*> parameters;  // the model parameters it adds (model.h keys)
  const char* signature;  // the signature it leaves in a campaign, and why
};
const std::vector<EffectInfo>& EffectLibrary();
const EffectInfo& Info(Effect effect);
Effect ParseEffect(std::string_view id);  // throws InputError("effect") listing the ids

struct DiagnoseOptions {
  FitOptions fit;               // the base fit (model paper | linear, harmonics, ...)
  int heldout_every = 4;        // every n-th record is held out (>= 2)
  double min_heldout_gain = 10; // held-out chi-square drop (in residual variances) an effect must beat
  bool pairs = true;            // forward selection beyond one effect (pairs, triples)
  // Whether coil_inductance is a candidate from the start. Its fits integrate a third, fast state (the
  // coil's pole tau_e, ~0.1-1 ms) with the explicit variational flow, whose steps then follow tau_e:
  // each orbit costs 10-40 times a two-state model's, and a campaign's diagnosis several times as long.
  bool coil_inductance = false;
  // Where it is not, whether the selection runs again with it when the library without it leaves the
  // misfit unexplained (the open-world test): a campaign that a cheaper model explains never pays
  // for the coil's fits. The broadband diagnosis does the same (broadband_diagnose.h step 5).
  bool coil_when_unexplained = true;
  int max_passes = 8;           // solves of an extended fit (sampling corrections refreshed between)
  double max_seconds = 600;     // wall time of the whole diagnosis [s]; candidates left are skipped
  // The report's saturation maps of the base and the diagnosed model (report/diagnosis_maps.h) over
  // the campaign's frequency x amplitude range: grid points per axis, 0 in either: no maps. Read by
  // the report layer (strokelab diagnose --out, a diagnose job's report), not by DiagnoseCampaign,
  // which stays free of sweeps; kept here so that the CLI flags and job options come from one table.
  // A caller that draws no maps sets them to 0, so that the progress plan leaves the maps out.
  int map_frequency_points = 40;
  int map_amplitude_points = 12;
  // Called at each stage's start and within the candidates' fits (each solve and Ceres iteration),
  // from the calling thread (may be empty). The stages, N of them: the records' analysis, the base
  // fit, the signatures, one stage per fit of the selection (selection.h's SelectionStep: each effect
  // that applies, every library effect planned until the base fit says which, then each fit of the
  // forward selection, N revised at each of its moves), the same again with coil_inductance where it
  // runs (coil_when_unexplained; the fits it has made already are passed over), and the report's two
  // maps (when both map point counts are not 0; reported by report/diagnosis_maps.h).
  ProgressHook progress;
  // Nothing, or the first wrong field and why: the base fit's own (as FitOptions::IsValid names it,
  // "harmonic_orders"), then "heldout_every", "min_heldout_gain", "max_passes", "max_seconds",
  // "map_frequency_points", "map_amplitude_points".
  std::optional<FieldError> IsValid() const;
};
// The diagnosis's own options under their names (OptionInfo, fit.h), in the order the CLI reads its
// flags; the base fit's are FitOptionFields(), applied to DiagnoseOptions::fit.
const std::vector<OptionInfo<DiagnoseOptions>>& DiagnoseOptionFields();

// How one model matches one record.
struct RecordMatch {
  std::string name;
  double frequency_hz = 0.0, amplitude_v = 0.0;  // estimated drive
  bool heldout = false;
  bool clear = false;  // clear of the stop (fit.h)
  double power = 0.0;  // sum_h |C_h|^2 over the usable harmonics (RecordAnalysis::usable)
  double nrmse = 0.0;  // sqrt(sum_h |C_h - C_h^model|^2 / power), usable harmonics
  // sum_h |C_h - C_h^model|^2 / s^2 (2N real residuals), s^2 the record's noise variance plus the
  // model's sampling jitter (fit_orbit.h HarmonicVariance): what the open-world test judges.
  double chi2 = 0.0;
  std::vector<double> harmonic_chi2;  // its terms, h = 1..N (0 for harmonics not usable)
  // The same over the record's noise variance alone: what candidates are compared on, since a model
  // could buy a small chi2 with a large jitter of its own.
  double noise_chi2 = 0.0;
  int residuals = 0;                  // real residuals in chi2: 2 per usable harmonic
  std::vector<std::complex<double>> measured, model;  // C_h, h = 1..N, response units
  int model_period = 1;
  State model_start;     // the model orbit's state at the drive's phase 0 (with model_period: where it repeats)
  double variance = 0.0;  // of Re and Im of each model harmonic: the record's noise and the sampling's jitter
  double model_contacts_per_period = 0.0;
  double model_mean_x_m = 0.0;  // the model orbit's mean displacement (0 unless period 1)
};

// Error figures of a model over the campaign.
struct FitFigures {
  double nrmse = 0.0;          // over all records: sqrt(sum |dC|^2 / sum |C|^2)
  double heldout_nrmse = 0.0;  // over the held-out records
  double chi2 = 0.0;           // over the fit records
  double heldout_chi2 = 0.0;   // over the held-out records
  double residual_variance = 0.0;  // chi2 / (M - P) on the fit records
  size_t dof = 0;                  // M - P
  // The fit records reject the model: its chi-square is beyond noise by the fit's own test (stepped:
  // extended_fit.h BeyondNoise over dof; broadband: broadband_fit.h's, the noise levels' spread included).
  bool beyond_noise = false;
};

// One piece of evidence: a measured figure, what it means, and which effects it points to.
struct Evidence {
  std::string kind;     // "harmonic_balance", "resonance_shift", "contact_time_trend", ...
  std::string summary;  // one sentence with the numbers
  double value = 0.0;   // the figure (see summary); NaN when not measurable
  double standard_error = 0.0;
  double significance = 0.0;    // |value| / standard_error (0 when no error is known)
  std::vector<Effect> points_to;  // effects this evidence supports
};

// Where the base model misses, from its residuals.
struct Signatures {
  std::vector<Evidence> evidence;
  // The worst records (largest chi2 per residual) and, for each, its worst harmonic.
  struct Hotspot {
    std::string record;
    double frequency_hz = 0.0, amplitude_v = 0.0;
    int harmonic = 1;
    double magnitude_error = 0.0;  // |C_h^model| / |C_h| - 1
    double phase_error_rad = 0.0;  // arg C_h^model - arg C_h
    double chi2_per_residual = 0.0;
  };
  std::vector<Hotspot> hotspots;
  // Time-domain residual RMS within +-contact_window_s of the contacts and elsewhere, over the
  // contacting records [response units] (NaN: no contacts).
  double contact_window_s = 0.0;
  double residual_rms_near_contacts = 0.0;
  double residual_rms_elsewhere = 0.0;
  // Per amplitude level [V]: resonance of paper Eq. 3 fitted to that level's clear records (NaN when
  // fewer than 3), and the mean |C_2| / |C_1|, |C_3| / |C_1| of its clear records.
  struct Level {
    double amplitude_v = 0.0;
    size_t clear_records = 0;
    double resonance_hz = 0.0, resonance_se_hz = 0.0;
    double second_harmonic_ratio = 0.0, third_harmonic_ratio = 0.0;
    double mean_contact_time_s = 0.0;  // NaN: no spikes at this level
  };
  std::vector<Level> levels;
};

struct CandidateFit {
  std::vector<Effect> effects;
  std::string label;                   // "cubic_stiffness" or "cubic_stiffness+contact_damping"
  bool fitted = false;                 // false: skipped (reason in `note`)
  bool converged = false;
  std::vector<FitParameter> parameters;  // base and effect parameters, with standard errors
  std::vector<double> covariance;        // of their values (ExtendedFitResult::covariance)
  std::vector<FitParameter> effect_parameters;  // the effect's own
  ActuatorModel model;
  FitFigures figures;
  double max_drive_v = 0.0;   // the campaign's largest drive amplitude [V]: an amplifier limit above it clips nothing
  double heldout_gain = 0.0;  // (base held-out chi2 - this) / max(1, this residual variance)
  double fit_gain = 0.0;      // the same on the fit records
  int passes = 0;
  double seconds = 0.0;
  std::string note;
  // "named", or why not, with the numbers: "rejected: held-out gain 1.6 <= 10", "rejected: k3 = ...
  // is within 2 standard errors of zero", "rejected: backward check: ...", "beats noise, but another
  // model is better", "not named: ..." (the open-world test), "not fitted" (time limit, failure).
  std::string decision;
};

// What the diagnosed model leaves unexplained, when that is more than noise (the open-world test):
// the held-out records' chi-square against what noise alone gives. A correct model's held-out
// residuals are noise plus its parameters' prediction error J_h (theta_hat - theta), of covariance
// J_h C J_h^T, C = (J_f^T J_f)^-1 from the fit records (the prediction error of a least-squares fit:
// Seber and Lee, "Linear Regression Analysis", 2nd ed., Wiley 2003, Sec. 5.3); with it counted, the
// chi-square is chi-square(R), R the held-out residuals (open_world.h HeldOutLeverage). Its mean over
// records is (1 + P / M) R, P the parameters and M the fit records' residuals, but a held-out record
// where the parameters' error shows most can take far more (control study seed 4162: held-out
// chi-square 176.5 over 120 residuals, flagged by the mean; 114.0 with that error counted). The test
// flags p < kUnexplainedP (unexplained.cc: the choice and its calibration on controls).
// A nonparametric estimate of the force the diagnosed model lacks, over the state (x, v): a
// restoring-force surface (S. F. Masri and T. K. Caughey, "A nonparametric identification technique
// for nonlinear dynamic problems", J. Appl. Mech. 46 (1979) 433-447), here of the force missing
// rather than the whole restoring force. Per record and drive phase the state and the acceleration
// come from the measured harmonics (the response channel's, read as displacement's), and the force
// missing there is m_p x'' - F(u, x, v) of the diagnosed model, less the same quantity on the model's
// own harmonics: that difference cancels what cutting both at N harmonics makes. Phases where either
// is within 5 % of the stop distance of a stop are left out (contact is seen in its own evidence, and
// N harmonics do not resolve an impact). The records' mean position is taken as the model orbit's
// (a force or acceleration channel does not see it).
struct MissingForceSurface {
  std::vector<double> x_m, v_m_per_s;       // bin centres
  // Per bin [ix * v_m_per_s.size() + iv]: the mean missing force, its standard error (spread over
  // sqrt(samples)) and the samples (records x phases) in it; NaN where it holds fewer than 2.
  std::vector<double> force_n, standard_error_n;
  std::vector<int> samples;
  double rms_n = 0.0;  // over all samples kept
  // The single term g(x, v) (x^2, x v, v^2, x^3, x^2 v, x v^2, v^3, x|x|, v|v|, sign v) that, fitted with
  // 1, x and v (what the fit's k_p, c_p and offsets absorb), explains most of the samples' variance.
  std::string term, term_unit;
  double term_coefficient = 0.0;  // [term_unit]
  double term_r2 = 0.0;           // variance explained by 1, x, v and the term
  double linear_r2 = 0.0;         // by 1, x and v alone
  std::string note;               // why there is no surface: "the model's coil force is ..."
};

struct Unexplained {
  static constexpr double kNoRing = std::numeric_limits<double>::quiet_NaN();
  double heldout_chi2 = 0.0;      // of the diagnosed model
  int heldout_residuals = 0;      // R
  // What noise and the parameters' own error give alone: R + trace(J_h C J_h^T) (HeldOutLeverage), or
  // where that is not measured (1 + P / M) R.
  double expected_chi2 = 0.0;
  double threshold_chi2 = 0.0;    // flagged above: the calibrated chi-square's 1 - p quantile
  double p_value = 0.0;           // of heldout_chi2 if the model were right (its parameters' error counted)
  double misfit_to_noise = 0.0;   // sqrt(heldout_chi2 / expected_chi2): misfit RMS over noise's (1: noise)
  // Where: records whose own chi-square is beyond noise (Bonferroni over the records at the same p),
  // worst first, each with the harmonic that misses most and the drive phase where the residual
  // waveform sum_h Re(dC_h e^{j h theta}) peaks (theta = 0: the drive's zero crossing upwards).
  struct Place {
    std::string record;
    double frequency_hz = 0.0, amplitude_v = 0.0;
    bool heldout = false;
    double chi2_per_residual = 0.0;  // 1 is noise
    int worst_harmonic = 1;
    double worst_harmonic_hz = 0.0;
    double residual_peak_phase_deg = 0.0;  // [0, 360)
    double impact_phase_deg = 0.0;         // circular mean of the record's impact spikes; NaN: none
    // The residual's ringing after the impacts, above the fitted harmonics (ringing.cc): its frequency,
    // damping ratio (NaN: it does not decay measurably), first swing [response units] and that swing
    // over its noise. All NaN when the residual does not ring (or the record has no impact).
    double ring_frequency_hz = kNoRing, ring_damping_ratio = kNoRing, ring_amplitude = kNoRing,
           ring_to_noise = kNoRing;
  };
  std::vector<Place> places;
  // Per harmonic order h over every record: chi-square per residual (1 is noise).
  std::vector<double> harmonic_chi2_per_residual;
  std::string description;  // the above in words, with a guess at its shape from the data
  MissingForceSurface missing_force;  // over all records, at the diagnosed model
};

// A named effect's characteristic, as a transducer analyser reports it (Klippel's large-signal
// identification: K(x), Bl(x), R(v)): the diagnosed model's curve over the range the records reach,
// with its standard error from the chosen fit's covariance (delta method: var y = g^T C g, g the
// curve's gradient in the fitted parameters), and the base model's curve for comparison.
struct EffectCurve {
  Effect effect = Effect::kCubicStiffness;
  std::string id;       // "stiffness", "force_factor", "resistance", "friction", "stop_force", ...
  std::string title;    // "K(x) = k_p + k2 x + k3 x^2: the suspension's force over displacement"
  std::string x_label, y_label;  // with units: "x [m]", "K [N/m]"
  std::vector<double> x, y;
  std::vector<double> y_se;    // NaN where a parameter it needs is not identifiable
  std::vector<double> base_y;  // the base fit's model
  std::string range;           // where x comes from, in words
};

struct Diagnosis {
  FitResult base;                   // the base fit on the fit records
  std::vector<size_t> heldout;      // record indices (into `records`)
  std::vector<RecordMatch> before;  // the base model on every record
  // The diagnosed model on every record: the chosen candidate's; with nothing named, the base model's
  // (== before), or its refit with the sampling correction's slopes where the base left more than noise.
  std::vector<RecordMatch> after;
  FitFigures fit_before, fit_after;
  Signatures signatures;
  std::vector<CandidateFit> candidates;  // every candidate tried, best held-out gain first
  // 2 when the selection ran again with the singles also fitted from the staged estimates (step 4).
  int selection_rounds = 1;
  // Whether the selection ran once more with coil_inductance (DiagnoseOptions::coil_when_unexplained).
  bool coil_round = false;
  std::vector<Effect> missing_physics;   // named effects, best first (empty: nothing missing)
  int chosen = -1;                       // index into candidates (-1: nothing missing)
  // The diagnosed model, ready to sweep or simulate (model_json.h): the base fit's model (or its refit,
  // as `after`) when nothing is missing, else the chosen candidate's (the base extended by the named
  // effects, all parameters as fitted together). `model_note` says which, and whether its fit converged.
  ActuatorModel model;
  std::string model_note;
  // Empty: what the diagnosed model leaves on the held-out records is noise. Set: it is not, and
  // says where (reported beside any named effect: that effect explains only part of the misfit).
  std::optional<Unexplained> unexplained;
  std::vector<EffectCurve> curves;       // one per characteristic of the named effects
  std::string conclusion;                // in words
  // N of the progress's "stage k of N" once the diagnosis has run (DiagnoseOptions::progress): the
  // stages it reached, then the report's maps when the options ask for them.
  int progress_stages = 0;
  double seconds = 0.0;
};

// Step 1's split: true for the records held out of all fits. The records are counted level by level
// of drive amplitude (nominal amplitudes within 1 % form a level), each level by frequency, and every
// n-th count is held out (n = heldout_every; 0 holds none out). Not the campaign's order: a campaign
// listed frequency by frequency with n amplitudes would then hold out its strongest drive at every
// frequency, and the fits would never see the records that reach the stop. The count runs on across
// levels, so the held-out frequencies move from level to level; a level of a multiple of n records
// counts one more at its end, so that they move there too.
std::vector<bool> HeldOutRecords(std::span<const RecordAnalysis> analyses, int heldout_every);

// Throws InputError for bad options or campaigns (as FitCampaign).
Diagnosis DiagnoseCampaign(const Campaign& campaign, const DiagnoseOptions& options = {});

// One candidate of the diagnosis fitted to every record, none held out: the base fit (step 2), then
// the base model extended by `effects` with every parameter free (step 4, the problem and start
// DiagnoseCampaign's first round fits for that candidate). For studies of the extended fit's estimates and
// standard errors against a known truth (tests/diagnose/fit_study.cc). The held-out figures are
// then empty (heldout_chi2 0, heldout_nrmse NaN, heldout_gain 0); heldout_every, min_heldout_gain
// and pairs play no part. Throws InputError for bad options or campaigns (as DiagnoseCampaign) and,
// naming "effects", for an effect that cannot show in the campaign (Hertzian contact, contact
// damping or a second stop without contacts).
CandidateFit FitCandidate(const Campaign& campaign, std::span<const Effect> effects,
                          const DiagnoseOptions& options = {});

// missing_physics (effect, parameters, evidence), model (the diagnosed model as ModelToJson writes it:
// what `strokelab sweep --model`, `simulate --model` and a sweep job's "model" read) and model_note,
// fit_before, fit_after (nrmse, heldout_nrmse, ...), base_parameters and base_model, candidates,
// selection_rounds, coil_round, signatures, records, conclusion, seconds. The fitted parameters appear
// twice in two shapes: as reported (by name, with standard error and unit: base_parameters,
// missing_physics[].parameters and .all_parameters) and as the model they make ("model", "base_model":
// model.h JSON names, no errors).
nlohmann::json DiagnosisToJson(const Diagnosis& diagnosis);

// The open-world test's result as DiagnosisToJson writes it under "unexplained": null, or its figures,
// places and description (also the form a remote worker's diagnosis data carries).
nlohmann::json UnexplainedToJson(const std::optional<Unexplained>& unexplained);
// The named effects' curves as DiagnosisToJson writes them under "curves": [{effect, id, title,
// x_label, y_label, x, y, y_se, base_y, range}], non-finite numbers as null.
nlohmann::json CurvesToJson(const std::vector<EffectCurve>& curves);

}  // namespace strokelab
