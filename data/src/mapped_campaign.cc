// Reading a mapped campaign (strokelab/data/mapping.h): mapping.json (mapping.cc), each data file it
// names parsed once (UFF or WAV, side by side), then each record's voltage and response taken from
// its file, converted to volts and physical units and checked against each other.
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "format_number.h"
#include "mapping_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/parallel_for.h"
#include "strokelab/data/mapping.h"
#include "strokelab/data/uff58.h"
#include "strokelab/data/wav.h"

namespace strokelab {
namespace {

namespace fs = std::filesystem;
using data_internal::DocumentError;
using data_internal::KnownUnits;
using data_internal::MappedRecord;
using data_internal::Mapping;
using data_internal::Num;
using data_internal::ParseUnit;
using data_internal::Selector;
using data_internal::UnitScale;

using DataFile = std::variant<UffFile, WavFile>;

DataFile ReadDataFile(const fs::path& dir, const std::string& file, const std::string& pointer) {
  std::string bytes;
  if (!data_internal::ReadWholeFile(dir / file, &bytes))
    DocumentError(kMappingName, pointer, "cannot read '" + file + "' in " + dir.string());
  if (bytes.size() >= 4 && bytes.compare(0, 4, "RIFF") == 0) return ParseWav(bytes, file);
  return ParseUff58(bytes, file);
}

// One channel of a record, in volts or in the physical unit of the response, with its rate.
struct Channel {
  std::vector<double> values;
  double sample_rate_hz = 0.0;
  bool rate_is_exact = false;  // WAV: a whole number of Hz as stored; UFF: 1 / a printed increment
  std::string what;            // "dataset 2 of rec_001.uff", for messages
};

// 1 / increment, a whole number of Hz when the increment's printed digits cannot tell them apart.
double RateFromIncrement(double increment_s) {
  const double rate = 1.0 / increment_s;
  const double whole = std::round(rate);
  return whole > 0 && std::abs(rate - whole) <= 5e-6 * rate ? whole : rate;
}

// The selected channel of a record. `response` decides the unit rules (mapping.h).
Channel SelectChannel(const DataFile& data, const std::string& file, const Selector& selector, bool response,
                      const Mapping& mapping) {
  Channel out;
  const char* role = response ? "response" : "voltage";
  if (const auto* wav = std::get_if<WavFile>(&data)) {
    if (selector.channel == 0)
      DocumentError(kMappingName, selector.pointer, "'" + file + "' is a WAV file: select its " + role + " by \"channel\"");
    if (static_cast<size_t>(selector.channel) > wav->channels.size())
      DocumentError(kMappingName, selector.pointer + "/channel",
                    "channel " + std::to_string(selector.channel) + ", but '" + file + "' holds " +
                        std::to_string(wav->channels.size()) + " channel(s)");
    out.values = wav->channels[static_cast<size_t>(selector.channel - 1)];
    for (double& value : out.values) value *= selector.full_scale_v;
    out.sample_rate_hz = wav->sample_rate_hz;
    out.rate_is_exact = true;
    out.what = "channel " + std::to_string(selector.channel) + " of " + file;
    if (response) {
      if (!mapping.sensitivity)
        DocumentError(kMappingName, mapping.sensitivity_pointer,
                      std::string("missing ") + SensitivityKey(mapping.kind) + ": " + out.what +
                          " holds sensor volts (WAV has no units)");
      for (double& value : out.values) value /= *mapping.sensitivity;
    }
    return out;
  }
  const UffFile& uff = std::get<UffFile>(data);
  if (selector.dataset == 0)
    DocumentError(kMappingName, selector.pointer, "'" + file + "' is a UFF file: select its " + role + " by \"dataset\"");
  if (static_cast<size_t>(selector.dataset) > uff.datasets.size())
    DocumentError(kMappingName, selector.pointer + "/dataset",
                  "dataset " + std::to_string(selector.dataset) + ", but '" + file + "' holds " +
                      std::to_string(uff.datasets.size()) + " dataset(s)");
  const UffFile::Entry& entry = uff.datasets[static_cast<size_t>(selector.dataset - 1)];
  if (entry.series < 0)
    DocumentError(kMappingName, selector.pointer + "/dataset",
                  "dataset " + std::to_string(entry.index) + " of '" + file + "' (line " + std::to_string(entry.line) +
                      ") is a dataset " + std::to_string(entry.type) + ", not 58");
  const UffTimeSeries& series = uff.series[static_cast<size_t>(entry.series)];
  out.values = series.values;
  out.sample_rate_hz = RateFromIncrement(series.increment_s);
  out.what = "dataset " + std::to_string(series.index) + " of " + file;
  // Record 9, the ordinate's characteristics, is the 11th line after the opening -1.
  const auto units_error = [&](const std::string& message) {
    throw InputError(file + ":" + std::to_string(series.line + 10),
                     "dataset " + std::to_string(series.index) + (series.binary ? " (58b): " : " (58): ") + message);
  };
  const std::string unit = series.ordinate_units.empty() ? (response ? mapping.unit : "V") : series.ordinate_units;
  const std::optional<UnitScale> scale = ParseUnit(unit, mapping.kind);
  if (!response) {
    if (!scale || !scale->volts) units_error("the voltage's units are '" + unit + "'; the drive must be in volts (V)");
    for (double& value : out.values) value *= scale->to_si;
    return out;
  }
  if (!scale)
    units_error("units '" + unit + "' are not known for a " + std::string(ToString(mapping.kind)) + " response (V, mV, " +
                KnownUnits(mapping.kind) + ")");
  // The specific data type, when it names a quantity, must be the mapping's kind.
  std::optional<ResponseKind> named;
  switch (series.ordinate_data_type) {
    case 8: named = ResponseKind::kDisplacement; break;
    case 9:
    case 13: named = ResponseKind::kForce; break;
    case 11: named = ResponseKind::kVelocity; break;
    case 12: named = ResponseKind::kAcceleration; break;
    default: break;
  }
  if (named && *named != mapping.kind)
    units_error("its specific data type " + std::to_string(series.ordinate_data_type) + " is " + ToString(*named) +
                ", the mapping's response is " + ToString(mapping.kind));
  if (scale->volts) {
    if (!mapping.sensitivity)
      DocumentError(kMappingName, mapping.sensitivity_pointer,
                    std::string("missing ") + SensitivityKey(mapping.kind) + ": " + out.what + " holds sensor volts");
    for (double& value : out.values) value *= scale->to_si / *mapping.sensitivity;
  } else {
    for (double& value : out.values) value *= scale->to_si;
  }
  return out;
}

Recording BuildRecord(const MappedRecord& mapped, const DataFile& data, const Mapping& mapping, bool shared_file) {
  const std::string& file = mapped.spec.file;
  Channel voltage = SelectChannel(data, file, mapped.voltage, false, mapping);
  Channel response = SelectChannel(data, file, mapped.response, true, mapping);
  const std::string& pointer = mapped.spec.pointer;
  if (voltage.values.size() != response.values.size())
    DocumentError(kMappingName, pointer,
                  "the voltage (" + voltage.what + ") holds " + std::to_string(voltage.values.size()) +
                      " values, the response (" + response.what + ") " + std::to_string(response.values.size()));
  if (std::abs(voltage.sample_rate_hz - response.sample_rate_hz) > 1e-9 * voltage.sample_rate_hz)
    DocumentError(kMappingName, pointer,
                  "the voltage (" + voltage.what + ") is sampled at " + Num(voltage.sample_rate_hz) +
                      " Hz, the response (" + response.what + ") at " + Num(response.sample_rate_hz) + " Hz");
  if (voltage.values.size() < 2)
    DocumentError(kMappingName, pointer, voltage.what + " holds a single sample; a record needs at least 2");
  double rate_hz = voltage.sample_rate_hz;
  if (mapped.spec.sample_rate_hz > 0) {
    // The mapping's rate, checked against the file's (a UFF increment is printed to 6-7 digits).
    const double tolerance = voltage.rate_is_exact ? 1e-9 : 1e-5;
    if (std::abs(mapped.spec.sample_rate_hz - rate_hz) > tolerance * rate_hz)
      DocumentError(kMappingName, mapped.rate_pointer,
                    "sample_rate_hz " + Num(mapped.spec.sample_rate_hz) + " disagrees with " + voltage.what + "'s " +
                        Num(rate_hz) + " Hz");
    rate_hz = mapped.spec.sample_rate_hz;
  }
  Recording record;
  record.name = shared_file ? file + "#" + (mapped.response.dataset > 0 ? "dataset" + std::to_string(mapped.response.dataset)
                                                                         : "channel" + std::to_string(mapped.response.channel))
                            : file;
  record.sample_rate_hz = rate_hz;
  record.voltage_v = std::move(voltage.values);
  record.response = std::move(response.values);
  record.broadband = mapped.spec.broadband;
  record.nominal_frequency_hz = mapped.spec.frequency_hz;
  record.nominal_amplitude_v = mapped.spec.amplitude_v;
  return record;
}

// Each data file once, in the order of first use: file -> its first record's pointer.
std::vector<std::pair<std::string, std::string>> UniqueFiles(const Mapping& mapping) {
  std::vector<std::pair<std::string, std::string>> files;
  std::map<std::string, size_t> seen;
  for (const MappedRecord& mapped : mapping.records) {
    const std::string normal = fs::path(mapped.spec.file).lexically_normal().string();
    if (seen.emplace(normal, files.size()).second) files.emplace_back(mapped.spec.file, mapped.spec.pointer);
  }
  return files;
}

}  // namespace

std::vector<std::string> MappedCampaignFiles(const fs::path& dir) {
  const Mapping mapping = data_internal::ReadMapping(dir);
  std::vector<std::string> files = {kMappingName};
  for (const auto& [file, pointer] : UniqueFiles(mapping)) files.push_back(file);
  return files;
}

Campaign ReadMappedCampaign(const fs::path& dir) {
  if (!fs::is_directory(dir)) throw InputError(dir.string(), "not a campaign directory (it does not exist)");
  const Mapping mapping = data_internal::ReadMapping(dir);
  const auto files = UniqueFiles(mapping);
  for (const auto& [file, pointer] : files) {
    if (!fs::is_regular_file(dir / file))
      DocumentError(kMappingName, pointer + "/file", "file '" + file + "' not found in " + dir.string());
  }
  // The files side by side; the first failure in the mapping's order is reported.
  std::vector<DataFile> data(files.size());
  ParallelFor(files.size(), [&](size_t i) { data[i] = ReadDataFile(dir, files[i].first, files[i].second + "/file"); });
  std::map<std::string, size_t> index, uses;
  for (size_t i = 0; i < files.size(); ++i) index[fs::path(files[i].first).lexically_normal().string()] = i;
  for (const MappedRecord& mapped : mapping.records) ++uses[fs::path(mapped.spec.file).lexically_normal().string()];

  Campaign campaign;
  campaign.actuator = mapping.actuator;
  campaign.response = mapping.kind;
  campaign.absolute_scale = !mapping.nominal;
  for (const MappedRecord& mapped : mapping.records) {
    const std::string normal = fs::path(mapped.spec.file).lexically_normal().string();
    campaign.records.push_back(BuildRecord(mapped, data[index.at(normal)], mapping, uses.at(normal) > 1));
  }
  return campaign;
}

}  // namespace strokelab
