// What the mapped-campaign files share (private to data/src): mapping.json as parsed (mapping.cc),
// read into a Campaign by mapped_campaign.cc, and the units a UFF dataset or the mapping may name.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "recordings_internal.h"
#include "strokelab/identify/campaign.h"

namespace strokelab::data_internal {

// Which channel of a record's file: a UFF dataset or a WAV channel (one of them is > 0).
struct Selector {
  long long dataset = 0;      // from 1
  long long channel = 0;      // from 1
  double full_scale_v = 1.0;  // WAV: volts at full scale
  std::string pointer;        // "/records/3/voltage" (where a wrong selection is reported)
};

struct MappedRecord {
  RecordSpec spec;             // file, pointer, excitation; sample_rate_hz 0 when the mapping gives none
  std::string rate_pointer;    // where the mapping's rate is (when it gives one)
  Selector voltage, response;
};

struct Mapping {
  std::string actuator;
  ResponseKind kind = ResponseKind::kForce;
  std::optional<double> sensitivity;  // sensor volts per unit
  std::string sensitivity_pointer;    // "/response" or "/response/sensitivity_V_per_N"
  std::string unit = "V";             // of a UFF dataset that names none
  bool nominal = false;
  std::vector<MappedRecord> records;
};

// mapping.json of `dir` parsed and checked; errors at "mapping.json:POINTER".
Mapping ReadMapping(const std::filesystem::path& dir);

// A unit: volts (scale to V) or a physical unit of `kind` (scale to SI); nullopt when unknown.
struct UnitScale {
  bool volts = false;
  double to_si = 1.0;  // value x to_si: V, or N, m/s^2, m/s, m
};
std::optional<UnitScale> ParseUnit(const std::string& unit, ResponseKind kind);
// The units ParseUnit knows for `kind`, for messages ("N, kN, mN, lbf").
std::string KnownUnits(ResponseKind kind);
// The SI unit of `kind`: N, m/s^2, m/s, m.
const char* SiUnit(ResponseKind kind);

}  // namespace strokelab::data_internal
