// mapping.json of a mapped campaign (strokelab/data/mapping.h): the response's kind, sensitivity and
// unit, the channel selectors and the records, each error at its JSON pointer.
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "format_number.h"
#include "mapping_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/data/mapping.h"

namespace strokelab::data_internal {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

[[noreturn]] void MappingError(const std::string& pointer, const std::string& message) {
  DocumentError(kMappingName, pointer, message);
}

constexpr ResponseKind kMappedKinds[] = {ResponseKind::kForce, ResponseKind::kAcceleration, ResponseKind::kVelocity,
                                         ResponseKind::kDisplacement};

long long PositiveIndex(const json& value, const std::string& pointer) {
  if (!value.is_number_integer() || value.get<long long>() < 1)
    MappingError(pointer, "expected a whole number >= 1 (counted from 1), got " + value.dump());
  return value.get<long long>();
}

// The selector fields of `object` over `base` (the defaults).
void ApplySelector(const json& object, const std::string& pointer, Selector* selector) {
  if (!object.is_object()) MappingError(pointer, "expected an object {\"dataset\": K} or {\"channel\": C, ...}");
  if (const json* dataset = Find(object, "dataset")) {
    selector->dataset = PositiveIndex(*dataset, pointer + "/dataset");
    selector->channel = 0;
  }
  if (const json* channel = Find(object, "channel")) {
    selector->channel = PositiveIndex(*channel, pointer + "/channel");
    if (Find(object, "dataset")) MappingError(pointer, "gives both \"dataset\" (UFF) and \"channel\" (WAV)");
    selector->dataset = 0;
  }
  if (const json* scale = Find(object, "full_scale_v")) {
    if (!scale->is_number() || !std::isfinite(scale->get<double>()) || scale->get<double>() <= 0)
      MappingError(pointer + "/full_scale_v", "expected a finite number > 0 [V at full scale], got " + scale->dump());
    selector->full_scale_v = scale->get<double>();
  }
}

// The physical units a response may be in, per kind, the SI unit first: name and factor to SI.
struct KnownUnit {
  const char* name;
  double to_si;
};
constexpr KnownUnit kForceUnits[] = {{"N", 1.0}, {"kN", 1e3}, {"mN", 1e-3}, {"lbf", 4.4482216152605}};
constexpr KnownUnit kAccelerationUnits[] = {{"m/s^2", 1.0}, {"m/s2", 1.0}, {"mm/s^2", 1e-3}, {"g", 9.80665}};
constexpr KnownUnit kVelocityUnits[] = {{"m/s", 1.0}, {"mm/s", 1e-3}, {"in/s", 0.0254}};
constexpr KnownUnit kDisplacementUnits[] = {{"m", 1.0}, {"mm", 1e-3}, {"um", 1e-6}, {"in", 0.0254}};

std::span<const KnownUnit> UnitsOf(ResponseKind kind) {
  switch (kind) {
    case ResponseKind::kForce: return kForceUnits;
    case ResponseKind::kAcceleration: return kAccelerationUnits;
    case ResponseKind::kVelocity: return kVelocityUnits;
    case ResponseKind::kDisplacement: return kDisplacementUnits;
  }
  return kForceUnits;
}

}  // namespace

std::optional<UnitScale> ParseUnit(const std::string& unit, ResponseKind kind) {
  if (unit == "V" || unit == "v" || unit == "Volt" || unit == "Volts" || unit == "volt" || unit == "volts")
    return UnitScale{true, 1.0};
  if (unit == "mV") return UnitScale{true, 1e-3};
  for (const KnownUnit& known : UnitsOf(kind))
    if (unit == known.name) return UnitScale{false, known.to_si};
  return std::nullopt;
}

const char* SiUnit(ResponseKind kind) { return UnitsOf(kind).front().name; }

std::string KnownUnits(ResponseKind kind) {
  std::string out;
  for (const KnownUnit& known : UnitsOf(kind)) out += (out.empty() ? "" : ", ") + std::string(known.name);
  return out;
}

Mapping ReadMapping(const fs::path& dir) {
  const json mapping = ReadJsonDocument(dir / kMappingName, kMappingName);
  CheckDocumentFormat(mapping, kMappingName, kMappingFormat);

  Mapping out;
  if (const json* actuator = Find(mapping, "actuator")) {
    if (!actuator->is_string()) MappingError("/actuator", "expected a string");
    out.actuator = actuator->get<std::string>();
  }
  double default_rate_hz = 0.0;
  if (const json* rate = Find(mapping, "sample_rate_hz"))
    default_rate_hz = RequirePositiveRate(*rate, "/sample_rate_hz", kMappingName);

  // The response: kind, sensitivity, unit, nominal, default selector.
  const json* response = Find(mapping, "response");
  if (!response) MappingError("/response", "missing: {\"kind\": force|acceleration|velocity|displacement, ...}");
  if (!response->is_object()) MappingError("/response", "expected an object {\"kind\": ..., ...}");
  const json* kind = Find(*response, "kind");
  if (!kind || !kind->is_string())
    MappingError("/response/kind", "missing: one of force, acceleration, velocity, displacement");
  try {
    out.kind = ParseResponseKind(kind->get<std::string>());
  } catch (const InputError&) {
    MappingError("/response/kind",
                 "unknown kind " + kind->dump() + " (known: force, acceleration, velocity, displacement)");
  }
  for (ResponseKind other : kMappedKinds) {
    if (other != out.kind && Find(*response, SensitivityKey(other)))
      MappingError(std::string("/response/") + SensitivityKey(other),
                   std::string("is the key of ") + ToString(other) + " responses; a " + ToString(out.kind) +
                       " response takes " + SensitivityKey(out.kind));
  }
  out.sensitivity_pointer = "/response";
  if (const json* sensitivity = Find(*response, SensitivityKey(out.kind))) {
    out.sensitivity_pointer = std::string("/response/") + SensitivityKey(out.kind);
    if (!sensitivity->is_number() || !std::isfinite(sensitivity->get<double>()) || sensitivity->get<double>() == 0)
      MappingError(out.sensitivity_pointer, "expected a finite number other than 0, got " + sensitivity->dump());
    out.sensitivity = sensitivity->get<double>();
  }
  if (const json* unit = Find(*response, "unit")) {
    if (!unit->is_string() || !ParseUnit(unit->get<std::string>(), out.kind))
      MappingError("/response/unit", "unknown unit " + unit->dump() + " for a " + ToString(out.kind) +
                                         " response (V, mV, " + KnownUnits(out.kind) + ")");
    out.unit = unit->get<std::string>();
  }
  if (const json* nominal = Find(*response, "nominal")) {
    if (!nominal->is_boolean()) MappingError("/response/nominal", "expected true or false");
    out.nominal = nominal->get<bool>();
  }
  Selector voltage_default, response_default;
  if (const json* voltage = Find(mapping, "voltage")) ApplySelector(*voltage, "/voltage", &voltage_default);
  ApplySelector(*response, "/response", &response_default);

  const json* records = Find(mapping, "records");
  if (!records) MappingError("/records", "missing: expected a list of records");
  if (!records->is_array()) MappingError("/records", "expected a list of records");
  if (records->empty()) MappingError("/records", "no records");
  for (size_t i = 0; i < records->size(); ++i) {
    const json& record = (*records)[i];
    MappedRecord mapped;
    RecordSpec& spec = mapped.spec;
    spec.pointer = "/records/" + std::to_string(i);
    if (!record.is_object()) MappingError(spec.pointer, "expected an object {\"file\": ..., ...}");
    const json* file = Find(record, "file");
    if (!file) MappingError(spec.pointer + "/file", "missing: the record's UFF or WAV file");
    if (!file->is_string() || file->get<std::string>().empty())
      MappingError(spec.pointer + "/file", "expected a file name");
    spec.file = file->get<std::string>();
    try {
      CheckFileName(spec.file, "");
    } catch (const InputError& e) {
      MappingError(spec.pointer + "/file", e.bare_message());
    }
    if (spec.file == kMappingName || spec.file == kManifestName)
      MappingError(spec.pointer + "/file", "'" + spec.file + "' is not a data file");
    spec.sample_rate_hz = default_rate_hz;
    mapped.rate_pointer = "/sample_rate_hz";
    if (const json* rate = Find(record, "sample_rate_hz")) {
      mapped.rate_pointer = spec.pointer + "/sample_rate_hz";
      spec.sample_rate_hz = RequirePositiveRate(*rate, mapped.rate_pointer, kMappingName);
      spec.rate_from_record = true;
    }
    ParseExcitation(record, &spec, kMappingName);

    mapped.voltage = voltage_default;
    mapped.response = response_default;
    mapped.voltage.pointer = spec.pointer + "/voltage";
    mapped.response.pointer = spec.pointer + "/response";
    if (const json* voltage = Find(record, "voltage")) ApplySelector(*voltage, mapped.voltage.pointer, &mapped.voltage);
    if (const json* selected = Find(record, "response"))
      ApplySelector(*selected, mapped.response.pointer, &mapped.response);
    for (const Selector* selector : {&mapped.voltage, &mapped.response}) {
      if (selector->dataset == 0 && selector->channel == 0)
        MappingError(selector->pointer, "missing: {\"dataset\": K} (UFF) or {\"channel\": C} (WAV), here or as "
                                        "the mapping's default");
    }
    if (mapped.voltage.dataset == mapped.response.dataset && mapped.voltage.channel == mapped.response.channel)
      MappingError(mapped.response.pointer, "selects the voltage's channel too");
    out.records.push_back(std::move(mapped));
  }
  return out;
}

}  // namespace strokelab::data_internal
