// What the campaign-directory tests of this folder share: a temporary folder per test under one
// per-process folder (removed when the tests end), reading a file back, and Fixture, a small valid
// campaign as text that the tests of accepted variants and of malformed campaigns change.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

namespace strokelab::recordings_test {

namespace fs = std::filesystem;
using nlohmann::json;

// Every directory a test writes lives under one per-process folder, removed when the tests end.
inline fs::path ProcessTempDir() {
  return fs::path(::testing::TempDir()) / ("strokelab_recordings_" + std::to_string(::getpid()));
}

class RemoveTempDirs : public ::testing::Environment {
 public:
  void TearDown() override { fs::remove_all(ProcessTempDir()); }
};
inline const auto* const kRemoveTempDirs = ::testing::AddGlobalTestEnvironment(new RemoveTempDirs);

inline fs::path TempDir(const std::string& name) {
  const fs::path dir = ProcessTempDir() / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

inline std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// A small valid campaign as text: 1000 Hz, 40 rows per record, three records whose CSVs differ in
// column order and extra columns.
struct Fixture {
  json manifest;
  std::map<std::string, std::vector<std::string>> csv;  // file -> lines (header first), no line ends
  std::map<std::string, std::string> raw;               // file -> exact bytes (overrides csv)
  bool write_manifest = true;
  std::string manifest_text;  // overrides manifest when not empty

  static constexpr double kRateHz = 1000.0;
  static constexpr size_t kRows = 40;

  static std::string Row(const std::vector<double>& values) {
    std::string out;
    for (double v : values) {
      char cell[32];
      std::snprintf(cell, sizeof cell, "%.7g", v);
      if (!out.empty()) out += ',';
      out += cell;
    }
    return out;
  }

  Fixture() {
    manifest = {{"format", "strokelab-recordings/1"},
                {"actuator", "fixture"},
                {"sample_rate_hz", kRateHz},
                {"channels",
                 {{"voltage", {{"column", "voltage_V"}, {"unit", "V"}}},
                  {"force", {{"column", "force_sensor_V"}, {"unit", "V"}, {"sensitivity_V_per_N", 0.02}}}}},
                {"records",
                 {{{"file", "rec_001.csv"}, {"drive_frequency_hz", 10}, {"drive_amplitude_v", 0.1}},
                  {{"file", "rec_002.csv"}, {"drive_frequency_hz", 20}, {"drive_amplitude_v", 0.2}},
                  {{"file", "rec_003.csv"}, {"excitation", "broadband"}}}}};
    // rec_001: time_s,voltage_V,force_sensor_V; rec_002 has an extra column in the middle;
    // rec_003 has its columns in another order.
    csv["rec_001.csv"] = {"time_s,voltage_V,force_sensor_V"};
    csv["rec_002.csv"] = {"time_s,temperature_C,voltage_V,force_sensor_V"};
    csv["rec_003.csv"] = {"force_sensor_V,time_s,voltage_V"};
    for (size_t n = 0; n < kRows; ++n) {
      const double t = static_cast<double>(n) / kRateHz;
      const double v = 0.1 * std::sin(2 * std::numbers::pi * 10 * t);
      const double f = 0.02 * std::cos(2 * std::numbers::pi * 10 * t) + 0.001;
      csv["rec_001.csv"].push_back(Row({t, v, f}));
      csv["rec_002.csv"].push_back(Row({t, 21.5, 2 * v, 2 * f}));
      csv["rec_003.csv"].push_back(Row({f, t, v}));
    }
  }

  // The cell of `file` on line `line` (1 = header) in column `column` (0-based).
  std::string GetCell(const std::string& file, size_t line, size_t column) const {
    const auto [start, length] = CellSpan(csv.at(file).at(line - 1), column);
    return csv.at(file).at(line - 1).substr(start, length);
  }
  void SetCell(const std::string& file, size_t line, size_t column, const std::string& value) {
    std::string& text = csv.at(file).at(line - 1);
    const auto [start, length] = CellSpan(text, column);
    text.replace(start, length, value);
  }
  // Rewrites the time column of `file` as t_n = offset + n / rate.
  void Retime(const std::string& file, double rate_hz, double offset_s, size_t time_column) {
    auto& lines = csv.at(file);
    for (size_t n = 0; n + 1 < lines.size(); ++n) {
      char cell[32];
      std::snprintf(cell, sizeof cell, "%.7g", offset_s + static_cast<double>(n) / rate_hz);
      SetCell(file, n + 2, time_column, cell);
    }
  }

  fs::path Write(const std::string& name) const {
    const fs::path dir = TempDir(name);
    if (write_manifest)
      std::ofstream(dir / "manifest.json") << (manifest_text.empty() ? manifest.dump(2) : manifest_text);
    for (const auto& [file, lines] : csv) {
      if (raw.count(file)) continue;
      std::ofstream out(dir / file, std::ios::binary);
      for (const std::string& line : lines) out << line << "\n";
    }
    for (const auto& [file, bytes] : raw) std::ofstream(dir / file, std::ios::binary) << bytes;
    return dir;
  }

 private:
  static std::pair<size_t, size_t> CellSpan(const std::string& text, size_t column) {
    size_t start = 0;
    for (size_t c = 0; c < column; ++c) start = text.find(',', start) + 1;
    const size_t end = text.find(',', start);
    return {start, (end == std::string::npos ? text.size() : end) - start};
  }
};


}  // namespace strokelab::recordings_test
