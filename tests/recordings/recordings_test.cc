// Campaign directories: the real campaign-a, Write -> Read round trips, every kind of malformed
// campaign (each naming its file and line, or its manifest pointer), and `strokelab synth` against
// the engine it drives.
#include "strokelab/data/recordings.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>
#include <vector>

#include "cli/run_cli.h"
#include "strokelab/engines/engine.h"
#include "strokelab/base/errors.h"
#include "strokelab/model/model.h"
#include "strokelab/data/synth.h"

namespace strokelab {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::testing::HasSubstr;

// %.10g keeps 10 significant digits: 5e-10 relative, plus the sensitivity's division and product.
constexpr double kRoundTripRelative = 1e-9;

// Every directory a test writes lives under one per-process folder, removed when the tests end.
fs::path ProcessTempDir() {
  return fs::path(::testing::TempDir()) / ("strokelab_recordings_" + std::to_string(::getpid()));
}

class RemoveTempDirs : public ::testing::Environment {
 public:
  void TearDown() override { fs::remove_all(ProcessTempDir()); }
};
const auto* const kRemoveTempDirs = ::testing::AddGlobalTestEnvironment(new RemoveTempDirs);

fs::path TempDir(const std::string& name) {
  const fs::path dir = ProcessTempDir() / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

::testing::AssertionResult ChannelsNear(const std::vector<double>& actual, const std::vector<double>& expected,
                                        double relative) {
  if (actual.size() != expected.size())
    return ::testing::AssertionFailure() << "sizes " << actual.size() << " vs " << expected.size();
  for (size_t n = 0; n < actual.size(); ++n) {
    if (!(std::abs(actual[n] - expected[n]) <= relative * std::abs(expected[n])))
      return ::testing::AssertionFailure() << "sample " << n << ": " << actual[n] << " vs " << expected[n];
  }
  return ::testing::AssertionSuccess();
}

// ---- campaign-a ------------------------------------------------------------------------------------

// The example campaign's manifest and the first 2048 rows (40 ms) of each of its 24 records.
const char* const kCampaignA = STROKELAB_TESTDATA "/campaign-a";
constexpr size_t kRowsPerRecord = 2048;

TEST(CampaignA, ReadsAll24RecordsInForceUnits) {
  const fs::path dir = kCampaignA;
  ASSERT_TRUE(fs::is_directory(dir)) << "campaign-a not found at " << dir;
  const Campaign campaign = ReadCampaign(dir);

  EXPECT_EQ(campaign.actuator, "inertial actuator, blocked-force test rig");
  EXPECT_EQ(campaign.response, ResponseKind::kForce);
  EXPECT_TRUE(campaign.absolute_scale);
  ASSERT_EQ(campaign.records.size(), 24u);
  const double frequencies[] = {6, 7, 8, 9, 11, 13};
  const double amplitudes[] = {0.1, 0.3, 0.4, 0.5};
  for (size_t k = 0; k < 24; ++k) {
    const Recording& record = campaign.records[k];
    char name[16];
    std::snprintf(name, sizeof name, "rec_%03zu.csv", k + 1);
    EXPECT_EQ(record.name, name);
    EXPECT_EQ(record.size(), kRowsPerRecord) << name;
    EXPECT_EQ(record.response.size(), kRowsPerRecord) << name;
    EXPECT_EQ(record.sample_rate_hz, 51200.0);
    EXPECT_FALSE(record.broadband);
    EXPECT_EQ(record.nominal_frequency_hz, frequencies[k % 6]);
    EXPECT_EQ(record.nominal_amplitude_v, amplitudes[k / 6]);
  }
  // rec_001.csv, first and last rows: 0,0.0001403209,0.001053068 and 0.03998047,0.09986991,0.001536967.
  constexpr double kSensitivityVPerN = 0.02248;
  const Recording& first = campaign.records[0];
  EXPECT_DOUBLE_EQ(first.voltage_v[0], 0.0001403209);
  EXPECT_DOUBLE_EQ(first.response[0], 0.001053068 / kSensitivityVPerN);
  EXPECT_DOUBLE_EQ(first.voltage_v.back(), 0.09986991);
  EXPECT_DOUBLE_EQ(first.response.back(), 0.001536967 / kSensitivityVPerN);
  // The drive is the nominal amplitude: the voltage channel peaks near 0.5 V in rec_024 (13 Hz: its
  // first crest, at 19 ms, lies inside the 40 ms kept).
  const auto& v = campaign.records[23].voltage_v;
  const double peak = *std::max_element(v.begin(), v.end());
  EXPECT_NEAR(peak, 0.5, 0.02);
}

TEST(CampaignA, SurvivesWriteAndReadBack) {
  const fs::path dir = kCampaignA;
  ASSERT_TRUE(fs::is_directory(dir)) << "campaign-a not found at " << dir;
  const Campaign campaign = ReadCampaign(dir);
  const fs::path out = TempDir("campaign_a_copy");
  WriteOptions options;
  options.sensitivity = 0.02248;
  options.response_column = "force_sensor_V";
  WriteCampaign(campaign, out, options);
  const Campaign back = ReadCampaign(out);
  ASSERT_EQ(back.records.size(), campaign.records.size());
  EXPECT_EQ(back.actuator, campaign.actuator);
  for (size_t k = 0; k < back.records.size(); ++k) {
    EXPECT_EQ(back.records[k].name, campaign.records[k].name);
    EXPECT_TRUE(ChannelsNear(back.records[k].voltage_v, campaign.records[k].voltage_v, kRoundTripRelative));
    EXPECT_TRUE(ChannelsNear(back.records[k].response, campaign.records[k].response, kRoundTripRelative));
  }
  fs::remove_all(out);
}

// ---- Round trip --------------------------------------------------------------------------------

Campaign MakeCampaign() {
  Campaign campaign;
  campaign.actuator = "bench \"B\", unit 2";
  campaign.response = ResponseKind::kAcceleration;
  campaign.absolute_scale = false;
  for (int k = 0; k < 3; ++k) {
    Recording record;
    record.name = k == 2 ? "sub/broad.csv" : "step_" + std::to_string(k) + ".csv";
    record.sample_rate_hz = k == 1 ? 2048.0 : 4096.0;
    record.broadband = k == 2;
    record.nominal_frequency_hz = k == 2 ? 0.0 : 7.5 + k;
    record.nominal_amplitude_v = 0.25 * (k + 1);
    const size_t count = 3000 + 17 * k;
    for (size_t n = 0; n < count; ++n) {
      const double t = static_cast<double>(n) / record.sample_rate_hz;
      record.voltage_v.push_back(record.nominal_amplitude_v * std::sin(2 * std::numbers::pi * 7.5 * t + 0.1 * k));
      // Values over many decades, negative, and exact zeros.
      record.response.push_back(
          n % 97 == 0 ? 0.0 : 123.456 * std::cos(0.37 * static_cast<double>(n)) * std::pow(10.0, (n % 13) - 6.0));
    }
    campaign.records.push_back(std::move(record));
  }
  return campaign;
}

TEST(RoundTrip, WriteThenReadGivesTheCampaignTo1e9) {
  const Campaign campaign = MakeCampaign();
  const fs::path dir = TempDir("round_trip");
  WriteOptions options;
  options.sensitivity = -0.0321;  // an inverted accelerometer
  WriteCampaign(campaign, dir, options);
  EXPECT_TRUE(fs::is_regular_file(dir / "sub/broad.csv"));
  const json manifest = json::parse(ReadText(dir / "manifest.json"));
  EXPECT_EQ(manifest["format"], "strokelab-recordings/1");
  EXPECT_EQ(manifest["channels"]["acceleration"]["column"], "acceleration_sensor_V");
  EXPECT_EQ(manifest["channels"]["acceleration"]["sensitivity_V_per_m_s2"], -0.0321);
  EXPECT_EQ(manifest["channels"]["acceleration"]["nominal"], true);
  EXPECT_EQ(manifest["records"][1]["sample_rate_hz"], 2048.0);
  EXPECT_FALSE(manifest["records"][0].contains("sample_rate_hz"));
  EXPECT_EQ(manifest["records"][2]["excitation"], "broadband");
  EXPECT_THAT(ReadText(dir / "step_0.csv"), ::testing::StartsWith("time_s,voltage_V,acceleration_sensor_V\n0,0,"));

  const Campaign back = ReadCampaign(dir);
  EXPECT_EQ(back.actuator, campaign.actuator);
  EXPECT_EQ(back.response, ResponseKind::kAcceleration);
  EXPECT_FALSE(back.absolute_scale);
  ASSERT_EQ(back.records.size(), 3u);
  for (size_t k = 0; k < 3; ++k) {
    const Recording& a = back.records[k];
    const Recording& b = campaign.records[k];
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.sample_rate_hz, b.sample_rate_hz);
    EXPECT_EQ(a.broadband, b.broadband);
    EXPECT_EQ(a.nominal_frequency_hz, b.nominal_frequency_hz);
    EXPECT_EQ(a.nominal_amplitude_v, b.nominal_amplitude_v);
    EXPECT_TRUE(ChannelsNear(a.voltage_v, b.voltage_v, kRoundTripRelative)) << b.name;
    EXPECT_TRUE(ChannelsNear(a.response, b.response, kRoundTripRelative)) << b.name;
  }
  fs::remove_all(dir);
}

TEST(RoundTrip, WriteRefusesWhatCannotBeRead) {
  const fs::path dir = TempDir("refused");
  const auto expect_refused = [&](Campaign campaign, const WriteOptions& options, const std::string& field,
                                  const std::string& fragment) {
    try {
      WriteCampaign(campaign, dir, options);
      ADD_FAILURE() << "no error for " << field;
    } catch (const InputError& e) {
      EXPECT_EQ(e.field(), field);
      EXPECT_THAT(e.bare_message(), HasSubstr(fragment));
    }
  };
  Campaign campaign = MakeCampaign();
  expect_refused(Campaign{}, {}, "records", "no records");
  Campaign same = campaign;
  same.records[1].name = "step_0.csv";
  expect_refused(same, {}, "records/1/name", "also that of records/0");
  Campaign short_response = campaign;
  short_response.records[2].response.pop_back();
  expect_refused(short_response, {}, "records/2", "different lengths");
  Campaign nan = campaign;
  nan.records[0].response[5] = std::nan("");
  expect_refused(nan, {}, "records/0", "non-finite sample 5");
  Campaign escaping = campaign;
  escaping.records[0].name = "../x.csv";
  expect_refused(escaping, {}, "records/0/name", "leaves the campaign directory");
  WriteOptions comma;
  comma.voltage_column = "volt,age";
  expect_refused(campaign, comma, "voltage_column", "comma");
  WriteOptions infinite;
  infinite.sensitivity = INFINITY;
  expect_refused(campaign, infinite, "sensitivity", "finite");
  EXPECT_FALSE(fs::exists(dir / "manifest.json"));  // nothing half-written
  fs::remove_all(dir);
}

// ---- Accepted variants -------------------------------------------------------------------------

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

TEST(ReadCampaign, ReadsTheFixtureWithExtraColumnsAndAnyColumnOrder) {
  Fixture fixture;
  const Campaign campaign = ReadCampaign(fixture.Write("fixture"));
  ASSERT_EQ(campaign.records.size(), 3u);
  EXPECT_EQ(campaign.actuator, "fixture");
  for (const Recording& record : campaign.records) {
    EXPECT_EQ(record.size(), Fixture::kRows);
    EXPECT_EQ(record.sample_rate_hz, Fixture::kRateHz);
  }
  EXPECT_NEAR(campaign.records[0].response[0], (0.02 + 0.001) / 0.02, 1e-12);
  EXPECT_NEAR(campaign.records[1].response[0], 2 * (0.02 + 0.001) / 0.02, 1e-12);
  EXPECT_NEAR(campaign.records[2].response[0], (0.02 + 0.001) / 0.02, 1e-12);
  EXPECT_NEAR(campaign.records[1].voltage_v[3], 2 * 0.1 * std::sin(2 * std::numbers::pi * 10 * 0.003), 1e-7);
  EXPECT_TRUE(campaign.records[2].broadband);
  EXPECT_FALSE(campaign.records[0].broadband);
  EXPECT_EQ(campaign.records[1].nominal_frequency_hz, 20.0);
  EXPECT_TRUE(campaign.absolute_scale);
}

TEST(ReadCampaign, AcceptsCrlfBomBlanksQuotedHeadersAndNominalSensitivity) {
  Fixture fixture;
  fixture.manifest["channels"]["force"]["nominal"] = true;
  fixture.manifest["records"][0]["excitation"] = "stepped-sine";
  std::string bytes = "\xEF\xBB\xBF\"time_s\", voltage_V ,\"force_sensor_V\"\r\n";
  for (size_t line = 2; line <= Fixture::kRows + 1; ++line) {
    bytes += " +" + fixture.GetCell("rec_001.csv", line, 0) + " ," + fixture.GetCell("rec_001.csv", line, 1) + ",\t" +
             fixture.GetCell("rec_001.csv", line, 2) + "\r\n";
  }
  bytes += "\r\n\n";  // blank lines at the very end
  fixture.raw["rec_001.csv"] = bytes;
  const Campaign campaign = ReadCampaign(fixture.Write("variants"));
  EXPECT_FALSE(campaign.absolute_scale);
  ASSERT_EQ(campaign.records[0].size(), Fixture::kRows);
  EXPECT_NEAR(campaign.records[0].response[0], 1.05, 1e-12);
}

TEST(ReadCampaign, ConvertsEachResponseKindByItsSensitivity) {
  const std::pair<const char*, const char*> kinds[] = {{"acceleration", "sensitivity_V_per_m_s2"},
                                                       {"velocity", "sensitivity_V_per_m_s"},
                                                       {"displacement", "sensitivity_V_per_m"}};
  for (const auto& [kind, key] : kinds) {
    Fixture fixture;
    fixture.manifest["channels"].erase("force");
    fixture.manifest["channels"][kind] = {{"column", "force_sensor_V"}, {key, 4.0}};
    const Campaign campaign = ReadCampaign(fixture.Write(std::string("kind_") + kind));
    EXPECT_STREQ(ToString(campaign.response), kind);
    EXPECT_NEAR(campaign.records[0].response[0], 0.021 / 4.0, 1e-15) << kind;
  }
}

// ---- Malformed campaigns -------------------------------------------------------------------------

struct Defect {
  std::string name;
  std::function<void(Fixture&)> apply;
  std::string field;     // exactly
  std::string fragment;  // in the message
};

std::vector<Defect> Defects() {
  std::vector<Defect> d;
  const auto add = [&](std::string name, std::function<void(Fixture&)> apply, std::string field, std::string fragment) {
    d.push_back({std::move(name), std::move(apply), std::move(field), std::move(fragment)});
  };
  // Column count per file: rec_001 3, rec_002 4, rec_003 3.
  const std::map<std::string, size_t> columns = {{"rec_001.csv", 3}, {"rec_002.csv", 4}, {"rec_003.csv", 3}};
  const size_t last = Fixture::kRows + 1;

  // Truncated rows (a cell missing), at several files and lines.
  for (const auto& [file, line] : std::vector<std::pair<std::string, size_t>>{
           {"rec_001.csv", 2}, {"rec_001.csv", 17}, {"rec_002.csv", 30}, {"rec_003.csv", last}}) {
    const size_t n = columns.at(file);
    add(
        "truncated " + file + ":" + std::to_string(line),
        // Named copies: clang 14 cannot capture structured bindings.
        [file = file, line = line](Fixture& f) {
          std::string& text = f.csv.at(file).at(line - 1);
          text = text.substr(0, text.rfind(','));
        },
        file + ":" + std::to_string(line),
        "row has " + std::to_string(n - 1) + " columns, the header has " + std::to_string(n) + " (truncated row?)");
  }
  // A file cut in the middle of its last row (no final line end), and cut just after a comma.
  add(
      "cut mid-number",
      [](Fixture& f) {
        std::string bytes;
        auto lines = f.csv.at("rec_002.csv");
        lines.back() = lines.back().substr(0, lines.back().find(',') + 3);
        for (size_t i = 0; i < lines.size(); ++i) bytes += lines[i] + (i + 1 < lines.size() ? "\n" : "");
        f.raw["rec_002.csv"] = bytes;
      },
      "rec_002.csv:" + std::to_string(last), "row has 2 columns, the header has 4");
  add(
      "cut after comma",
      [](Fixture& f) {
        f.csv.at("rec_001.csv").at(9) =
            f.csv.at("rec_001.csv").at(9).substr(0, f.csv.at("rec_001.csv").at(9).find(',') + 1);
      },
      "rec_001.csv:10", "row has 2 columns, the header has 3");
  // Too many cells.
  add(
      "extra cell", [](Fixture& f) { f.csv.at("rec_001.csv").at(4) += ",0.5"; }, "rec_001.csv:5",
      "row has 4 columns, the header has 3");
  add(
      "extra cell in a 4-column file", [](Fixture& f) { f.csv.at("rec_002.csv").at(20) += ",1,2"; }, "rec_002.csv:21",
      "row has 6 columns, the header has 4");
  // Cells that are not numbers, in each role's column.
  struct Bad {
    std::string file;
    size_t line, column;
    std::string cell, column_name, fragment;
  };
  const std::vector<Bad> bad_cells = {
      {"rec_001.csv", 3, 1, "abc", "voltage_V", "'abc' is not a number"},
      {"rec_001.csv", 40, 2, "1.2.3", "force_sensor_V", "'1.2.3' is not a number"},
      {"rec_002.csv", 7, 0, "0,001", "time_s", ""},  // a decimal comma: a cell too many
      {"rec_002.csv", 12, 3, "12V", "force_sensor_V", "'12V' is not a number"},
      {"rec_003.csv", 25, 0, "--1", "force_sensor_V", "'--1' is not a number"},
      {"rec_003.csv", 2, 2, "0x1p3", "voltage_V", "'0x1p3' is not a number"},
      {"rec_001.csv", 13, 1, "+-0.5", "voltage_V", "'+-0.5' is not a number"},
      {"rec_001.csv", 8, 1, "nan", "voltage_V", "non-finite value 'nan'"},
      {"rec_001.csv", last, 2, "NaN", "force_sensor_V", "non-finite value 'NaN'"},
      {"rec_002.csv", 33, 2, "-nan", "voltage_V", "non-finite value '-nan'"},
      {"rec_002.csv", 5, 3, "inf", "force_sensor_V", "non-finite value 'inf'"},
      {"rec_003.csv", 14, 0, "-inf", "force_sensor_V", "non-finite value '-inf'"},
      {"rec_003.csv", 19, 1, "Infinity", "time_s", "non-finite value 'Infinity'"},
      {"rec_001.csv", 6, 0, "1e999", "time_s", "'1e999' is out of range"},
      {"rec_002.csv", 9, 2, "-2e400", "voltage_V", "'-2e400' is out of range"},
      {"rec_001.csv", 11, 2, "", "force_sensor_V", "empty cell in column 'force_sensor_V'"},
      {"rec_003.csv", 30, 2, "  ", "voltage_V", "empty cell in column 'voltage_V'"},
  };
  for (const Bad& bad : bad_cells) {
    const std::string fragment = bad.fragment.empty() ? "row has 5 columns, the header has 4"
                                                      : (bad.fragment.rfind("empty", 0) == 0
                                                             ? bad.fragment
                                                             : "column '" + bad.column_name + "': " + bad.fragment);
    add(
        "cell '" + bad.cell + "' " + bad.file + ":" + std::to_string(bad.line),
        [bad](Fixture& f) { f.SetCell(bad.file, bad.line, bad.column, bad.cell); },
        bad.file + ":" + std::to_string(bad.line), fragment);
  }
  // A blank line inside the data.
  add(
      "blank line", [](Fixture& f) { f.csv.at("rec_002.csv").insert(f.csv.at("rec_002.csv").begin() + 10, ""); },
      "rec_002.csv:11", "blank line among the data rows");
  add(
      "blank line after header",
      [](Fixture& f) { f.csv.at("rec_003.csv").insert(f.csv.at("rec_003.csv").begin() + 1, "  "); }, "rec_003.csv:2",
      "blank line among the data rows");
  // Header problems.
  add(
      "renamed response column", [](Fixture& f) { f.csv.at("rec_001.csv")[0] = "time_s,voltage_V,force_V"; },
      "rec_001.csv:1", "no column 'force_sensor_V' (header: time_s,voltage_V,force_V)");
  add(
      "renamed time column", [](Fixture& f) { f.csv.at("rec_003.csv")[0] = "force_sensor_V,time,voltage_V"; },
      "rec_003.csv:1", "no column 'time_s'");
  add(
      "renamed voltage column",
      [](Fixture& f) { f.csv.at("rec_002.csv")[0] = "time_s,temperature_C,Voltage_V,force_sensor_V"; }, "rec_002.csv:1",
      "no column 'voltage_V'");
  add(
      "no header", [](Fixture& f) { f.csv.at("rec_001.csv").erase(f.csv.at("rec_001.csv").begin()); }, "rec_001.csv:1",
      "no column 'time_s'");
  add(
      "duplicate column", [](Fixture& f) { f.csv.at("rec_002.csv")[0] = "time_s,voltage_V,voltage_V,force_sensor_V"; },
      "rec_002.csv:1", "column 'voltage_V' appears twice");
  add(
      "unnamed column", [](Fixture& f) { f.csv.at("rec_002.csv")[0] = "time_s,,voltage_V,force_sensor_V"; },
      "rec_002.csv:1", "column 2 of the header has no name");
  add(
      "empty file", [](Fixture& f) { f.raw["rec_002.csv"] = ""; }, "rec_002.csv:1", "empty file");
  add(
      "header only", [](Fixture& f) { f.csv.at("rec_003.csv").resize(1); }, "rec_003.csv:2", "no samples");
  add(
      "one sample", [](Fixture& f) { f.csv.at("rec_001.csv").resize(2); }, "rec_001.csv:2", "a single sample");
  // Time column problems: start, uniformity, rate.
  add(
      "time starts at 0.5 s", [](Fixture& f) { f.Retime("rec_001.csv", 1000, 0.5, 0); }, "rec_001.csv:2",
      "time column starts at t = 0.5 s");
  add(
      "time starts a sample late", [](Fixture& f) { f.Retime("rec_003.csv", 1000, 0.001, 1); }, "rec_003.csv:2",
      "the first sample must be at t = 0");
  add(
      "time glitch", [](Fixture& f) { f.SetCell("rec_002.csv", 21, 0, "0.0194"); }, "rec_002.csv:21",
      "time column is not uniform: it steps by");
  add(
      "dropped sample", [](Fixture& f) { f.csv.at("rec_001.csv").erase(f.csv.at("rec_001.csv").begin() + 15); },
      "rec_001.csv:16", "time column is not uniform");
  add(
      "repeated sample",
      [](Fixture& f) {
        auto& lines = f.csv.at("rec_003.csv");
        lines.insert(lines.begin() + 30, lines[29]);
      },
      "rec_003.csv:31", "time column is not uniform: it steps by 0 s");
  add(
      "swapped rows", [](Fixture& f) { std::swap(f.csv.at("rec_001.csv")[5], f.csv.at("rec_001.csv")[6]); },
      "rec_001.csv:6", "time column is not uniform");
  add(
      "time column at 900 Hz", [](Fixture& f) { f.Retime("rec_002.csv", 900, 0, 0); }, "rec_002.csv:5",
      "sample_rate_hz 1000 of manifest.json disagrees with the time column's 900 Hz");
  add(
      "manifest says 1100 Hz", [](Fixture& f) { f.manifest["sample_rate_hz"] = 1100; }, "rec_001.csv:5",
      "sample_rate_hz 1100 of manifest.json disagrees with the time column's 1000 Hz");
  add(
      "manifest says 2000 Hz for one record", [](Fixture& f) { f.manifest["records"][2]["sample_rate_hz"] = 2000; },
      "rec_003.csv:3", "sample_rate_hz 2000 of manifest.json:/records/2 disagrees with the time column's 1000 Hz");

  // Manifest problems.
  add(
      "no manifest", [](Fixture& f) { f.write_manifest = false; }, "manifest.json", "not found in");
  add(
      "manifest not JSON",
      [](Fixture& f) {
        f.manifest_text =
            "{\n  \"format\": \"strokelab-recordings/1\",\n  \"sample_rate_hz\": 1000,\n  \"channels\": {\n";
      },
      "manifest.json:5", "not valid JSON");
  add(
      "manifest number beyond a double",  // a fuzz finding: json's out_of_range went uncaught
      [](Fixture& f) { f.manifest_text = "{\n \"format\": 59375e397180\n}\n"; }, "manifest.json",
      "not valid JSON: number overflow parsing '59375e397180'");
  add(
      "manifest an array", [](Fixture& f) { f.manifest_text = "[1, 2]"; }, "manifest.json", "expected a JSON object");
  add(
      "format missing", [](Fixture& f) { f.manifest.erase("format"); }, "manifest.json:/format", "missing");
  add(
      "format other", [](Fixture& f) { f.manifest["format"] = "strokelab-recordings/2"; }, "manifest.json:/format",
      "unsupported format \"strokelab-recordings/2\"");
  add(
      "sample rate 0", [](Fixture& f) { f.manifest["sample_rate_hz"] = 0; }, "manifest.json:/sample_rate_hz",
      "must be a finite number > 0, got 0");
  add(
      "sample rate negative", [](Fixture& f) { f.manifest["sample_rate_hz"] = -51200; },
      "manifest.json:/sample_rate_hz", "must be a finite number > 0, got -51200");
  add(
      "sample rate a string", [](Fixture& f) { f.manifest["sample_rate_hz"] = "51.2 kHz"; },
      "manifest.json:/sample_rate_hz", "expected a number [Hz], got string");
  add(
      "sample rate missing", [](Fixture& f) { f.manifest.erase("sample_rate_hz"); }, "manifest.json:/sample_rate_hz",
      "missing");
  add(
      "record sample rate 0", [](Fixture& f) { f.manifest["records"][1]["sample_rate_hz"] = 0; },
      "manifest.json:/records/1/sample_rate_hz", "must be a finite number > 0");
  add(
      "unknown channel",
      [](Fixture& f) {
        f.manifest["channels"]["temperature"] = {{"column", "temperature_C"}};
      },
      "manifest.json:/channels/temperature", "unknown channel 'temperature'");
  add(
      "two response channels",
      [](Fixture& f) {
        f.manifest["channels"]["velocity"] = {{"column", "v_V"}, {"sensitivity_V_per_m_s", 1}};
      },
      "manifest.json:/channels/velocity", "a second response channel ('force' is one already)");
  add(
      "no response channel", [](Fixture& f) { f.manifest["channels"].erase("force"); }, "manifest.json:/channels",
      "no response channel");
  add(
      "no voltage channel", [](Fixture& f) { f.manifest["channels"].erase("voltage"); }, "manifest.json:/channels",
      "no 'voltage' channel");
  add(
      "channels missing", [](Fixture& f) { f.manifest.erase("channels"); }, "manifest.json:/channels", "missing");
  add(
      "column missing", [](Fixture& f) { f.manifest["channels"]["voltage"].erase("column"); },
      "manifest.json:/channels/voltage/column", "missing");
  add(
      "same column twice", [](Fixture& f) { f.manifest["channels"]["force"]["column"] = "voltage_V"; },
      "manifest.json:/channels/force/column", "the voltage channel's column too");
  add(
      "unit mV", [](Fixture& f) { f.manifest["channels"]["force"]["unit"] = "mV"; },
      "manifest.json:/channels/force/unit", "channels are recorded in volts");
  add(
      "sensitivity missing", [](Fixture& f) { f.manifest["channels"]["force"].erase("sensitivity_V_per_N"); },
      "manifest.json:/channels/force", "missing sensitivity_V_per_N");
  add(
      "sensitivity of another kind",
      [](Fixture& f) {
        f.manifest["channels"]["force"].erase("sensitivity_V_per_N");
        f.manifest["channels"]["force"]["sensitivity_V_per_m_s2"] = 0.01;
      },
      "manifest.json:/channels/force/sensitivity_V_per_m_s2",
      "is the key of acceleration channels; a force channel takes sensitivity_V_per_N");
  add(
      "sensitivity 0", [](Fixture& f) { f.manifest["channels"]["force"]["sensitivity_V_per_N"] = 0; },
      "manifest.json:/channels/force/sensitivity_V_per_N", "must be a finite number other than 0");
  add(
      "nominal not boolean", [](Fixture& f) { f.manifest["channels"]["force"]["nominal"] = "yes"; },
      "manifest.json:/channels/force/nominal", "expected true or false");
  add(
      "records empty", [](Fixture& f) { f.manifest["records"] = json::array(); }, "manifest.json:/records",
      "no records");
  add(
      "records missing", [](Fixture& f) { f.manifest.erase("records"); }, "manifest.json:/records", "missing");
  add(
      "record without file", [](Fixture& f) { f.manifest["records"][1].erase("file"); },
      "manifest.json:/records/1/file", "missing");
  add(
      "duplicate file", [](Fixture& f) { f.manifest["records"][2]["file"] = "rec_001.csv"; },
      "manifest.json:/records/2/file", "duplicate file name 'rec_001.csv' (also /records/0)");
  add(
      "duplicate file spelled differently", [](Fixture& f) { f.manifest["records"][1]["file"] = "./rec_001.csv"; },
      "manifest.json:/records/1/file", "duplicate file name './rec_001.csv'");
  add(
      "missing file", [](Fixture& f) { f.csv.erase("rec_002.csv"); }, "manifest.json:/records/1/file",
      "file 'rec_002.csv' not found in");
  add(
      "missing file listed last",
      [](Fixture& f) {
        f.manifest["records"].push_back({{"file", "rec_004.csv"}, {"drive_frequency_hz", 5}, {"drive_amplitude_v", 1}});
      },
      "manifest.json:/records/3/file", "file 'rec_004.csv' not found");
  add(
      "absolute path", [](Fixture& f) { f.manifest["records"][0]["file"] = "/etc/passwd"; },
      "manifest.json:/records/0/file", "not a path relative to the campaign directory");
  add(
      "parent path", [](Fixture& f) { f.manifest["records"][0]["file"] = "../rec_001.csv"; },
      "manifest.json:/records/0/file", "leaves the campaign directory");
  add(
      "frequency missing", [](Fixture& f) { f.manifest["records"][1].erase("drive_frequency_hz"); },
      "manifest.json:/records/1/drive_frequency_hz", "missing");
  add(
      "frequency negative", [](Fixture& f) { f.manifest["records"][0]["drive_frequency_hz"] = -6; },
      "manifest.json:/records/0/drive_frequency_hz", "must be a finite number > 0, got -6");
  add(
      "amplitude missing", [](Fixture& f) { f.manifest["records"][0].erase("drive_amplitude_v"); },
      "manifest.json:/records/0/drive_amplitude_v", "missing");
  add(
      "amplitude a string", [](Fixture& f) { f.manifest["records"][1]["drive_amplitude_v"] = "0.2 V"; },
      "manifest.json:/records/1/drive_amplitude_v", "expected a number [V], got string");
  add(
      "unknown excitation", [](Fixture& f) { f.manifest["records"][2]["excitation"] = "chirp"; },
      "manifest.json:/records/2/excitation", "unknown excitation 'chirp'");
  add(
      "broadband with a frequency", [](Fixture& f) { f.manifest["records"][2]["drive_frequency_hz"] = 5; },
      "manifest.json:/records/2/drive_frequency_hz", "a broadband record has no nominal drive frequency");
  add(
      "record not an object", [](Fixture& f) { f.manifest["records"][1] = "rec_002.csv"; }, "manifest.json:/records/1",
      "expected an object");
  return d;
}

TEST(MalformedCampaign, EachDefectNamesItsFileAndLine) {
  const std::vector<Defect> defects = Defects();
  std::printf("%zu malformed campaigns\n", defects.size());
  EXPECT_GE(defects.size(), 50u);
  size_t index = 0;
  for (const Defect& defect : defects) {
    SCOPED_TRACE(defect.name);
    Fixture fixture;
    defect.apply(fixture);
    const fs::path dir = fixture.Write("defect_" + std::to_string(index++));
    try {
      ReadCampaign(dir);
      ADD_FAILURE() << defect.name << ": read without error";
    } catch (const InputError& e) {
      EXPECT_EQ(e.field(), defect.field) << e.what();
      EXPECT_THAT(e.bare_message(), HasSubstr(defect.fragment)) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << "one line: " << e.what();
    } catch (const std::exception& e) {
      ADD_FAILURE() << defect.name << ": not an InputError: " << e.what();
    }
    fs::remove_all(dir);
  }
}

TEST(MalformedCampaign, SampleRateOffByATenthOfAPercentIsCaughtOnALongRecord) {
  // 1 s at 51.2 kHz written at 51251.2 Hz: the time column drifts a quarter sample after ~250 samples.
  Campaign campaign;
  Recording record;
  record.name = "long.csv";
  record.sample_rate_hz = 51251.2;
  record.nominal_frequency_hz = 8;
  record.nominal_amplitude_v = 0.4;
  record.voltage_v.assign(51200, 0.1);
  record.response.assign(51200, 0.2);
  campaign.records.push_back(record);
  const fs::path dir = TempDir("rate_off");
  WriteCampaign(campaign, dir);
  json manifest = json::parse(ReadText(dir / "manifest.json"));
  manifest["sample_rate_hz"] = 51200;
  std::ofstream(dir / "manifest.json") << manifest.dump();
  try {
    ReadCampaign(dir);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    // |n / 51200 - n / 51251.2| > 0.25 / 51200 + 1e-6 t first at n = 251 -> line 253.
    EXPECT_EQ(e.field(), "long.csv:253");
    EXPECT_THAT(e.bare_message(),
                HasSubstr("sample_rate_hz 51200 of manifest.json disagrees with the time column's 51251.2 Hz"));
  }
  fs::remove_all(dir);
}

// ---- Synthesis ---------------------------------------------------------------------------------

SynthOptions SmallSynth() {
  SynthOptions options;
  options.frequencies_hz = {8, 13};
  options.amplitudes_v = {0.2, 0.5};
  options.duration_s = 0.5;
  options.settle_s = 0.75;
  options.sample_rate_hz = 8192;
  return options;
}

// The engine's record of one SmallSynth step (0.75 s of settling, then the kept 0.5 s), and the index
// of its first kept sample.
Record SmallSynthStep(const ActuatorModel& model, const SineDrive& drive) {
  SimulationOptions simulation;
  simulation.duration_s = 1.25;
  simulation.sample_rate_hz = 8192;
  return MakeExactEngine()->Simulate(model, drive, simulation);
}
constexpr size_t kSmallSynthFirstKept = 10240 - 4096;

TEST(Synthesize, CleanChannelsAreTheEngineRecordInSensorVolts) {
  const ActuatorModel model = PaperModel();
  for (ResponseKind kind :
       {ResponseKind::kForce, ResponseKind::kAcceleration, ResponseKind::kVelocity, ResponseKind::kDisplacement}) {
    SynthOptions options = SmallSynth();
    options.response = kind;
    const Synthesis synthesis = Synthesize(model, options);
    EXPECT_EQ(synthesis.method, Method::kExact);
    ASSERT_EQ(synthesis.campaign.records.size(), 4u);
    const Recording& rec = synthesis.campaign.records[3];  // 13 Hz, 0.5 V: in contact
    EXPECT_EQ(rec.name, "rec_004.csv");
    EXPECT_EQ(rec.nominal_frequency_hz, 13.0);
    EXPECT_EQ(rec.nominal_amplitude_v, 0.5);
    ASSERT_EQ(rec.size(), 4096u);

    SineDrive drive;
    drive.frequency_hz = 13;
    drive.amplitude_v = 0.5;
    const Record record = SmallSynthStep(model, drive);
    const size_t first = kSmallSynthFirstKept;
    for (size_t n = 0; n < rec.size(); n += 97) {
      const double expected = kind == ResponseKind::kForce          ? record.force_n[first + n]
                              : kind == ResponseKind::kAcceleration ? record.force_n[first + n] / model.mass_kg
                              : kind == ResponseKind::kVelocity     ? record.velocity_m_per_s[first + n]
                                                                    : record.displacement_m[first + n];
      EXPECT_NEAR(rec.response[n], expected, 1e-12 * std::abs(expected) + 1e-300) << ToString(kind) << " n=" << n;
      EXPECT_NEAR(rec.voltage_v[n], drive.Voltage(static_cast<double>(first + n) / 8192), 1e-15);
    }
    EXPECT_FALSE(synthesis.truth.contains("drive_frequency_error"));  // unset: the truth as before
    EXPECT_FALSE(synthesis.truth["records"][3].contains("drive_phase_rad"));
  }

  // A generator 0.1 % fast, each drive at its own phase and a sensor 10 % above its written
  // sensitivity: the channels are the engine's record of that drive, the manifest keeps the nominal.
  SynthOptions off = SmallSynth();
  off.drive_frequency_error = 1e-3;
  off.random_drive_phase = true;
  off.sensitivity_error = 0.1;
  const Synthesis synthesis = Synthesize(model, off);
  const Recording& rec = synthesis.campaign.records[3];
  EXPECT_EQ(rec.nominal_frequency_hz, 13.0);
  EXPECT_EQ(synthesis.truth["drive_frequency_error"], 1e-3);
  EXPECT_DOUBLE_EQ(synthesis.truth["sensitivity_true"].get<double>(), 1.1 * synthesis.write.sensitivity);
  const double phase = synthesis.truth["records"][3]["drive_phase_rad"].get<double>();
  EXPECT_GE(phase, -std::numbers::pi);
  EXPECT_LT(phase, std::numbers::pi);
  EXPECT_NE(phase, synthesis.truth["records"][2]["drive_phase_rad"].get<double>());
  SineDrive drive;
  drive.frequency_hz = 13 * (1.0 + 1e-3);  // as the synthesiser computes it
  drive.amplitude_v = 0.5;
  drive.phase_rad = phase;
  const Record record = SmallSynthStep(model, drive);
  const size_t first = kSmallSynthFirstKept;
  for (size_t n = 0; n < rec.size(); n += 97) {
    const double expected = 1.1 * record.force_n[first + n];
    EXPECT_NEAR(rec.response[n], expected, 1e-12 * std::abs(expected) + 1e-300) << "n=" << n;
    EXPECT_NEAR(rec.voltage_v[n], drive.Voltage(static_cast<double>(first + n) / 8192), 1e-15);
  }
}

TEST(Synthesize, NoiseOffsetAndHumHaveTheirSettingsAndDependOnTheSeedOnly) {
  const ActuatorModel model = PaperModel();
  SynthOptions clean = SmallSynth();
  SynthOptions dirty = clean;
  dirty.noise_rms_v = 2e-3;
  dirty.voltage_noise_rms_v = 1e-4;
  dirty.offset_v = 0.05;
  dirty.hum_v = 0.01;
  dirty.voltage_offset_v = 2e-3;
  dirty.seed = 42;
  dirty.threads = 1;
  const Synthesis a = Synthesize(model, clean);
  const Synthesis b = Synthesize(model, dirty);
  dirty.threads = 3;
  const Synthesis c = Synthesize(model, dirty);
  const double s = DefaultSensitivity(ResponseKind::kForce);
  for (size_t k = 0; k < 4; ++k) {
    EXPECT_EQ(b.campaign.records[k].response, c.campaign.records[k].response) << "thread count changed the result";
    EXPECT_EQ(b.campaign.records[k].voltage_v, c.campaign.records[k].voltage_v);
    // The added signal in sensor volts: offset + hum + noise.
    const size_t count = a.campaign.records[k].size();
    const double hum_phase = b.truth["records"][k]["hum_phase_rad"].get<double>();
    double mean = 0, noise_square = 0, voltage_mean = 0, voltage_square = 0;
    for (size_t n = 0; n < count; ++n) {
      const double added = (b.campaign.records[k].response[n] - a.campaign.records[k].response[n]) * s;
      mean += added;
      const double hum = 0.01 * std::sin(2 * std::numbers::pi * 50 * static_cast<double>(n) / 8192 + hum_phase);
      noise_square += std::pow(added - 0.05 - hum, 2);
      const double voltage_added = b.campaign.records[k].voltage_v[n] - a.campaign.records[k].voltage_v[n];
      voltage_mean += voltage_added;
      voltage_square += std::pow(voltage_added - 2e-3, 2);
    }
    // 4096 samples: the rms estimate is within ~1.1 % (1 sigma), the mean within 3e-5 V (the
    // voltage's within 1.6e-6 V).
    EXPECT_NEAR(mean / count, 0.05, 2e-4);
    EXPECT_NEAR(voltage_mean / count, 2e-3, 1e-5);
    EXPECT_NEAR(std::sqrt(noise_square / count), 2e-3, 2e-3 * 0.06);
    EXPECT_NEAR(std::sqrt(voltage_square / count), 1e-4, 1e-4 * 0.06);
  }
  EXPECT_EQ(b.truth["voltage_offset_v"], 2e-3);
  EXPECT_FALSE(a.truth.contains("voltage_offset_v"));
  dirty.seed = 43;
  const Synthesis d = Synthesize(model, dirty);
  EXPECT_NE(d.campaign.records[0].response, b.campaign.records[0].response);
}

TEST(Synthesize, PerturbationsAreRelativeDrawsRecordedInTheTruth) {
  SynthOptions options = SmallSynth();
  options.frequencies_hz = {8};
  options.amplitudes_v = {0.1};
  options.perturb = {{"k_p", 0.03}, {"damping_n_s_per_m", 0.05}, {"sensitivity", 0.1}, {"k3", 0.5}};
  options.seed = 5;
  const ActuatorModel nominal = PaperModel();
  const Synthesis synthesis = Synthesize(nominal, options);
  const json& p = synthesis.truth["perturbations"];
  ASSERT_EQ(p.size(), 4u);
  EXPECT_EQ(p[0]["key"], "k_p");
  EXPECT_EQ(p[1]["key"], "c_p");
  EXPECT_NEAR(p[0]["factor"].get<double>(), 1.0, 0.03);
  EXPECT_NEAR(p[1]["factor"].get<double>(), 1.0, 0.05);
  EXPECT_NE(p[0]["factor"].get<double>(), 1.0);
  EXPECT_DOUBLE_EQ(synthesis.model.stiffness_n_per_m, nominal.stiffness_n_per_m * p[0]["factor"].get<double>());
  EXPECT_DOUBLE_EQ(synthesis.model.damping_n_s_per_m, nominal.damping_n_s_per_m * p[1]["factor"].get<double>());
  EXPECT_EQ(synthesis.model.cubic_stiffness_n_per_m3, 0.0);  // zero stays zero
  EXPECT_DOUBLE_EQ(synthesis.truth["sensitivity_true"].get<double>(), 0.02248 * p[2]["factor"].get<double>());
  EXPECT_EQ(synthesis.truth["model"]["stiffness_n_per_m"].get<double>(), synthesis.model.stiffness_n_per_m);
  EXPECT_EQ(synthesis.write.sensitivity, 0.02248);
}

TEST(Synthesize, RejectsBadOptionsNamingTheField) {
  const auto expect_refused = [](SynthOptions options, const std::string& field, const std::string& fragment) {
    try {
      Synthesize(PaperModel(), options);
      ADD_FAILURE() << "no error for " << field;
    } catch (const InputError& e) {
      EXPECT_EQ(e.field(), field) << e.what();
      EXPECT_THAT(e.bare_message(), HasSubstr(fragment));
    }
  };
  SynthOptions o = SmallSynth();
  o.frequencies_hz = {};
  expect_refused(o, "frequencies_hz", "at least one");
  o = SmallSynth();
  o.frequencies_hz = {8, 5000};
  expect_refused(o, "frequencies_hz", "Nyquist");
  o = SmallSynth();
  o.noise_rms_v = -1;
  expect_refused(o, "noise_rms_v", ">= 0");
  o = SmallSynth();
  o.perturb = {{"k9", 0.1}};
  expect_refused(o, "perturb", "'k9': unknown model parameter");
  o = SmallSynth();
  o.perturb = {{"k_p", 1.5}};
  expect_refused(o, "perturb", "must be in [0, 1)");
  o = SmallSynth();
  o.perturb = {{"k_p", 0.1}, {"stiffness_n_per_m", 0.1}};
  expect_refused(o, "perturb", "perturbed twice");
  o = SmallSynth();
  o.voltage_offset_v = INFINITY;
  expect_refused(o, "voltage_offset_v", "finite");
  o = SmallSynth();
  o.drive_frequency_error = -1;
  expect_refused(o, "drive_frequency_error", "in (-1, 1)");
  o = SmallSynth();
  o.frequencies_hz = {8, 4000};  // below the Nyquist frequency of 4096 Hz, but driven at 4400
  o.drive_frequency_error = 0.1;
  expect_refused(o, "drive_frequency_error", "drives 4000 Hz at 4400 Hz");
  o = SmallSynth();
  o.sensitivity_error = -1;
  expect_refused(o, "sensitivity_error", "> -1");
  o = SmallSynth();
  o.sensitivity_error = 0.1;
  o.perturb = {{"sensitivity", 0.1}};
  expect_refused(o, "sensitivity_error", "do not go together");
}

// ---- strokelab synth end to end ----------------------------------------------------------------

TEST(SynthCli, WritesACampaignThatReadsBackAndKeepsTheTruthApart) {
  const fs::path dir = TempDir("synth_cli");
  const std::string args = "synth --out " + dir.string() +
                           " --frequencies-hz 8,13 --amplitudes-v 0.2,0.5 --duration-s 0.5 --settle-s 0.75"
                           " --sample-rate-hz 8192 --noise-rms 1e-4 --voltage-noise-rms 1e-5 --offset-v 0.01"
                           " --hum-v 0.002 --perturb k_p=0.03,c_p=0.05 --seed 7 --response acceleration";
  const auto result = testing::RunCli(args);
  ASSERT_EQ(result.exit_code, 0) << result.stderr_text;
  EXPECT_THAT(result.stdout_text, HasSubstr("wrote 4 records"));
  const Campaign campaign = ReadCampaign(dir);
  EXPECT_EQ(campaign.response, ResponseKind::kAcceleration);
  ASSERT_EQ(campaign.records.size(), 4u);
  for (size_t k = 0; k < 4; ++k) {
    EXPECT_EQ(campaign.records[k].size(), 4096u);
    EXPECT_EQ(campaign.records[k].sample_rate_hz, 8192.0);
    EXPECT_EQ(campaign.records[k].nominal_frequency_hz, k % 2 == 0 ? 8.0 : 13.0);
    EXPECT_EQ(campaign.records[k].nominal_amplitude_v, k < 2 ? 0.2 : 0.5);
  }
  ASSERT_TRUE(fs::is_regular_file(dir / "truth.json"));
  const json truth = json::parse(ReadText(dir / "truth.json"));
  EXPECT_EQ(truth["seed"], 7);
  EXPECT_EQ(truth["method"], "exact");
  EXPECT_EQ(truth["perturbations"].size(), 2u);
  EXPECT_EQ(truth["offset_v"], 0.01);
  // The manifest knows nothing of the truth.
  const std::string manifest = ReadText(dir / "manifest.json");
  for (const char* secret : {"stiffness", "k_p", "seed", "noise", "perturb", "truth", "offset", "hum"})
    EXPECT_THAT(manifest, ::testing::Not(HasSubstr(secret))) << secret;

  // The same command again gives the same files (the seed fixes everything).
  const fs::path again = TempDir("synth_cli_again");
  std::string args_again = args;
  args_again.replace(args_again.find(dir.string()), dir.string().size(), again.string());
  ASSERT_EQ(testing::RunCli(args_again).exit_code, 0);
  EXPECT_EQ(ReadText(dir / "rec_003.csv"), ReadText(again / "rec_003.csv"));
  fs::remove_all(dir);
  fs::remove_all(again);
}

TEST(SynthCli, ChoosesCvodeForSmoothNonlinearModelsAndNamesBadFlags) {
  const fs::path dir = TempDir("synth_cvode");
  const fs::path truth = TempDir("synth_truth") / "elsewhere.json";
  const auto result = testing::RunCli("synth --out " + dir.string() + " --truth " + truth.string() +
                                      " --set k3=4e7 --frequencies-hz 9 --amplitudes-v 0.3 --duration-s 0.2"
                                      " --settle-s 0.3 --sample-rate-hz 4096");
  ASSERT_EQ(result.exit_code, 0) << result.stderr_text;
  EXPECT_FALSE(fs::exists(dir / "truth.json"));
  ASSERT_TRUE(fs::is_regular_file(truth));
  EXPECT_EQ(json::parse(ReadText(truth))["method"], "cvode");
  EXPECT_EQ(ReadCampaign(dir).records.at(0).size(), 819u);

  const auto expect_error = [](const std::string& args, const std::string& fragment) {
    const auto r = testing::RunCli(args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.stderr_text;
    EXPECT_THAT(r.stderr_text, HasSubstr(fragment)) << args;
  };
  expect_error("synth --frequencies-hz 8", "--out: is required");
  expect_error("synth --out " + dir.string() + " --response torque", "--response: unknown response channel 'torque'");
  expect_error("synth --out " + dir.string() + " --perturb k9=0.1", "--perturb: 'k9': unknown model parameter");
  expect_error("synth --out " + dir.string() + " --perturb k_p", "--perturb: expected KEY=RELATIVE");
  expect_error("synth --out " + dir.string() + " --frequencies-hz 8,x", "--frequencies-hz: expected a number, got 'x'");
  expect_error("synth --out " + dir.string() + " --noise-rms -1", "--noise-rms: must be a finite number >= 0");
  expect_error("synth --out " + dir.string() + " --seed -3", "--seed: expected a non-negative integer");
  expect_error("synth --out " + dir.string() + " --set k3=4e7 --method exact",
               "the exact engine needs a piecewise-linear model");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace strokelab
