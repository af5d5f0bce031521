// Malformed campaigns, written out by hand one defect at a time from Fixture (a small valid campaign,
// recordings_test_util.h): each must be refused naming its file and line, or its manifest pointer.
// The generated defects, through the library and `strokelab fit --data`: malformed_cli_test.cc.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "strokelab/base/errors.h"
#include "strokelab/data/recordings.h"

#include "recordings_test_util.h"

namespace strokelab {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::testing::HasSubstr;
using recordings_test::Fixture;
using recordings_test::ReadText;
using recordings_test::TempDir;

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

}  // namespace
}  // namespace strokelab
