// Reading campaign directories (strokelab/data/recordings.h): manifest.json (manifest.cc), then the
// records on several threads (record_csv.cc); a directory holding mapping.json instead goes to
// mapped_campaign.cc. The first failing record in manifest order is the one
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
#include "strokelab/data/mapping.h"

namespace strokelab {
namespace data_internal {

nlohmann::json ReadJsonDocument(const std::filesystem::path& path, const char* name) {
  using nlohmann::json;
  std::string text;
  if (!ReadWholeFile(path, &text)) throw InputError(name, "cannot be read");
  try {
    return ParseJson(text);
  } catch (const json::parse_error& e) {
    // e.byte counts characters read, the offending one (or the end of input) included.
    const size_t before = std::min(e.byte > 0 ? e.byte - 1 : 0, text.size());
    const size_t line =
        1 + static_cast<size_t>(std::count(text.begin(), text.begin() + static_cast<long>(before), '\n'));
    std::string what = e.what();
    // "[json.exception.parse_error.101] parse error at line 3, column 5: syntax error ..." -> after the position.
    if (const size_t colon = what.find(": "); colon != std::string::npos) what = what.substr(colon + 2);
    throw InputError(std::string(name) + ":" + std::to_string(line), "not valid JSON: " + what);
  } catch (const json::exception& e) {
    // Not a syntax error: a number beyond a double ("1e400", out_of_range 406), which has no position.
    std::string what = e.what();
    if (const size_t bracket = what.find("] "); bracket != std::string::npos) what = what.substr(bracket + 2);
    throw InputError(name, "not valid JSON: " + what);
  }
}

void CheckDocumentFormat(const nlohmann::json& document, const char* name, const char* format) {
  if (!document.is_object()) DocumentError(name, "", "expected a JSON object");
  const auto found = document.find("format");
  if (found == document.end()) DocumentError(name, "/format", std::string("missing; expected \"") + format + "\"");
  if (!found->is_string() || found->get<std::string>() != format)
    DocumentError(name, "/format", "unsupported format " + found->dump() + " (expected \"" + format + "\")");
}

}  // namespace data_internal

namespace {

using data_internal::Channels;
using data_internal::Find;
using data_internal::ManifestError;
using data_internal::ParseChannels;
using data_internal::ParseRecords;
using data_internal::ReadJsonDocument;
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
  const json manifest = ReadJsonDocument(manifest_path, kManifestName);
  data_internal::CheckDocumentFormat(manifest, kManifestName, kRecordingsFormat);
  return manifest;
}

// A directory in the mapped layout (mapping.h): mapping.json and no manifest.json. Both is an error.
bool IsMappedCampaign(const fs::path& dir) {
  if (!fs::is_regular_file(dir / kMappingName)) return false;
  if (fs::exists(dir / kManifestName))
    throw InputError(dir.string(), std::string("holds both ") + kManifestName + " and " + kMappingName +
                                       " (a campaign is described by one of them)");
  return true;
}

}  // namespace

std::vector<std::string> CampaignFiles(const fs::path& dir) {
  if (fs::is_directory(dir) && IsMappedCampaign(dir)) return MappedCampaignFiles(dir);
  const json manifest = ReadManifest(dir);
  const json* rate = Find(manifest, "sample_rate_hz");
  if (!rate) ManifestError("/sample_rate_hz", "missing: the sample rate [Hz]");
  std::vector<std::string> files = {kManifestName};
  for (const RecordSpec& spec : ParseRecords(manifest, RequirePositiveRate(*rate, "/sample_rate_hz")))
    files.push_back(spec.file);
  return files;
}

Campaign ReadCampaign(const fs::path& dir) {
  if (fs::is_directory(dir) && IsMappedCampaign(dir)) return ReadMappedCampaign(dir);
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
