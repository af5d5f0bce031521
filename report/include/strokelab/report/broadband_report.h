// What `strokelab diagnose --out DIR` makes of a broadband diagnosis (diagnose/broadband_diagnose.h) for
// people: the stepped-sine report's folder (diagnose_report.h) with the sections both share, and the
// figures a time-series diagnosis has. Pure functions of the BroadbandDiagnosis, tested on hand-made ones.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "strokelab/diagnose/broadband_diagnose.h"
#include "strokelab/report/diagnosis_maps.h"

namespace strokelab::report {

// The page: the verdict (missing physics with its parameters, or "nothing missing", or
// "unexplained" with the held-out parts where the misfit lives), the fit before and after, the base
// and the chosen parameters, the candidates with their decisions, the evidence, and the figures:
//   parts   each record's chi-square per sample (1 is noise) on its fit and its held-out part, base
//           and diagnosed model, against the record's drive level
//   curves  the named effects' characteristics with their bands (as the stepped report's)
// the records' table, and the saturation maps of both models with the threshold's shift and the jump
// intervals, as the stepped report's (`maps` from SweepBroadbandDiagnosisMaps; null: not computed, said on
// the page).
std::string BroadbandDiagnosisHtml(const BroadbandDiagnosis& diagnosis, const DiagnosisMaps* maps = nullptr);

// The files WriteBroadbandDiagnosisReport writes, in order.
const std::vector<std::string>& BroadbandDiagnosisReportFiles();

// Writes BroadbandDiagnosisReportFiles() into `dir` (created if missing):
//   index.html                BroadbandDiagnosisHtml
//   records.csv               per record: drive rms, noise rms, and nrmse and chi-square per sample of
//                             its fit and held-out part, base and diagnosed model
//   candidates.csv, candidate_parameters.csv, threshold_shift.csv, jump_intervals.csv   as the
//                             stepped report's
//   model.json                the diagnosed model (the model file of sweep --model, simulate --model)
// Non-finite numbers as empty cells. Throws std::runtime_error if a file cannot be written.
void WriteBroadbandDiagnosisReport(const BroadbandDiagnosis& diagnosis, const std::filesystem::path& dir,
                                   const DiagnosisMaps* maps = nullptr);

}  // namespace strokelab::report
