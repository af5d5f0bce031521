// What `strokelab diagnose` makes of a Diagnosis for people: a folder with one self-contained HTML
// page (conclusion, fit figures, candidates, evidence, inline SVG figures; no script, no external
// resource), CSV tables of the numbers behind it and the diagnosed model's file. Pure functions of
// the Diagnosis and its maps (diagnosis_maps.h, which runs the sweeps), so they are tested on
// hand-made diagnoses and sweep results without fitting or sweeping anything.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "strokelab/diagnose/diagnose.h"
#include "strokelab/report/diagnosis_maps.h"

namespace strokelab::report {

// The page: the conclusion (missing physics with its parameters and standard errors, or "nothing
// missing"), nrmse before and after with the relative improvement, the base and chosen parameters,
// the candidates (the chosen one highlighted), the evidence and hotspots, and the figures:
//   harmonics  |C_h| and arg C_h of the worst records (by base chi-square): measured, base, chosen
//   frf        |C_1| / V against frequency per amplitude level: measured, base, chosen
//   residual   each record's nrmse over (frequency, amplitude), base and chosen, held-out ringed
//   resonance  the resonance per amplitude level (Signatures::levels) with its standard error
//   contact    mean contact time per level, and the residual near contacts against elsewhere
//   ratios     |C_2| / |C_1| and |C_3| / |C_1| per level (records clear of the stop)
// and, when `maps` is given (diagnosis_maps.h), what the missing physics changes for the control
// loop: the saturation maps of the base and the diagnosed model side by side on one colour scale,
// the saturation threshold per frequency of both with the shift in V and %, and the jump intervals
// of both (without `maps`, or with maps not computed, a sentence says so).
// A figure without data is replaced by a sentence saying why. Non-finite numbers show as "-".
std::string DiagnosisHtml(const Diagnosis& diagnosis, const DiagnosisMaps* maps = nullptr);

// The files WriteDiagnosisReport writes, in order.
const std::vector<std::string>& DiagnosisReportFiles();

// Writes DiagnosisReportFiles() into `dir` (created if missing):
//   index.html           DiagnosisHtml
//   records.csv          per record: drive, held out, clear, nrmse / chi2 / period of base and chosen model
//   candidates.csv       per candidate: label, fitted, converged, gains, figures, passes, wall time, note
//   candidate_parameters.csv  per effect parameter of each candidate: candidate, parameter, value,
//                        standard error and unit, one value per cell
//   levels.csv           Signatures::levels
//   threshold_shift.csv  per map frequency: grazing and lowest contacting amplitude of the base and
//                        the diagnosed model, their differences in V and % (header only without maps)
//   jump_intervals.csv   the jump intervals of both maps: model (base | diagnosed), amplitude,
//                        frequency bounds and what bounds them (header only without maps)
//   model.json           the diagnosed model (Diagnosis::model) as ModelToJson writes it: the model
//                        file of `strokelab sweep --model` and `simulate --model`
// Non-finite numbers as empty cells. Throws std::runtime_error if a file cannot be written.
void WriteDiagnosisReport(const Diagnosis& diagnosis, const std::filesystem::path& dir,
                          const DiagnosisMaps* maps = nullptr);

}  // namespace strokelab::report
