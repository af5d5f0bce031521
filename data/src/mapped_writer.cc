// Writing a campaign as UFF dataset 58 or WAV files plus mapping.json (strokelab/data/mapping.h):
// everything checked before the first byte is written, mapping.json last.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "mapping_internal.h"
#include "recordings_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/data/mapping.h"
#include "strokelab/data/uff58.h"
#include "strokelab/data/wav.h"

namespace strokelab {
namespace {

namespace fs = std::filesystem;
using data_internal::ManifestNumber;

// Record 9's specific data type of a response kind.
int UffDataType(ResponseKind kind) {
  switch (kind) {
    case ResponseKind::kForce: return 9;  // reaction force (the blocked force)
    case ResponseKind::kAcceleration: return 12;
    case ResponseKind::kVelocity: return 11;
    case ResponseKind::kDisplacement: return 8;
  }
  return 0;
}
// Volts at full scale for `values` written as `format`: 1 for floats (the values are volts), else
// the largest |value| on the top code (2^(bits-1) - 1).
double FullScaleVolts(const std::vector<double>& values, WavSampleFormat format) {
  if (format == WavSampleFormat::kFloat32) return 1.0;
  double peak = 0.0;
  for (double value : values) peak = std::max(peak, std::abs(value));
  if (peak == 0) return 1.0;
  const double codes = std::ldexp(1.0, WavBits(format) - 1);
  return peak * codes / (codes - 1.0);
}

}  // namespace

const char* ToString(CampaignFormat format) {
  switch (format) {
    case CampaignFormat::kCsv: return "csv";
    case CampaignFormat::kUff58: return "uff58";
    case CampaignFormat::kUff58Binary: return "uff58b";
    case CampaignFormat::kWav: return "wav";
  }
  return "?";
}

CampaignFormat ParseCampaignFormat(const std::string& text, const std::string& field) {
  if (text == "csv") return CampaignFormat::kCsv;
  if (text == "uff58" || text == "uff") return CampaignFormat::kUff58;
  if (text == "uff58b") return CampaignFormat::kUff58Binary;
  if (text == "wav") return CampaignFormat::kWav;
  throw InputError(field, "unknown campaign format '" + text + "' (csv, uff58, uff58b, wav)");
}

void WriteMappedCampaign(const Campaign& campaign, const fs::path& dir, const MappedWriteOptions& options) {
  if (options.format == CampaignFormat::kCsv)
    throw InputError("format", "a CSV campaign is written by WriteCampaign (recordings.h)");
  if (!std::isfinite(options.sensitivity))
    throw InputError("sensitivity", "must be a finite number (0: the default)");
  const bool wav = options.format == CampaignFormat::kWav;
  const double sensitivity = options.sensitivity != 0 ? options.sensitivity : DefaultSensitivity(campaign.response);
  const std::vector<std::string> files =
      data_internal::RecordFileNames(campaign, wav ? sensitivity : 1.0, options.rename_records, wav ? ".wav" : ".uff");
  for (size_t i = 0; i < campaign.records.size() && wav; ++i) {
    const double rate = campaign.records[i].sample_rate_hz;
    if (rate != std::floor(rate) || rate > 4294967295.0)
      throw InputError("records/" + std::to_string(i) + "/sample_rate_hz",
                       "a WAV file holds a whole number of Hz, got " + std::to_string(rate));
  }
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error("cannot create '" + dir.string() + "': " + ec.message());

  const double sample_rate_hz = campaign.records.front().sample_rate_hz;
  nlohmann::ordered_json response = {{"kind", ToString(campaign.response)}};
  if (wav) {
    response[SensitivityKey(campaign.response)] = ManifestNumber(sensitivity);
    response["channel"] = 2;
  } else {
    response["dataset"] = 2;
  }
  if (!campaign.absolute_scale) response["nominal"] = true;
  nlohmann::ordered_json mapping = {{"format", kMappingFormat},
                                    {"actuator", campaign.actuator},
                                    {"sample_rate_hz", ManifestNumber(sample_rate_hz)},
                                    {"voltage", wav ? nlohmann::ordered_json{{"channel", 1}}
                                                    : nlohmann::ordered_json{{"dataset", 1}}},
                                    {"response", response},
                                    {"records", nlohmann::ordered_json::array()}};
  std::string bytes;
  std::vector<double> sensor_v;
  for (size_t i = 0; i < campaign.records.size(); ++i) {
    const Recording& record = campaign.records[i];
    nlohmann::ordered_json entry = {{"file", files[i]}};
    if (record.broadband) {
      entry["excitation"] = "broadband";
      if (record.nominal_amplitude_v > 0) entry["drive_amplitude_v"] = ManifestNumber(record.nominal_amplitude_v);
    } else {
      entry["drive_frequency_hz"] = ManifestNumber(record.nominal_frequency_hz);
      entry["drive_amplitude_v"] = ManifestNumber(record.nominal_amplitude_v);
    }
    if (record.sample_rate_hz != sample_rate_hz) entry["sample_rate_hz"] = ManifestNumber(record.sample_rate_hz);
    bytes.clear();
    if (wav) {
      sensor_v.resize(record.size());
      for (size_t n = 0; n < record.size(); ++n) sensor_v[n] = record.response[n] * sensitivity;
      const double voltage_full_scale = FullScaleVolts(record.voltage_v, options.wav_format);
      const double response_full_scale = FullScaleVolts(sensor_v, options.wav_format);
      std::vector<double> voltage_fraction(record.voltage_v);
      for (double& value : voltage_fraction) value /= voltage_full_scale;
      for (double& value : sensor_v) value /= response_full_scale;
      bytes = EncodeWav({&voltage_fraction, &sensor_v}, static_cast<std::uint32_t>(record.sample_rate_hz),
                        options.wav_format);
      if (voltage_full_scale != 1.0) entry["voltage"] = {{"full_scale_v", voltage_full_scale}};
      if (response_full_scale != 1.0) entry["response"] = {{"full_scale_v", response_full_scale}};
    } else {
      const bool binary = options.format == CampaignFormat::kUff58Binary;
      UffWriteSeries voltage;
      voltage.id1 = "voltage";
      voltage.sample_rate_hz = record.sample_rate_hz;
      voltage.ordinate_units = "V";
      voltage.values = &record.voltage_v;
      AppendUff58(&bytes, voltage, binary);
      UffWriteSeries response_series;
      response_series.id1 = ToString(campaign.response);
      response_series.sample_rate_hz = record.sample_rate_hz;
      response_series.ordinate_data_type = UffDataType(campaign.response);
      response_series.ordinate_units = data_internal::SiUnit(campaign.response);
      response_series.values = &record.response;
      AppendUff58(&bytes, response_series, binary);
    }
    const fs::path path = dir / files[i];
    if (path.has_parent_path()) fs::create_directories(path.parent_path(), ec);
    data_internal::WriteWholeFile(path, bytes);
    mapping["records"].push_back(entry);
  }
  data_internal::WriteWholeFile(dir / kMappingName, mapping.dump(2) + "\n");
}

}  // namespace strokelab
