// A diagnosis with its maps as plain data, and back: what a remote worker sends for a diagnose task
// (table "diagnosis_data", or "broadband_diagnosis_data" for a campaign of broadband records only), from which the server writes the result document (DiagnosisToJson) and
// renders the report itself (WriteDiagnosisReport), so that no markup a worker wrote is ever served.
// The document holds every field those two read, so both come out as from the worker's own Diagnosis
// (tests/server/remote_campaign_test.cc renders both ways and compares).
#pragma once

#include <nlohmann/json.hpp>

#include "strokelab/diagnose/broadband_diagnose.h"
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

// The same for a broadband diagnosis (diagnose/broadband_diagnose.h). Its base fit comes as what the
// report and the job's warnings read (the fit's kind, response and scale, whether it converged and
// was rejected, its parameters) and as its result document (BroadbandCampaignFitToJson: an object with
// its "parameters" object, at most 16 MiB), which the server serves as JSON only, as a remote fit's.
struct BroadbandDiagnosisData {
  BroadbandDiagnosis diagnosis;  // its base fit: the members named above
  nlohmann::json base_fit;       // the base fit's document, for BroadbandDiagnosisToJson
  DiagnosisMaps maps;
};
nlohmann::json BroadbandDiagnosisDataToJson(const BroadbandDiagnosis& diagnosis, const DiagnosisMaps& maps);
BroadbandDiagnosisData BroadbandDiagnosisDataFromJson(const nlohmann::json& json);

}  // namespace strokelab::report
