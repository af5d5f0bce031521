// Reading campaign directories (strokelab/data/recordings.h): manifest.json (manifest.cc), then the
// records on several threads (record_csv.cc). The first failing record in manifest order is the one
// reported, so errors do not depend on timing. Writing is recordings_writer.cc.
#include "strokelab/data/recordings.h"

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "recordings_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/parallel_for.h"
#include "strokelab/base/json_parse.h"

namespace strokelab {
namespace {

using data_internal::Channels;
using data_internal::Find;
using data_internal::ManifestError;
using data_internal::ParseChannels;
using data_internal::ParseRecords;
using data_internal::ReadRecord;
using data_internal::ReadWholeFile;
using data_internal::RecordSpec;
using data_internal::RequirePositiveRate;

namespace fs = std::filesystem;
using nlohmann::json;

// manifest.json of `dir`, parsed and checked as far as its format; InputError naming its line.
json ReadManifest(const fs::path& dir) {
  if (!fs::is_directory(dir)) throw InputError(dir.string(), "not a campaign directory (it does not exist)");
  const fs::path manifest_path = dir / kManifestName;
  if (!fs::is_regular_file(manifest_path)) ManifestError("", "not found in " + dir.string());
  std::string manifest_text;
  if (!ReadWholeFile(manifest_path, &manifest_text)) ManifestError("", "cannot be read");
  json manifest;
  try {
    manifest = ParseJson(manifest_text);
  } catch (const json::parse_error& e) {
    // e.byte counts characters read, the offending one (or the end of input) included.
    const size_t before = std::min(e.byte > 0 ? e.byte - 1 : 0, manifest_text.size());
    const size_t line = 1 + static_cast<size_t>(std::count(manifest_text.begin(),
                                                           manifest_text.begin() + static_cast<long>(before), '\n'));
    std::string what = e.what();
    // "[json.exception.parse_error.101] parse error at line 3, column 5: syntax error ..." -> after the position.
    if (const size_t colon = what.find(": "); colon != std::string::npos) what = what.substr(colon + 2);
    throw InputError(std::string(kManifestName) + ":" + std::to_string(line), "not valid JSON: " + what);
  } catch (const json::exception& e) {
    // Not a syntax error: a number beyond a double ("1e400", out_of_range 406), which has no position.
    std::string what = e.what();
    if (const size_t bracket = what.find("] "); bracket != std::string::npos) what = what.substr(bracket + 2);
    throw InputError(kManifestName, "not valid JSON: " + what);
  }
  if (!manifest.is_object()) ManifestError("", "expected a JSON object");
  const json* format = Find(manifest, "format");
  if (!format) ManifestError("/format", std::string("missing; expected \"") + kRecordingsFormat + "\"");
  if (!format->is_string() || format->get<std::string>() != kRecordingsFormat)
    ManifestError("/format", "unsupported format " + format->dump() + " (expected \"" + kRecordingsFormat + "\")");
  return manifest;
}

}  // namespace

std::vector<std::string> CampaignFiles(const fs::path& dir) {
  const json manifest = ReadManifest(dir);
  const json* rate = Find(manifest, "sample_rate_hz");
  if (!rate) ManifestError("/sample_rate_hz", "missing: the sample rate [Hz]");
  std::vector<std::string> files = {kManifestName};
  for (const RecordSpec& spec : ParseRecords(manifest, RequirePositiveRate(*rate, "/sample_rate_hz")))
    files.push_back(spec.file);
  return files;
}

Campaign ReadCampaign(const fs::path& dir) {
  const json manifest = ReadManifest(dir);
  Campaign campaign;
  if (const json* actuator = Find(manifest, "actuator")) {
    if (!actuator->is_string()) ManifestError("/actuator", "expected a string");
    campaign.actuator = actuator->get<std::string>();
  }
  const json* rate = Find(manifest, "sample_rate_hz");
  if (!rate) ManifestError("/sample_rate_hz", "missing: the sample rate [Hz]");
  const double sample_rate_hz = RequirePositiveRate(*rate, "/sample_rate_hz");
  const Channels channels = ParseChannels(manifest);
  campaign.response = channels.kind;
  campaign.absolute_scale = !channels.nominal;
  const std::vector<RecordSpec> specs = ParseRecords(manifest, sample_rate_hz);
  for (const RecordSpec& spec : specs) {
    if (!fs::is_regular_file(dir / spec.file))
      ManifestError(spec.pointer + "/file", "file '" + spec.file + "' not found in " + dir.string());
  }

  // The records, on up to one thread per core; the first failure in manifest order is reported.
  campaign.records.resize(specs.size());
  ParallelFor(specs.size(), [&](size_t i) { campaign.records[i] = ReadRecord(dir, specs[i], channels); });
  return campaign;
}

}  // namespace strokelab
