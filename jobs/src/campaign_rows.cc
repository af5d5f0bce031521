// A remote worker's rows for a fit or diagnose task, checked and turned into the rows stored
// (task_rows.h).
#include <cmath>
#include <utility>

#include "campaign_rows_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/jobs/task_rows.h"
#include "strokelab/model/model_json.h"
#include "strokelab/report/diagnosis_data.h"

namespace strokelab::jobs {
namespace {

using nlohmann::json;

constexpr size_t kMaxFitResultBytes = 16 << 20;

void RequireOneRow(const std::vector<ResultRow>& rows, const std::string& table, const std::string& type) {
  if (rows.size() != 1) throw InputError("/rows", "a " + type + " task sends one row, table '" + table + "'");
  if (rows[0].table != table)
    throw InputError("/rows/0/table", "a " + type + " task sends table '" + table + "', not '" + rows[0].table + "'");
  if (!rows[0].values.is_object()) throw InputError("/rows/0/values", "must be an object");
}

void RequireFiniteNumbers(const json& value, const std::string& pointer) {
  if (value.is_number_float() && !std::isfinite(value.get<double>())) throw InputError(pointer, "must be a finite number");
  if (value.is_structured())
    for (const auto& [key, child] : value.items()) RequireFiniteNumbers(child, pointer + "/" + key);
}

}  // namespace

std::vector<ResultRow> CampaignRowsFromWorker(const json& task, std::vector<ResultRow> rows) {
  const std::string type = task.at("type");
  if (type == "fit") {
    RequireOneRow(rows, "fit", type);
    const json& fit = rows[0].values;
    RequireFiniteNumbers(fit, "/rows/0/values");
    if (fit.dump().size() > kMaxFitResultBytes) throw InputError("/rows/0/values", "is larger than 16 MiB");
    if (!fit.contains("parameters") || !fit["parameters"].is_object())
      throw InputError("/rows/0/values/parameters", "must be an object");
    if (!fit.contains("model")) throw InputError("/rows/0/values/model", "is missing");
    (void)ModelFromJson(fit["model"], "/rows/0/values/model");
    return rows;
  }
  if (type != "diagnose") throw InputError("/rows", "a " + type + " task is not a campaign task");
  // A campaign of broadband records only is diagnosed by its time series (jobs.cc), the others by
  // their stepped sines: the worker's row says which.
  const bool broadband = rows.size() == 1 && rows[0].table == "broadband_diagnosis_data";
  RequireOneRow(rows, broadband ? "broadband_diagnosis_data" : "diagnosis_data", type);
  // The member a worker's data spoils, as a pointer into its completion.
  const auto read = [&](auto from_json) {
    try {
      return from_json(rows[0].values);
    } catch (const InputError& e) {
      throw InputError("/rows/0/values" + e.field(), e.bare_message());
    }
  };
  if (broadband) {
    report::BroadbandDiagnosisData data = read(report::BroadbandDiagnosisDataFromJson);
    return BroadbandDiagnosisRows(data.diagnosis, std::move(data.base_fit), data.maps);
  }
  const report::DiagnosisData data = read(report::DiagnosisDataFromJson);
  return DiagnosisRows(data.diagnosis, data.maps);
}

}  // namespace strokelab::jobs
