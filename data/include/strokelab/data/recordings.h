// Campaign directories as the test rig exports them (the format below), read into and written from
// the in-memory Campaign of core (strokelab/identify/campaign.h).
//
// Layout:
//
//   campaign/manifest.json
//   campaign/rec_001.csv ...
//
// manifest.json ("format": "strokelab-recordings/1"):
//   "actuator"        optional string
//   "sample_rate_hz"  fs [Hz], finite and > 0; a record may override it with its own "sample_rate_hz"
//   "channels"        exactly "voltage" and one response channel among force, acceleration, velocity,
//                     displacement; each {"column": NAME, "unit": "V" (optional; only "V" is accepted),
//                     ...}. The response channel carries its sensitivity in sensor volts per physical
//                     unit under the key of its kind (SensitivityKey): sensitivity_V_per_N,
//                     sensitivity_V_per_m_s2, sensitivity_V_per_m_s, sensitivity_V_per_m (finite, != 0).
//                     "nominal": true on the response channel says the sensitivity is only nominal:
//                     the campaign's absolute_scale is then false (only ratios of model parameters are
//                     identifiable). Other keys ("note", a serial number, ...) are ignored, except a
//                     sensitivity key of another kind, which is an error.
//   "records"         a non-empty list of {"file": NAME, ...}: a stepped-sine step has
//                     "drive_frequency_hz" (> 0) and "drive_amplitude_v" (>= 0); a broadband record has
//                     "excitation": "broadband" (noise, multisine, sweep) and no nominal frequency.
//                     "excitation": "stepped-sine" may be written out. File names are relative to the
//                     directory (no absolute paths, no ".."), each used once.
//
// Each CSV: a header line naming the columns, then one row per sample, comma-separated. The columns
// must include "time_s" and the two channel columns; extra columns are allowed and ignored (their
// cells are counted, not parsed). Cells may be surrounded by blanks; header names may be quoted. A
// UTF-8 byte-order mark, CRLF line ends and blank lines at the very end are accepted; any other blank
// line is an error. Every parsed cell must be a finite number. The response column is in sensor
// volts and becomes physical units by dividing by the sensitivity.
//
// The time column must be uniform sampling from t = 0 at the manifest's rate: sample n at n / fs,
// within kTimeToleranceSamples samples plus kTimeRelativeTolerance * |t| (the rig prints time to 7
// significant digits). Checked in this order, each naming the first offending row:
//   start     |t_0| within tolerance;
//   uniform   every step t_n - t_(n-1) within tolerance of the column's median step (a glitch,
//             a dropped or repeated sample, a reversal);
//   rate      every t_n within tolerance of n / fs (the manifest's rate against the column's).
//
// Errors are strokelab::InputError whose field is where the problem is: "manifest.json" or
// "manifest.json:LINE" (unreadable, not JSON), "manifest.json:/records/3/file" (a JSON pointer into
// the manifest; indices from 0), "rec_004.csv:LINE" (lines from 1, the header being line 1), with a
// one-line message.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "strokelab/base/errors.h"
#include "strokelab/identify/campaign.h"

namespace strokelab {

inline constexpr const char* kRecordingsFormat = "strokelab-recordings/1";
inline constexpr const char* kManifestName = "manifest.json";

// Time-column tolerance: a fraction of a sample [dimensionless, in samples] plus a relative part
// [dimensionless] for times printed with few significant digits.
inline constexpr double kTimeToleranceSamples = 0.25;
inline constexpr double kTimeRelativeTolerance = 1e-6;

// The manifest key of a response kind's sensitivity, e.g. "sensitivity_V_per_N".
const char* SensitivityKey(ResponseKind kind);
// A plausible sensor sensitivity for synthetic campaigns [V per N, m/s^2, m/s or m]: force 0.02248
// (as campaign-a), acceleration 0.0102 (100 mV/g), velocity 1, displacement 1000 (1 V/mm).
double DefaultSensitivity(ResponseKind kind);

// Reads and validates a campaign directory. Throws InputError (see above); never returns a partial
// campaign. Records keep the manifest's order; Recording::name is the file name as the manifest gives it.
// A directory holding mapping.json instead of manifest.json is a campaign of UFF 58 or WAV files,
// read by ReadMappedCampaign (mapping.h); one holding both is refused.
Campaign ReadCampaign(const std::filesystem::path& dir);

// The files a campaign's manifest lists, relative to `dir`: manifest.json, then each record's CSV in
// manifest order (for mapping.json: MappedCampaignFiles). Only the manifest is read (a server hashes
// these before reading the campaign and opens nothing else in `dir`). Throws InputError for the
// manifest as ReadCampaign does.
std::vector<std::string> CampaignFiles(const std::filesystem::path& dir);

struct WriteOptions {
  // Sensor volts per physical unit of the response [V/N, V/(m/s^2), V/(m/s), V/m]; 0: DefaultSensitivity.
  double sensitivity = 0.0;
  std::string voltage_column = "voltage_V";
  std::string response_column;  // empty: "<kind>_sensor_V", e.g. "force_sensor_V"
  std::string actuator;         // empty: the campaign's own
  // File names: a record's own name, or rec_001.csv, ... (by position) when it has none or when
  // rename_records is set.
  bool rename_records = false;

  // Nothing, or the offending field (sensitivity, voltage_column, response_column).
  std::optional<FieldError> IsValid() const;
};

// Writes manifest.json and one CSV per record (time_s, voltage, response in sensor volts, each
// "%.10g"), creating `dir` if needed and overwriting files of the same names. A record whose sample
// rate differs from the first record's gets its own "sample_rate_hz" in the manifest; absolute_scale
// false is written as "nominal": true. Throws InputError for options or a campaign that cannot be
// written (no records, channels of unequal length, non-finite samples, a repeated file name), and
// std::runtime_error when the file system refuses.
void WriteCampaign(const Campaign& campaign, const std::filesystem::path& dir, const WriteOptions& options = {});

}  // namespace strokelab
