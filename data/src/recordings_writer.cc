// Writing campaign directories (strokelab/data/recordings.h): everything checked before the first
// byte is written, then one CSV per record and manifest.json last.
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "format_number.h"
#include "recordings_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/data/mapping.h"
#include "strokelab/data/recordings.h"

namespace strokelab {
namespace data_internal {

// Integral values as JSON integers (51200, not 51200.0), as the rig writes them.
nlohmann::json ManifestNumber(double value) {
  if (std::abs(value) < 1e15 && value == std::floor(value)) return nlohmann::json(static_cast<std::int64_t>(value));
  return nlohmann::json(value);
}

void WriteWholeFile(const std::filesystem::path& path, std::string_view text) {
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (!file) throw std::runtime_error("cannot open '" + path.string() + "' for writing: " + std::strerror(errno));
  const size_t written = std::fwrite(text.data(), 1, text.size(), file);
  const int closed = std::fclose(file);
  if (written != text.size() || closed != 0)
    throw std::runtime_error("writing '" + path.string() + "' failed: " + std::strerror(errno));
}

std::vector<std::string> RecordFileNames(const Campaign& campaign, double sensitivity, bool rename_records,
                                         const std::string& extension) {
  if (campaign.records.empty()) throw InputError("records", "no records to write");
  std::vector<std::string> files;
  std::map<std::string, size_t> seen;
  for (size_t i = 0; i < campaign.records.size(); ++i) {
    const Recording& record = campaign.records[i];
    const std::string field = "records/" + std::to_string(i);
    std::string file = record.name;
    if (file.empty() || rename_records) {
      char name[32];
      std::snprintf(name, sizeof name, "rec_%03zu", i + 1);
      file = name + (extension.empty() ? std::string(".csv") : extension);
    } else if (!extension.empty()) {
      file = std::filesystem::path(file).replace_extension(extension).string();
    }
    try {
      CheckFileName(file, "");
    } catch (const InputError& e) {
      throw InputError(field + "/name", e.bare_message());
    }
    if (const auto [it, fresh] = seen.emplace(std::filesystem::path(file).lexically_normal().string(), i); !fresh)
      throw InputError(field + "/name",
                       "file name '" + file + "' is also that of records/" + std::to_string(it->second));
    if (file == kManifestName || file == kMappingName)
      throw InputError(field + "/name", "a record cannot be called " + file);
    if (!std::isfinite(record.sample_rate_hz) || record.sample_rate_hz <= 0)
      throw InputError(field + "/sample_rate_hz", "must be a finite number > 0, got " + Num(record.sample_rate_hz));
    if (record.voltage_v.size() != record.response.size())
      throw InputError(field, "voltage and response have different lengths (" +
                                  std::to_string(record.voltage_v.size()) + " and " +
                                  std::to_string(record.response.size()) + ")");
    if (record.voltage_v.size() < 2) throw InputError(field, "a record needs at least 2 samples");
    for (size_t n = 0; n < record.size(); ++n) {
      if (!std::isfinite(record.voltage_v[n]) || !std::isfinite(record.response[n] * sensitivity))
        throw InputError(field, "non-finite sample " + std::to_string(n));
    }
    if (!record.broadband && (!std::isfinite(record.nominal_frequency_hz) || record.nominal_frequency_hz <= 0))
      throw InputError(field + "/nominal_frequency_hz", "a stepped-sine record needs a frequency > 0");
    if (!std::isfinite(record.nominal_amplitude_v) || record.nominal_amplitude_v < 0)
      throw InputError(field + "/nominal_amplitude_v", "must be a finite number >= 0");
    files.push_back(file);
  }

  return files;
}

}  // namespace data_internal

namespace {

using data_internal::CheckFileName;
using data_internal::Num;
using data_internal::Trim;

namespace fs = std::filesystem;
using nlohmann::json;

void AppendNumber(std::string* out, double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value, std::chars_format::general, 10);
  out->append(buffer, result.ptr);
}

std::optional<FieldError> ColumnNameError(const std::string& name, const char* field) {
  if (name.empty()) return FieldError{field, "must not be empty"};
  if (name.find_first_of(",\"\r\n") != std::string::npos)
    return FieldError{field, "'" + name + "' holds a comma, quote or line break"};
  if (name == "time_s") return FieldError{field, "'time_s' is the time column"};
  if (Trim(name) != name) return FieldError{field, "'" + name + "' starts or ends with a blank"};
  return std::nullopt;
}

}  // namespace

std::optional<FieldError> WriteOptions::IsValid() const {
  if (!std::isfinite(sensitivity))
    return FieldError{"sensitivity", "must be a finite number (0: the default), got " + Num(sensitivity)};
  if (auto error = ColumnNameError(voltage_column, "voltage_column")) return error;
  if (!response_column.empty()) {
    if (auto error = ColumnNameError(response_column, "response_column")) return error;
    if (response_column == voltage_column) return FieldError{"response_column", "is the voltage column too"};
  }
  return std::nullopt;
}

void WriteCampaign(const Campaign& campaign, const fs::path& dir, const WriteOptions& options) {
  Validate(options);
  const double sensitivity = options.sensitivity != 0 ? options.sensitivity : DefaultSensitivity(campaign.response);
  const std::string response_column = options.response_column.empty()
                                          ? std::string(ToString(campaign.response)) + "_sensor_V"
                                          : options.response_column;
  if (response_column == options.voltage_column) throw InputError("response_column", "is the voltage column too");
  if (campaign.records.empty()) throw InputError("records", "no records to write");

  const std::vector<std::string> files =
      data_internal::RecordFileNames(campaign, sensitivity, options.rename_records, "");

  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error("cannot create '" + dir.string() + "': " + ec.message());

  const double sample_rate_hz = campaign.records.front().sample_rate_hz;
  nlohmann::ordered_json voltage = {
      {"column", options.voltage_column}, {"unit", "V"}, {"note", "drive voltage measured before the power amplifier"}};
  nlohmann::ordered_json response = {
      {"column", response_column}, {"unit", "V"}, {SensitivityKey(campaign.response), data_internal::ManifestNumber(sensitivity)}};
  if (!campaign.absolute_scale) response["nominal"] = true;
  std::string manifest = "{\n";
  manifest += "  \"format\": " + json(kRecordingsFormat).dump() + ",\n";
  manifest += "  \"actuator\": " + json(options.actuator.empty() ? campaign.actuator : options.actuator).dump() + ",\n";
  manifest += "  \"sample_rate_hz\": " + data_internal::ManifestNumber(sample_rate_hz).dump() + ",\n";
  manifest += "  \"channels\": {\n";
  manifest += "    \"voltage\": " + voltage.dump() + ",\n";
  manifest += "    " + json(ToString(campaign.response)).dump() + ": " + response.dump() + "\n";
  manifest += "  },\n  \"records\": [\n";
  for (size_t i = 0; i < campaign.records.size(); ++i) {
    const Recording& record = campaign.records[i];
    nlohmann::ordered_json entry = {{"file", files[i]}};
    if (record.broadband) {
      entry["excitation"] = "broadband";
      if (record.nominal_amplitude_v > 0) entry["drive_amplitude_v"] = data_internal::ManifestNumber(record.nominal_amplitude_v);
    } else {
      entry["drive_frequency_hz"] = data_internal::ManifestNumber(record.nominal_frequency_hz);
      entry["drive_amplitude_v"] = data_internal::ManifestNumber(record.nominal_amplitude_v);
    }
    if (record.sample_rate_hz != sample_rate_hz) entry["sample_rate_hz"] = data_internal::ManifestNumber(record.sample_rate_hz);
    manifest += "    " + entry.dump() + (i + 1 < campaign.records.size() ? ",\n" : "\n");
  }
  manifest += "  ]\n}\n";

  std::string text;
  for (size_t i = 0; i < campaign.records.size(); ++i) {
    const Recording& record = campaign.records[i];
    text.clear();
    text.reserve(record.size() * 48 + 64);
    text += "time_s," + options.voltage_column + "," + response_column + "\n";
    for (size_t n = 0; n < record.size(); ++n) {
      AppendNumber(&text, static_cast<double>(n) / record.sample_rate_hz);
      text += ',';
      AppendNumber(&text, record.voltage_v[n]);
      text += ',';
      AppendNumber(&text, record.response[n] * sensitivity);
      text += '\n';
    }
    const fs::path path = dir / files[i];
    if (path.has_parent_path()) fs::create_directories(path.parent_path(), ec);
    data_internal::WriteWholeFile(path, text);
  }
  data_internal::WriteWholeFile(dir / kManifestName, manifest);
}

}  // namespace strokelab
