// manifest.json of a campaign directory (strokelab/data/recordings.h): its channels and records
// parsed and checked, every error naming the JSON pointer of the offending value.
#include <cmath>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "format_number.h"
#include "recordings_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/data/recordings.h"

namespace strokelab {
namespace data_internal {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr ResponseKind kResponseKinds[] = {ResponseKind::kForce, ResponseKind::kAcceleration, ResponseKind::kVelocity,
                                           ResponseKind::kDisplacement};

std::string Quote(std::string_view text) {
  std::string out = "'";
  out.append(text);
  return out += "'";
}

std::string TypeName(const json& value) { return value.type_name(); }

std::string ChannelColumn(const json& channel, const std::string& pointer) {
  if (!channel.is_object()) ManifestError(pointer, "expected an object {\"column\": ..., \"unit\": \"V\"}");
  const json* column = Find(channel, "column");
  if (!column) ManifestError(pointer + "/column", "missing: the CSV column that holds this channel");
  if (!column->is_string() || column->get<std::string>().empty())
    ManifestError(pointer + "/column", "expected a non-empty column name");
  const std::string name = column->get<std::string>();
  if (name == "time_s") ManifestError(pointer + "/column", "'time_s' is the time column, not a channel");
  if (const json* unit = Find(channel, "unit")) {
    if (!unit->is_string() || unit->get<std::string>() != "V")
      ManifestError(pointer + "/unit", "channels are recorded in volts (\"V\"), got " + unit->dump());
  }
  return name;
}

}  // namespace

[[noreturn]] void DocumentError(const char* document, const std::string& pointer, const std::string& message) {
  throw InputError(std::string(document) + (pointer.empty() ? "" : ":" + pointer), message);
}

[[noreturn]] void ManifestError(const std::string& pointer, const std::string& message) {
  DocumentError(kManifestName, pointer, message);
}

const json* Find(const json& object, const char* key) {
  const auto it = object.find(key);
  return it == object.end() ? nullptr : &*it;
}

double RequirePositiveRate(const json& value, const std::string& pointer, const char* document) {
  if (!value.is_number()) DocumentError(document, pointer, "expected a number [Hz], got " + TypeName(value));
  const double rate = value.get<double>();
  if (!std::isfinite(rate) || rate <= 0)
    DocumentError(document, pointer, "must be a finite number > 0, got " + Num(rate));
  return rate;
}

Channels ParseChannels(const json& manifest) {
  const json* channels = Find(manifest, "channels");
  if (!channels) ManifestError("/channels", "missing: expected \"voltage\" and one response channel");
  if (!channels->is_object()) ManifestError("/channels", "expected an object naming the channels");
  Channels out;
  bool have_voltage = false, have_response = false;
  std::string response_name;
  for (const auto& [name, channel] : channels->items()) {
    const std::string pointer = "/channels/" + name;
    if (name == "voltage") {
      out.voltage_column = ChannelColumn(channel, pointer);
      have_voltage = true;
      continue;
    }
    ResponseKind kind;
    try {
      kind = ParseResponseKind(name);
    } catch (const InputError&) {
      ManifestError(pointer,
                    "unknown channel '" + name + "' (known: voltage, force, acceleration, velocity, displacement)");
    }
    if (have_response)
      ManifestError(pointer, "a second response channel ('" + response_name +
                                 "' is one already); a campaign records exactly one");
    have_response = true;
    response_name = name;
    out.kind = kind;
    out.response_column = ChannelColumn(channel, pointer);
    for (ResponseKind other : kResponseKinds) {
      if (other != kind && Find(channel, SensitivityKey(other)))
        ManifestError(pointer + "/" + SensitivityKey(other), std::string("is the key of ") + ToString(other) +
                                                                 " channels; a " + name + " channel takes " +
                                                                 SensitivityKey(kind));
    }
    const json* sensitivity = Find(channel, SensitivityKey(kind));
    if (!sensitivity) ManifestError(pointer, std::string("missing ") + SensitivityKey(kind));
    const std::string sensitivity_pointer = pointer + "/" + SensitivityKey(kind);
    if (!sensitivity->is_number())
      ManifestError(sensitivity_pointer, "expected a number, got " + TypeName(*sensitivity));
    out.sensitivity = sensitivity->get<double>();
    if (!std::isfinite(out.sensitivity) || out.sensitivity == 0)
      ManifestError(sensitivity_pointer, "must be a finite number other than 0, got " + Num(out.sensitivity));
    if (const json* nominal = Find(channel, "nominal")) {
      if (!nominal->is_boolean()) ManifestError(pointer + "/nominal", "expected true or false");
      out.nominal = nominal->get<bool>();
    }
  }
  if (!have_voltage) ManifestError("/channels", "no 'voltage' channel");
  if (!have_response)
    ManifestError("/channels", "no response channel (one of force, acceleration, velocity, displacement)");
  if (out.voltage_column == out.response_column)
    ManifestError("/channels/" + response_name + "/column",
                  "'" + out.response_column + "' is the voltage channel's column too");
  return out;
}

// A relative path inside the campaign directory.
void CheckFileName(const std::string& file, const std::string& pointer) {
  const fs::path path(file);
  if (path.is_absolute() || path.has_root_name() || path.has_root_directory())
    ManifestError(pointer, "'" + file + "' is not a path relative to the campaign directory");
  for (const fs::path& part : path) {
    if (part == "..") ManifestError(pointer, "'" + file + "' leaves the campaign directory");
  }
  if (file.back() == '/') ManifestError(pointer, "'" + file + "' names a directory");
}

void ParseExcitation(const json& record, RecordSpec* out, const char* document) {
  RecordSpec& spec = *out;
  if (const json* excitation = Find(record, "excitation")) {
    const std::string text = excitation->is_string() ? excitation->get<std::string>() : excitation->dump();
    if (text == "broadband")
      spec.broadband = true;
    else if (text != "stepped-sine" && text != "stepped_sine" && text != "sine")
      DocumentError(document, spec.pointer + "/excitation",
                    "unknown excitation " + Quote(text) + " (known: stepped-sine, broadband)");
  }
  const json* frequency = Find(record, "drive_frequency_hz");
  const json* amplitude = Find(record, "drive_amplitude_v");
  if (spec.broadband) {
    if (frequency)
      DocumentError(document, spec.pointer + "/drive_frequency_hz", "a broadband record has no nominal drive frequency");
  } else {
    if (!frequency)
      DocumentError(document, spec.pointer + "/drive_frequency_hz",
                    "missing (a stepped-sine step; write \"excitation\": \"broadband\" for other drives)");
    if (!frequency->is_number())
      DocumentError(document, spec.pointer + "/drive_frequency_hz", "expected a number [Hz], got " + TypeName(*frequency));
    spec.frequency_hz = frequency->get<double>();
    if (!std::isfinite(spec.frequency_hz) || spec.frequency_hz <= 0)
      DocumentError(document, spec.pointer + "/drive_frequency_hz",
                    "must be a finite number > 0, got " + Num(spec.frequency_hz));
    if (!amplitude) DocumentError(document, spec.pointer + "/drive_amplitude_v", "missing (a stepped-sine step)");
  }
  if (amplitude) {
    if (!amplitude->is_number())
      DocumentError(document, spec.pointer + "/drive_amplitude_v", "expected a number [V], got " + TypeName(*amplitude));
    spec.amplitude_v = amplitude->get<double>();
    if (!std::isfinite(spec.amplitude_v) || spec.amplitude_v < 0)
      DocumentError(document, spec.pointer + "/drive_amplitude_v",
                    "must be a finite number >= 0, got " + Num(spec.amplitude_v));
  }
}

std::vector<RecordSpec> ParseRecords(const json& manifest, double sample_rate_hz) {
  const json* records = Find(manifest, "records");
  if (!records) ManifestError("/records", "missing: expected a list of records");
  if (!records->is_array()) ManifestError("/records", "expected a list of records");
  if (records->empty()) ManifestError("/records", "no records");
  std::vector<RecordSpec> out;
  std::map<std::string, std::string> files;  // file -> pointer of its first use
  for (size_t i = 0; i < records->size(); ++i) {
    const json& record = (*records)[i];
    RecordSpec spec;
    spec.pointer = "/records/" + std::to_string(i);
    if (!record.is_object()) ManifestError(spec.pointer, "expected an object {\"file\": ..., ...}");
    const json* file = Find(record, "file");
    if (!file) ManifestError(spec.pointer + "/file", "missing: the record's CSV file");
    if (!file->is_string() || file->get<std::string>().empty())
      ManifestError(spec.pointer + "/file", "expected a file name");
    spec.file = file->get<std::string>();
    CheckFileName(spec.file, spec.pointer + "/file");
    const std::string normal = fs::path(spec.file).lexically_normal().string();
    if (const auto [it, fresh] = files.emplace(normal, spec.pointer); !fresh)
      ManifestError(spec.pointer + "/file", "duplicate file name '" + spec.file + "' (also " + it->second + ")");

    spec.sample_rate_hz = sample_rate_hz;
    if (const json* rate = Find(record, "sample_rate_hz")) {
      spec.sample_rate_hz = RequirePositiveRate(*rate, spec.pointer + "/sample_rate_hz");
      spec.rate_from_record = true;
    }
    ParseExcitation(record, &spec, kManifestName);
    out.push_back(std::move(spec));
  }
  return out;
}

}  // namespace data_internal

const char* SensitivityKey(ResponseKind kind) {
  switch (kind) {
    case ResponseKind::kForce: return "sensitivity_V_per_N";
    case ResponseKind::kAcceleration: return "sensitivity_V_per_m_s2";
    case ResponseKind::kVelocity: return "sensitivity_V_per_m_s";
    case ResponseKind::kDisplacement: return "sensitivity_V_per_m";
  }
  return "sensitivity";
}

double DefaultSensitivity(ResponseKind kind) {
  switch (kind) {
    case ResponseKind::kForce: return 0.02248;
    case ResponseKind::kAcceleration: return 0.0102;
    case ResponseKind::kVelocity: return 1.0;
    case ResponseKind::kDisplacement: return 1000.0;
  }
  return 1.0;
}

}  // namespace strokelab
