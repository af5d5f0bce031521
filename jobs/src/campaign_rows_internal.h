// Shared by jobs.cc (a diagnose task run in the server) and campaign_rows.cc (one run by a remote
// worker): the rows stored for a diagnosis.
#pragma once

#include <vector>

#include <nlohmann/json.hpp>

#include "strokelab/diagnose/broadband_diagnose.h"
#include "strokelab/diagnose/diagnose.h"
#include "strokelab/jobs/task.h"
#include "strokelab/report/diagnosis_maps.h"

namespace strokelab::jobs {

// The result document (table "diagnosis"), the warnings (table "warnings", campaign_warnings.h) and the
// report's files (table "report_files", {"name", "content_type", "text"}, written into a scratch
// directory by WriteDiagnosisReport or WriteBroadbandDiagnosisReport).
std::vector<ResultRow> DiagnosisRows(const Diagnosis& diagnosis, const report::DiagnosisMaps& maps);
// `base_fit`: the base fit's document (BroadbandDiagnosisToJson's "base").
std::vector<ResultRow> BroadbandDiagnosisRows(const BroadbandDiagnosis& diagnosis, nlohmann::json base_fit,
                                              const report::DiagnosisMaps& maps);

}  // namespace strokelab::jobs
