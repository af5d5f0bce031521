// Checking a worker's rows against its task (task_rows.h).
#include "strokelab/jobs/task_rows.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

#include "strokelab/base/errors.h"
#include "strokelab/jobs/json_schema.h"

namespace strokelab::jobs {
namespace {

using nlohmann::json;

// The same double as the task's, allowing for a decimal round trip.
bool SameValue(double a, double b) { return std::abs(a - b) <= 1e-12 * std::max(std::abs(a), std::abs(b)); }

// `sorted`: the grid in ascending order. A value within the tolerance of a grid value lies beside
// the first grid value not below it (grid steps are far wider than 1e-12 relative).
bool OnGrid(double value, const std::vector<double>& sorted) {
  const auto at = std::lower_bound(sorted.begin(), sorted.end(), value);
  return (at != sorted.end() && SameValue(value, *at)) || (at != sorted.begin() && SameValue(value, *(at - 1)));
}

std::vector<double> Sorted(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v;
}

// The first non-finite number under `value` (JSON text cannot hold one, but 1e999 parses to inf).
void RequireFinite(const json& value, const std::string& pointer) {
  if (value.is_number_float() && !std::isfinite(value.get<double>())) throw InputError(pointer, "must be a finite number");
  if (value.is_structured())
    for (const auto& [key, child] : value.items()) RequireFinite(child, pointer + "/" + key);
}

// The schema of one row definition, built once per definition: copying the result schema's
// definitions for every row cost far more than checking the row (a completion has thousands).
const json& DefinitionSchema(const std::string& definition) {
  static const std::map<std::string, json> schemas = [] {
    std::map<std::string, json> m;
    const json& defs = BuiltInSchema("result").at("$defs");
    for (const auto& [name, unused] : defs.items()) m[name] = {{"$defs", defs}, {"$ref", "#/$defs/" + name}};
    return m;
  }();
  return schemas.at(definition);
}

void RequireDefinition(const json& values, const std::string& definition, const std::string& pointer) {
  if (const std::optional<SchemaViolation> v = ValidateAgainstSchema(DefinitionSchema(definition), values))
    throw InputError(pointer + v->pointer, v->message + " (a " + definition + " row)");
}

void RequireNumberOn(const json& values, const char* key, const std::vector<double>& grid, const std::string& pointer) {
  if (!OnGrid(values.at(key).get<double>(), grid))
    throw InputError(pointer + "/" + key, "is not on the task's grid");
}

}  // namespace

void ValidateTaskRows(const json& task, const std::vector<ResultRow>& rows) {
  const std::string type = task.at("type");
  const auto table_of = [&](size_t i, const std::vector<std::string>& allowed) {
    if (std::find(allowed.begin(), allowed.end(), rows[i].table) == allowed.end())
      throw InputError("/rows/" + std::to_string(i) + "/table",
                       "a " + type + " task writes no table '" + rows[i].table + "'");
    return rows[i].table;
  };
  for (size_t i = 0; i < rows.size(); ++i) RequireFinite(rows[i].values, "/rows/" + std::to_string(i) + "/values");
  if (type == "sweep_row") {
    const std::vector<double> frequencies = Sorted(task.at("frequencies_hz").get<std::vector<double>>());
    const std::vector<double> amplitude = {task.at("amplitude_v").get<double>()};
    const std::vector<double> span = {frequencies.front(), frequencies.back()};
    for (size_t i = 0; i < rows.size(); ++i) {
      const std::string at = "/rows/" + std::to_string(i) + "/values";
      const json& v = rows[i].values;
      if (table_of(i, {"points", "jumps"}) == "points") {
        RequireDefinition(v, "sweep_point", at);
        RequireNumberOn(v, "frequency_hz", frequencies, at);
      } else {
        RequireDefinition(v, "jump_interval", at);
        for (const char* edge : {"bistable_from_hz", "bistable_to_hz"})
          if (v.at(edge).get<double>() < span.front() * (1 - 1e-12) || v.at(edge).get<double>() > span.back() * (1 + 1e-12))
            throw InputError(at + "/" + edge, "is outside the task's frequencies");
      }
      RequireNumberOn(v, "amplitude_v", amplitude, at);
    }
  } else if (type == "sweep_columns") {
    const std::vector<double> frequencies = task.at("frequencies_hz").get<std::vector<double>>();
    if (rows.size() != frequencies.size())
      throw InputError("/rows", "expected " + std::to_string(frequencies.size()) + " thresholds, one per frequency");
    for (size_t i = 0; i < rows.size(); ++i) {
      const std::string at = "/rows/" + std::to_string(i) + "/values";
      table_of(i, {"thresholds"});
      RequireDefinition(rows[i].values, "saturation_threshold", at);
      RequireNumberOn(rows[i].values, "frequency_hz", {frequencies[i]}, at);
    }
  } else if (type == "simulate") {
    if (rows.size() != 1) throw InputError("/rows", "expected one record");
    table_of(0, {"records"});
    RequireDefinition(rows[0].values, "simulate_record", "/rows/0/values");
    RequireNumberOn(rows[0].values, "frequency_hz", {task.at("frequency_hz").get<double>()}, "/rows/0/values");
    RequireNumberOn(rows[0].values, "amplitude_v", {task.at("amplitude_v").get<double>()}, "/rows/0/values");
  } else {
    throw InputError("/rows", "a " + type + " task is not completed by remote workers");
  }
}

}  // namespace strokelab::jobs
