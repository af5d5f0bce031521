// Campaigns in the vibration-test world's files: UFF dataset 58 (uff58.h) and multi-channel WAV
// (wav.h), mapped to the recordings format (recordings.h) by a small JSON file, `mapping.json`, in the
// campaign directory in place of manifest.json. ReadCampaign and CampaignFiles recognise it, so
// `strokelab fit/diagnose DIR` and the server take such a directory as they take a CSV campaign.
//
// mapping.json ("format": "strokelab-mapping/1"):
//   "actuator"   optional string
//   "response"   {"kind": force | acceleration | velocity | displacement,
//                 SENSITIVITY_KEY (recordings.h, e.g. "sensitivity_V_per_N"): sensor volts per unit,
//                 "unit": the unit of a UFF dataset that names none ("V" by default),
//                 "nominal": true when the sensitivity or the file's calibration is only nominal,
//                 and optionally the defaults of the record's response selector (below)}
//   "voltage"    optional defaults of the record's voltage selector
//   "records"    a non-empty list of {"file": NAME, "voltage": SELECTOR, "response": SELECTOR, and as a
//                manifest's record: "drive_frequency_hz" and "drive_amplitude_v" (a stepped-sine step)
//                or "excitation": "broadband"; "sample_rate_hz" optionally, checked against the file's}
//   A SELECTOR is {"dataset": K} for a UFF file (K from 1: the dataset's position in the file) or
//   {"channel": C, "full_scale_v": X} for a WAV file (C from 1; X volts at full scale, default 1).
//   A record's selector fields override the top-level defaults.
//
// A file is WAV when it starts with "RIFF", else UFF. Units: a UFF dataset's units label ("V", "N",
// "m/s^2", "g", "m/s", "mm", ...) says what it holds; a WAV channel is in volts (sample x full_scale_v).
// The voltage must be in volts; a response in volts is divided by the sensitivity (which is then
// required), a response in physical units is converted to SI (and a sensitivity is then refused). A
// UFF dataset's specific data type, when it names a quantity (8 displacement, 9 and 13 force,
// 11 velocity, 12 acceleration), must agree with the kind. A UFF sample rate is 1 / increment,
// rounded to a whole Hz when the increment's printed digits cannot tell them apart (relative 5e-6).
// The voltage and response of a record must have the same rate and length.
//
// Errors: InputError whose field is "mapping.json:POINTER" or "mapping.json:LINE" as for a manifest,
// or the data file's own (uff58.h, wav.h).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "strokelab/data/recordings.h"
#include "strokelab/data/wav.h"
#include "strokelab/identify/campaign.h"

namespace strokelab {

inline constexpr const char* kMappingFormat = "strokelab-mapping/1";
inline constexpr const char* kMappingName = "mapping.json";

// Reads a campaign directory holding mapping.json. Throws InputError as above.
Campaign ReadMappedCampaign(const std::filesystem::path& dir);
// mapping.json, then each data file it names once, in the order of first use (only the mapping is read).
std::vector<std::string> MappedCampaignFiles(const std::filesystem::path& dir);

enum class CampaignFormat { kCsv, kUff58, kUff58Binary, kWav };
const char* ToString(CampaignFormat format);  // "csv", "uff58", "uff58b", "wav"
CampaignFormat ParseCampaignFormat(const std::string& text, const std::string& field);

struct MappedWriteOptions {
  CampaignFormat format = CampaignFormat::kUff58;  // kUff58, kUff58Binary or kWav
  WavSampleFormat wav_format = WavSampleFormat::kFloat32;
  // WAV and a response in volts: sensor volts per physical unit; 0: DefaultSensitivity. UFF files
  // carry the response in SI units (N, m/s^2, m/s, m) and need none.
  double sensitivity = 0.0;
  bool rename_records = false;  // rec_001.uff / rec_001.wav by position, as WriteOptions
};

// Writes one file per record (UFF: the voltage as dataset 1, the response as dataset 2; WAV: channels
// 1 and 2, each scaled to its own full scale, written to the mapping) and mapping.json last. A
// record's name keeps its stem with the format's extension. Throws InputError for a campaign that
// cannot be written (as WriteCampaign), std::runtime_error when the file system refuses.
void WriteMappedCampaign(const Campaign& campaign, const std::filesystem::path& dir,
                         const MappedWriteOptions& options = {});

}  // namespace strokelab
