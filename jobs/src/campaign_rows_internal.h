// Shared by jobs.cc (a diagnose task run in the server) and campaign_rows.cc (one run by a remote
// worker): the report's files of a diagnosis as result rows.
#pragma once

#include <vector>

#include "strokelab/diagnose/diagnose.h"
#include "strokelab/jobs/task.h"
#include "strokelab/report/diagnosis_maps.h"

namespace strokelab::jobs {

// WriteDiagnosisReport into a scratch directory, each file a row of table "report_files"
// ({"name", "content_type", "text"}).
std::vector<ResultRow> DiagnosisReportRows(const Diagnosis& diagnosis, const report::DiagnosisMaps& maps);

}  // namespace strokelab::jobs
