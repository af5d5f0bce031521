// What the campaign reader's and writer's files share (private to data/src): the manifest as parsed
// (manifest.cc), one record's CSV read into a Recording (record_csv.cc), and the blanks of a CSV cell,
// which the writer's column-name check also uses (recordings_writer.cc).
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "strokelab/data/recordings.h"
#include "strokelab/identify/campaign.h"

namespace strokelab::data_internal {

// The manifest's "channels": the voltage column and the one response channel.
struct Channels {
  std::string voltage_column;
  std::string response_column;
  ResponseKind kind = ResponseKind::kForce;
  double sensitivity = 0.0;  // sensor volts per physical unit
  bool nominal = false;
};

// One entry of the manifest's "records".
struct RecordSpec {
  std::string file;
  std::string pointer;  // "/records/3"
  double sample_rate_hz = 0.0;
  bool rate_from_record = false;
  bool broadband = false;
  double frequency_hz = 0.0;
  double amplitude_v = 0.0;
};

// ---- manifest.cc -------------------------------------------------------------------------------

// Throws InputError with the field "DOCUMENT:POINTER" ("DOCUMENT" for an empty pointer).
[[noreturn]] void DocumentError(const char* document, const std::string& pointer, const std::string& message);
// DocumentError for manifest.json.
[[noreturn]] void ManifestError(const std::string& pointer, const std::string& message);
// The member `key` of a JSON object, or nullptr.
const nlohmann::json* Find(const nlohmann::json& object, const char* key);
double RequirePositiveRate(const nlohmann::json& value, const std::string& pointer,
                           const char* document = kManifestName);
Channels ParseChannels(const nlohmann::json& manifest);
// A relative path inside the campaign directory; else ManifestError at `pointer`.
void CheckFileName(const std::string& file, const std::string& pointer);
std::vector<RecordSpec> ParseRecords(const nlohmann::json& manifest, double sample_rate_hz);
// A record's "excitation", "drive_frequency_hz" and "drive_amplitude_v" into `spec` (whose pointer
// is set), errors at DOCUMENT:POINTER.
void ParseExcitation(const nlohmann::json& record, RecordSpec* spec, const char* document);

// ---- recordings.cc -----------------------------------------------------------------------------

// A JSON file parsed; InputError "NAME:LINE" for a syntax error, "NAME" when unreadable.
nlohmann::json ReadJsonDocument(const std::filesystem::path& path, const char* name);
// A JSON object whose "format" is `format`; else DocumentError at NAME or NAME:/format.
void CheckDocumentFormat(const nlohmann::json& document, const char* name, const char* format);

// ---- recordings_writer.cc ----------------------------------------------------------------------

// The file name of each record of `campaign` as a writer writes it (its own name, with `extension`
// in place of its own when not empty, or rec_001EXT by position), every record checked as
// WriteCampaign checks it (response values as multiplied by `sensitivity`). Throws InputError.
std::vector<std::string> RecordFileNames(const Campaign& campaign, double sensitivity, bool rename_records,
                                         const std::string& extension);
// Writes `text` to `path`; std::runtime_error when the file system refuses.
void WriteWholeFile(const std::filesystem::path& path, std::string_view text);
// Integral values as JSON integers (51200, not 51200.0), as the rig writes them.
nlohmann::json ManifestNumber(double value);

// ---- record_csv.cc -----------------------------------------------------------------------------

// The file's bytes; false if it cannot be opened or read.
bool ReadWholeFile(const std::filesystem::path& path, std::string* text);
// The record `spec` names in `dir`: its CSV parsed, its time column checked, the response divided by
// the sensitivity. Throws InputError naming the file and line.
Recording ReadRecord(const std::filesystem::path& dir, const RecordSpec& spec, const Channels& channels);

// ---- CSV cells ---------------------------------------------------------------------------------

inline bool IsBlank(char c) { return c == ' ' || c == '\t'; }

inline std::string_view Trim(std::string_view text) {
  while (!text.empty() && IsBlank(text.front())) text.remove_prefix(1);
  while (!text.empty() && IsBlank(text.back())) text.remove_suffix(1);
  return text;
}

}  // namespace strokelab::data_internal
