// strokelab diagnose: where a fitted model misses a campaign and which physics it left out
// (core/include/strokelab/diagnose.h).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include "commands.h"
#include "diagnose_print.h"
#include "format.h"
#include "option_flags.h"
#include "strokelab/diagnose/diagnose.h"
#include "strokelab/report/broadband_report.h"
#include "strokelab/report/diagnose_report.h"
#include "strokelab/report/diagnosis_maps.h"
#include "strokelab/base/errors.h"
#include "strokelab/data/recordings.h"

namespace strokelab::cli {
namespace {

constexpr const char* kDiagnoseHelp = R"(usage: strokelab diagnose --data DIR [--model paper|linear] [--json] [--out DIR] [options]

Fits the base model (as strokelab fit) to all but every n-th record (counted by drive amplitude, then
frequency, whatever the manifest's order), measures where it misses (per record and harmonic, harmonic
balance below the stop, resonance against amplitude, contact times, the residual around impacts),
fits the base model extended by each candidate effect (cubic_stiffness, quadratic_stiffness,
hertzian_contact, contact_damping, second_stop, dry_friction, amplifier_saturation,
quadratic_damping, force_factor) and names the ones that improve the held-out records beyond
noise, or says "nothing missing". Where they leave the misfit unexplained, it runs the selection
again with coil_inductance (the coil's pole: a third state, whose fits are slow), which
--coil-inductance tries from the start.

A campaign of broadband records only (noise, multisine, sweep) is diagnosed by the records' time
series instead (as strokelab fit fits them): the first or last 1/N of each record (--heldout-every N),
one that shows some of the record's impacts where it can, is held out, the candidates are fitted to the
other parts, and their held-out chi-square is the held-out parts' at the fitted model (each part's
start, offset and hum fitted). The choice, the thresholds and
the "unexplained" verdict are the same; the evidence is where the base model's residual stands out
(far out in displacement, slow, fast, near contacts), its spectrum and its coherence with the drive.
--out writes its report (index.html: the verdict, the held-out parts where a misfit lives, the fit,
parameters, both models' saturation maps over the drives' band and from the quietest drive's rms
sqrt 2 to the largest drive peak, candidates, evidence, each record's misfit per part against noise,
the named effects' curves), records.csv, candidates.csv, candidate_parameters.csv,
threshold_shift.csv, jump_intervals.csv, model.json and diagnosis.json.

  --data DIR               campaign directory (manifest.json or mapping.json)         (required)
  --model NAME             paper | linear                                             [paper]
  --json                   one JSON object on stdout instead of the text report
  --out DIR                also write the report folder (below)
  --heldout-every N        every N-th record is held out of the fits                  [4]
  --min-gain G             held-out chi-square drop (residual variances) to name an effect [10]
  --no-pairs               do not try pairs of effects
  --coil-inductance        try coil_inductance from the start (the coil's pole, a third
                           state: its fits take 10-40 times the others' time)
  --no-coil-when-unexplained  never try coil_inductance without --coil-inductance
  --max-seconds T          wall-time budget; candidates past it are skipped, and the
                           report's maps are cut off once it is spent                 [600]
  --map-frequency-points N the report's saturation maps: frequencies over the
                           campaign's range (geometric); 0: no maps                   [40]
  --map-amplitude-points N amplitudes over the campaign's range (linear); 0: no maps  [12]
  --progress               progress on stderr: a line at each stage's start (stage k of N,
                           each candidate's fit a stage, N revised as the forward selection
                           learns its moves; the time elapsed, an estimate of the time left
                           from the stages done so far) and, inside a candidate's fit, one
                           every 2 s at most (its solve and Ceres iteration)
  (and the fit's options: --harmonics, --mass-kg, --mains-hz, --max-distortion, --max-iterations,
   --fit-contact-damping, --no-refine; see strokelab fit --help)

The diagnosed model is the base fit's model when nothing is missing, else the base model extended by
the named effects with every parameter as fitted with them. The JSON result carries it as "model"
(with "model_note"), in the format of model files; the fitted parameters with their standard errors
are in "base_parameters" and "missing_physics" as before.

--out DIR writes:
  model.json           the diagnosed model: strokelab sweep --model DIR/model.json and
                       strokelab simulate --model DIR/model.json take it as it is, a sweep job
                       takes its content as "model" (the engine for a smooth model is chosen
                       as for any model: --method auto)
  index.html           the report: verdict, fit before and after, parameters, the saturation maps of
                       the base and the diagnosed model side by side with the saturation threshold
                       per frequency of both and its shift (V and %), the jump intervals of both,
                       candidates, evidence, figures, records
  threshold_shift.csv  per map frequency: grazing and lowest contacting amplitude, base and
                       diagnosed, and the shifts
  jump_intervals.csv   the jump (bistable) intervals of both models
  records.csv, candidates.csv, candidate_parameters.csv, levels.csv, diagnosis.json (the JSON result)
The maps sweep both models over the campaign's frequency x amplitude range after the diagnosis (a
smooth model's 40 x 12 map with thresholds: about a second, longer with the coil's pole);
--map-frequency-points 0 skips them.

Exit codes: 0 diagnosed (including "nothing missing"), 2 bad input (the message names the file and
line or the flag), 3 numerical failure.
)";

void PrintReport(const Diagnosis& d, std::ostream& out) {
  out << d.conclusion << "\n";
  out << "diagnosed model: " << d.model_note << "\n\n";
  if (d.unexplained) {
    out << "unexplained misfit (held-out chi-square " << General(d.unexplained->heldout_chi2, 4) << " against "
        << General(d.unexplained->expected_chi2, 4) << " from noise, flagged above "
        << General(d.unexplained->threshold_chi2, 4) << "), worst records:\n";
    for (const Unexplained::Place& p : d.unexplained->places)
      out << "  " << p.record << (p.heldout ? " (held out)" : "") << ": " << General(p.frequency_hz, 4) << " Hz, "
          << General(p.amplitude_v, 4) << " V, " << General(p.chi2_per_residual, 3) << " x noise, worst harmonic "
          << p.worst_harmonic << " (" << General(p.worst_harmonic_hz, 4) << " Hz), residual peaks at drive phase "
          << General(p.residual_peak_phase_deg, 3) << " deg\n";
    out << "\n";
  }
  out << "normalised RMS error (harmonics 1..N): before " << General(d.fit_before.nrmse, 4) << ", after "
      << General(d.fit_after.nrmse, 4) << "; held-out records (" << d.heldout.size() << "): before "
      << General(d.fit_before.heldout_nrmse, 4) << ", after " << General(d.fit_after.heldout_nrmse, 4) << "\n";
  if (d.chosen >= 0) PrintChosenParameters(d.candidates[d.chosen], out);
  PrintCandidates(d.candidates, out);
  PrintEvidence(d.signatures.evidence, out);
  out << "\nworst records of the base model:\n";
  for (const auto& h : d.signatures.hotspots)
    out << "  " << h.record << " (" << General(h.frequency_hz, 4) << " Hz, " << General(h.amplitude_v, 4) << " V): chi2/residual "
        << General(h.chi2_per_residual, 4) << ", worst harmonic " << h.harmonic << " (magnitude "
        << General(100 * h.magnitude_error, 3) << " %, phase " << General(h.phase_error_rad, 3) << " rad)\n";
  out << "\n" << General(d.seconds, 3) << " s\n";
}

// --progress: a line at each stage's start, and within a stage (a candidate's solves and
// iterations, a map's grid points) at most one per kStepLineInterval.
class ProgressPrinter {
 public:
  void operator()(const ProgressStage& stage) {
    const std::lock_guard<std::mutex> lock(mutex_);  // the maps report from the sweep's threads
    const auto now = std::chrono::steady_clock::now();
    const bool new_stage = stage.stage != last_stage_;
    if (!new_stage && now - last_line_ < kStepLineInterval) return;
    const ProgressReport report = clock_.Report(stage);
    std::cerr << ProgressLine(report) << std::endl;
    last_stage_ = stage.stage;
    last_line_ = now;
  }

 private:
  static constexpr std::chrono::seconds kStepLineInterval{2};
  std::mutex mutex_;
  ProgressClock clock_;
  int last_stage_ = 0;
  std::chrono::steady_clock::time_point last_line_{};
};

// What the maps of the report show, in a few lines: the threshold's shift, or why a map is missing.
void PrintMaps(const report::DiagnosisMaps& maps, std::ostream& out) {
  out << "\nsaturation maps: ";
  if (!maps.note.empty()) {
    out << maps.note << "\n";
    return;
  }
  out << maps.frequency_hz.points << " x " << maps.amplitude_v.points << " grid, " << General(maps.seconds, 3)
      << " s\n";
  for (const auto& [name, result, note] : {std::tuple{"base model", &maps.base, &maps.base_note},
                                          std::tuple{"diagnosed model", &maps.diagnosed, &maps.diagnosed_note}}) {
    if (maps.same_model && result == &maps.diagnosed) continue;
    if (!*result) out << "  " << name << ": no map, " << *note << "\n";
    else if (!(*result)->failures.empty())
      out << "  " << name << ": " << (*result)->failures.size() << " rows and columns failed and are left blank, the first: "
          << (*result)->failures.front() << "\n";
  }
  if (maps.base && maps.diagnosed && !maps.same_model)
    out << "  " << report::ThresholdShiftSummary(report::ThresholdShifts(*maps.base, *maps.diagnosed)) << "\n";
}

// `json` as DIR/name (--out DIR, created if missing).
void WriteJson(const std::string& dir, const char* name, const nlohmann::json& json) {
  std::error_code ignored;
  std::filesystem::create_directories(dir, ignored);  // a failure shows as the file's
  const std::filesystem::path path = std::filesystem::path(dir) / name;
  std::ofstream file(path);
  file << json.dump(2) << "\n";
  if (!file) throw InputError("--out", "cannot write " + path.string());
}

// A campaign of broadband records only: diagnose/broadband_diagnose.h. --out gets its report folder
// (report/broadband_report.h, with both models' maps) and diagnosis.json.
int RunBroadbandDiagnose(const Campaign& campaign, const DiagnoseOptions& options, const Args& args) {
  const BroadbandDiagnosis diagnosis = DiagnoseBroadbandCampaign(campaign, options);
  const nlohmann::json json = BroadbandDiagnosisToJson(diagnosis);
  const auto out = args.Get("--out");
  std::optional<report::DiagnosisMaps> maps;
  if (out) {
    maps = report::SweepBroadbandDiagnosisMaps(diagnosis, campaign, options);
    report::WriteBroadbandDiagnosisReport(diagnosis, *out, &*maps);
    WriteJson(*out, "diagnosis.json", json);
  }
  if (args.Has("--json")) {
    std::cout << json.dump(2) << "\n";
  } else {
    PrintBroadbandDiagnosis(diagnosis, std::cout);
    if (maps) PrintMaps(*maps, std::cout);
    if (out) std::cout << "report: " << (std::filesystem::path(*out) / "index.html").string() << "\n";
  }
  return 0;
}

}  // namespace

int RunDiagnose(const std::vector<std::string>& argv) {
  std::vector<std::string> values = {"--data", "--out"}, switches = {"--json", "--progress", "--help"};
  AddFitFlags(&values, &switches);
  AddOptionFlags(DiagnoseOptionFields(), &values, &switches);
  const Args args(argv, {values.begin(), values.end()}, {switches.begin(), switches.end()});
  if (args.Has("--help")) {
    std::cout << kDiagnoseHelp;
    return 0;
  }
  if (!args.Positional().empty())
    throw InputError(args.Positional().front(), "unexpected argument (see strokelab diagnose --help)");
  const auto data = args.Get("--data");
  if (!data) throw InputError("--data", "is required (the campaign directory)");
  DiagnoseOptions options;
  options.fit = FitOptionsFromArgs(args);
  ReadOptionFlags(args, DiagnoseOptionFields(), &options);
  if (const std::optional<FieldError> error = options.IsValid())
    throw InputError(FlagOf(DiagnoseOptionFields(), error->field), error->message);
  const auto out = args.Get("--out");
  if (!out) options.map_frequency_points = options.map_amplitude_points = 0;  // no maps: none in the progress plan
  const auto printer = std::make_shared<ProgressPrinter>();
  if (args.Has("--progress")) options.progress = [printer](const ProgressStage& stage) { (*printer)(stage); };

  const Campaign campaign = ReadCampaign(*data);
  const bool broadband = std::none_of(campaign.records.begin(), campaign.records.end(),
                                      [](const Recording& r) { return !r.broadband; });
  if (broadband) return RunBroadbandDiagnose(campaign, options, args);
  const Diagnosis diagnosis = DiagnoseCampaign(campaign, options);
  const nlohmann::json json = DiagnosisToJson(diagnosis);
  std::optional<report::DiagnosisMaps> maps;
  if (out) {
    maps = report::SweepDiagnosisMaps(diagnosis, options);
    report::WriteDiagnosisReport(diagnosis, *out, &*maps);
    WriteJson(*out, "diagnosis.json", json);
  }
  if (args.Has("--json")) {
    std::cout << json.dump(2) << "\n";
  } else {
    PrintReport(diagnosis, std::cout);
    if (maps) PrintMaps(*maps, std::cout);
    if (out) {
      std::cout << "report: " << (std::filesystem::path(*out) / "index.html").string() << "\n";
      std::cout << "model file: " << (std::filesystem::path(*out) / "model.json").string() << "\n";
    }
  }
  return 0;
}

}  // namespace strokelab::cli
