// The JSON both diagnoses' data (diagnosis_data.h) are written as and read from: each member read is
// checked (present, of its type, finite or null, within its size limit) and refused naming its JSON
// pointer. Private to the report library.
#pragma once

#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include <nlohmann/json.hpp>

#include "strokelab/diagnose/diagnose.h"
#include "strokelab/report/diagnosis_maps.h"

namespace strokelab::report::data_json {

using nlohmann::json;

constexpr size_t kMaxItems = 100'000;  // any array: records, points, candidates, ...
constexpr size_t kMaxTextBytes = 64 << 10;

// ---- Writing (non-finite numbers as null) ----
json ParametersOut(const std::vector<FitParameter>& parameters);
json FiguresOut(const FitFigures& f);
json EffectsOut(const std::vector<Effect>& effects);
json SweepOut(const std::optional<SweepResult>& sweep);
json AxisOut(const GridAxis& axis);
json CandidatesOut(const std::vector<CandidateFit>& candidates);
json EvidenceOut(const std::vector<Evidence>& evidence);
json MapsOut(const DiagnosisMaps& maps);

// ---- Reading member `key` of `object` (at pointer `at`) ----
const json& Member(const json& object, const char* key, const std::string& at);
double Number(const json& object, const char* key, const std::string& at);  // null: NaN
int64_t Integer(const json& object, const char* key, const std::string& at, int64_t min, int64_t max);
bool Flag(const json& object, const char* key, const std::string& at);
std::string Text(const json& value, const std::string& at);
std::string Text(const json& object, const char* key, const std::string& at);
// The array at `key` (its pointer in *pointer), within `limit` items.
const json& Array(const json& object, const char* key, const std::string& at, std::string* pointer,
                  size_t limit = kMaxItems);

// Each item of the array at `key`, read by read(item, the item's pointer), within `limit` items.
template <class Read>
auto ItemsIn(const json& object, const char* key, const std::string& at, Read read, size_t limit = kMaxItems) {
  std::string p;
  const json& items = Array(object, key, at, &p, limit);
  std::vector<std::invoke_result_t<Read, const json&, const std::string&>> out;
  out.reserve(items.size());
  for (size_t i = 0; i < items.size(); ++i) out.push_back(read(items[i], p + "/" + std::to_string(i)));
  return out;
}

std::vector<std::string> Texts(const json& object, const char* key, const std::string& at);
// Finite numbers; with `null_is_nan`, nulls too (read as NaN).
std::vector<double> Numbers(const json& object, const char* key, const std::string& at, bool null_is_nan = false);
// The items of array `v` (at pointer `at`): finite numbers, or null read as NaN.
std::vector<double> NullableNumbers(const json& v, const std::string& at);
Effect EffectAt(const json& value, const std::string& at);
std::vector<Effect> EffectsIn(const json& object, const char* key, const std::string& at);
std::vector<FitParameter> ParametersIn(const json& object, const char* key, const std::string& at);
FitFigures FiguresIn(const json& object, const char* key, const std::string& at);
ActuatorModel ModelIn(const json& object, const char* key, const std::string& at);
std::optional<SweepResult> SweepIn(const json& object, const char* key, const std::string& at);
GridAxis AxisIn(const json& object, const char* key, const std::string& at);
std::vector<EffectCurve> CurvesIn(const json& object, const char* key, const std::string& at);
// Members "model_kind" (paper or linear) and "response" of a base fit.
FitModelKind ModelKindIn(const json& object, const std::string& at);
ResponseKind ResponseIn(const json& object, const std::string& at);
std::vector<CandidateFit> CandidatesIn(const json& object, const char* key, const std::string& at);
std::vector<Evidence> EvidenceIn(const json& object, const char* key, const std::string& at);
// Member "chosen": -1 or an index into the `candidates`, and a candidate exactly when effects are `named`.
int ChosenIn(const json& object, const std::string& at, size_t candidates, bool named);
// Member "maps" of the document.
DiagnosisMaps MapsIn(const json& document);
void RequireIndex(int64_t index, size_t size, const std::string& at);

}  // namespace strokelab::report::data_json
