// Whether rows a worker sends back for a task are rows RunTask could have written for it: the table
// the task's type writes, each row valid against its definition in schema/result.schema.json
// (sweep_point, jump_interval, saturation_threshold, simulate_record), on the task's grid (the
// row's amplitude is the task's, its frequency one of the task's; one threshold per frequency and
// one record, in order) and finite. A completion is checked before it is stored and cached, so a
// worker cannot store rows of another table, extra fields, points off the grid or non-finite numbers
// for a job that someone else's identical job would later be served from the cache. The numbers
// themselves are the worker's word: a worker token is trusted to compute, not to shape.
#pragma once

#include <nlohmann/json.hpp>
#include <vector>

#include "strokelab/jobs/task.h"

namespace strokelab::jobs {

// Throws InputError whose field is the JSON pointer of the offending part of the completion
// ("/rows/3/values/h_re", "/rows/0/table", "/rows").
void ValidateTaskRows(const nlohmann::json& task_spec, const std::vector<ResultRow>& rows);

// The rows to store for a fit or diagnose task from those a remote worker sent (RunTaskForRemote):
// a fit task's one "fit" row (an object, finite, with its "parameters" object and a "model" within
// ModelBounds; at most 16 MiB of JSON; served as JSON only), unchanged; a diagnose task's one
// "diagnosis_data" row, read by report::DiagnosisDataFromJson, becomes the "diagnosis" row
// (DiagnosisToJson) and the report's files rendered here ("report_files"): a worker's text reaches
// the page only as escaped text. A "broadband_diagnosis_data" row (a campaign of broadband records
// only) likewise, by BroadbandDiagnosisDataFromJson, BroadbandDiagnosisToJson and its report. Any
// other table (a worker's own "report_files") is refused. Throws InputError with the JSON pointer of
// the offending part ("/rows/0/values/diagnosis/conclusion").
std::vector<ResultRow> CampaignRowsFromWorker(const nlohmann::json& task_spec, std::vector<ResultRow> rows);

}  // namespace strokelab::jobs
