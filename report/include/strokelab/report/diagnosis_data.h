// A diagnosis with its maps as plain data, and back: what a remote worker sends for a diagnose task
// (table "diagnosis_data"), from which the server writes the result document (DiagnosisToJson) and
// renders the report itself (WriteDiagnosisReport), so that no markup a worker wrote is ever served.
// The document holds every field those two read, so both come out as from the worker's own Diagnosis
// (tests/server/remote_campaign_test.cc renders both ways and compares).
#pragma once

#include <nlohmann/json.hpp>

#include "strokelab/diagnose/diagnose.h"
#include "strokelab/report/diagnosis_maps.h"

namespace strokelab::report {

struct DiagnosisData {
  Diagnosis diagnosis;
  DiagnosisMaps maps;
};

// Non-finite numbers as null.
nlohmann::json DiagnosisDataToJson(const Diagnosis& diagnosis, const DiagnosisMaps& maps);

// The inverse, checked as input from elsewhere: every member present with its type, numbers finite
// or null (read as NaN), models within ModelBounds (ModelFromJson), effects known, indices in
// range, arrays within their size limits (100,000 items; harmonics 64; texts 64 KiB). Throws
// InputError whose field is the JSON pointer of the offending member ("/diagnosis/records/3/nrmse").
DiagnosisData DiagnosisDataFromJson(const nlohmann::json& json);

}  // namespace strokelab::report
