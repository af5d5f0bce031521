// Malformed campaigns, generated: a valid two-record campaign (WriteCampaign) is broken one way at a
// time: every cell defect at the first, a middle and the last row of each file, every header column
// renamed, files emptied or cut to the header, the manifest's rate against the time column, and the
// manifest's own defects. Each must be refused with an InputError whose field names the file and
// line (a CSV line from 1, the header being line 1) or the manifest (its line when it is not JSON,
// else the JSON pointer of the offending value, which locates it better than a line could) by
// ReadCampaign, AND by `strokelab fit --data DIR`, which exits 2 with that error as one line.
//
// CRLF line ends and a UTF-8 byte-order mark are accepted (data/include/strokelab/
// data/recordings.h): spreadsheet tools on Windows write both, and neither makes a number ambiguous.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "strokelab/base/errors.h"
#include "strokelab/data/recordings.h"

namespace strokelab {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::testing::HasSubstr;

constexpr int kSamples = 40;                     // per record
constexpr double kSampleRateHz = 1000;           // [Hz]
const std::vector<std::string> kFiles = {"rec_001.csv", "rec_002.csv"};
const std::vector<std::string> kColumns = {"time_s", "voltage_V", "force_sensor_V"};

// The valid campaign as editable text: manifest JSON and each CSV's lines (header first).
struct CampaignText {
  json manifest;
  std::string manifest_text;  // written instead of `manifest` when not empty
  std::map<std::string, std::vector<std::string>> csv;
  std::map<std::string, std::string> raw;  // whole-file bytes instead of `csv` lines
  bool write_manifest = true;

  static CampaignText Valid(const fs::path& scratch) {
    Campaign campaign;
    for (int r = 0; r < 2; ++r) {
      Recording rec;
      rec.sample_rate_hz = kSampleRateHz;
      rec.nominal_frequency_hz = 8 + r;
      rec.nominal_amplitude_v = 0.2;
      for (int n = 0; n < kSamples; ++n) {
        rec.voltage_v.push_back(0.2 * std::sin(0.05 * n * (r + 1)));
        rec.response.push_back(0.5 * std::cos(0.05 * n));
      }
      campaign.records.push_back(rec);
    }
    WriteCampaign(campaign, scratch);
    CampaignText text;
    text.manifest = json::parse(ReadText(scratch / kManifestName));
    for (const std::string& file : kFiles) {
      std::istringstream lines(ReadText(scratch / file));
      for (std::string line; std::getline(lines, line);) text.csv[file].push_back(line);
    }
    return text;
  }

  static std::string ReadText(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
  }

  void SetCell(const std::string& file, size_t line, size_t column, const std::string& value) {
    std::vector<std::string> cells;
    std::istringstream row(csv.at(file).at(line - 1));
    for (std::string cell; std::getline(row, cell, ',');) cells.push_back(cell);
    cells.at(column) = value;
    std::string joined;
    for (size_t c = 0; c < cells.size(); ++c) joined += (c ? "," : "") + cells[c];
    csv.at(file).at(line - 1) = joined;
  }

  void Write(const fs::path& dir) const {
    fs::create_directories(dir);
    if (write_manifest) std::ofstream(dir / kManifestName) << (manifest_text.empty() ? manifest.dump(2) : manifest_text);
    for (const auto& [file, lines] : csv) {
      if (raw.count(file)) continue;
      std::ofstream out(dir / file, std::ios::binary);
      for (const std::string& line : lines) out << line << "\n";
    }
    for (const auto& [file, bytes] : raw) std::ofstream(dir / file, std::ios::binary) << bytes;
  }
};

struct TextDefect {
  std::string name;                          // what is broken
  std::function<void(CampaignText&)> apply;  // breaks it
  std::string field, fragment;               // the error's field, exactly; a piece of its message
};

std::vector<TextDefect> Generate() {
  std::vector<TextDefect> out;
  const size_t last = kSamples + 1;  // the last data line
  for (const std::string& file : kFiles) {
    for (const size_t line : {size_t{2}, size_t{kSamples / 2}, last}) {
      const std::string at = file + ":" + std::to_string(line);
      const auto cell = [&](size_t column, const std::string& value, const std::string& fragment) {
        out.push_back({at + " column " + std::to_string(column) + " '" + value + "'",
                       [=](CampaignText& c) { c.SetCell(file, line, column, value); }, at,
                       "column '" + kColumns[column] + "': " + fragment});
      };
      cell(1, "abc", "'abc' is not a number");
      cell(2, "1.2.3", "'1.2.3' is not a number");
      cell(2, "nan", "non-finite value 'nan'");
      cell(1, "-inf", "non-finite value '-inf'");
      cell(0, "1e999", "'1e999' is out of range");
      out.push_back({at + " empty cell", [=](CampaignText& c) { c.SetCell(file, line, 2, ""); }, at,
                     "empty cell in column 'force_sensor_V'"});
      out.push_back({at + " truncated",
                     [=](CampaignText& c) {
                       std::string& row = c.csv.at(file).at(line - 1);
                       row = row.substr(0, row.rfind(','));
                     },
                     at, "row has 2 columns, the header has 3 (truncated row?)"});
      out.push_back({at + " extra cell", [=](CampaignText& c) { c.csv.at(file).at(line - 1) += ",7"; }, at,
                     "row has 4 columns, the header has 3"});
    }
    for (size_t column = 0; column < kColumns.size(); ++column) {
      out.push_back({file + " header without " + kColumns[column],
                     [=](CampaignText& c) {
                       std::vector<std::string> names = kColumns;
                       names[column] += "_x";
                       c.csv.at(file)[0] = names[0] + "," + names[1] + "," + names[2];
                     },
                     file + ":1", "no column '" + kColumns[column] + "'"});
    }
    out.push_back({file + " empty", [=](CampaignText& c) { c.raw[file] = ""; }, file + ":1", "empty file"});
    out.push_back({file + " header only", [=](CampaignText& c) { c.csv.at(file).resize(1); }, file + ":2",
                   "no samples"});
    out.push_back({file + " missing", [=](CampaignText& c) { c.csv.erase(file); },
                   std::string("manifest.json:/records/") + (file == kFiles[0] ? "0" : "1") + "/file",
                   "file '" + file + "' not found"});
  }
  // The manifest's rate against the time column, and the manifest's own defects.
  out.push_back({"rate 1100 Hz against a 1000 Hz column", [](CampaignText& c) { c.manifest["sample_rate_hz"] = 1100; },
                 "rec_001.csv:5", "sample_rate_hz 1100 of manifest.json disagrees with the time column's 1000 Hz"});
  out.push_back({"no manifest", [](CampaignText& c) { c.write_manifest = false; }, "manifest.json", "not found in"});
  // The manifest cut at three places: the error is at the end of input, on the cut's last line.
  const std::string manifest = CampaignText::Valid(fs::temp_directory_path() / "strokelab-malformed-base").manifest.dump(2);
  for (const size_t cut : {size_t{60}, manifest.size() / 2, manifest.size() - 3}) {
    const std::string head = manifest.substr(0, cut);
    const size_t line = 1 + static_cast<size_t>(std::count(head.begin(), head.end(), '\n'));
    out.push_back({"manifest cut at byte " + std::to_string(cut), [=](CampaignText& c) { c.manifest_text = head; },
                   "manifest.json:" + std::to_string(line), "not valid JSON"});
  }
  out.push_back({"negative frequency", [](CampaignText& c) { c.manifest["records"][1]["drive_frequency_hz"] = -8; },
                 "manifest.json:/records/1/drive_frequency_hz", "must be a finite number > 0, got -8"});
  out.push_back({"duplicate record", [](CampaignText& c) { c.manifest["records"][1]["file"] = kFiles[0]; },
                 "manifest.json:/records/1/file", "duplicate file name 'rec_001.csv' (also /records/0)"});
  out.push_back({"unknown channel", [](CampaignText& c) { c.manifest["channels"]["strain"] = {{"column", "s_V"}}; },
                 "manifest.json:/channels/strain", "unknown channel 'strain'"});
  return out;
}

struct CliRun {
  int exit_code;
  std::string output;
};

CliRun Fit(const fs::path& dir) {
  const std::string command = std::string(STROKELAB_BINARY) + " fit --data " + dir.string() + " 2>&1";
  FILE* pipe = ::popen(command.c_str(), "r");
  std::string output;
  char buffer[4096];
  for (size_t n; pipe && (n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0;) output.append(buffer, n);
  const int status = pipe ? ::pclose(pipe) : -1;
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, output};
}

fs::path Scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("strokelab-malformed-" + std::to_string(::getpid())) / name;
  fs::remove_all(dir);
  return dir;
}

TEST(MalformedCampaignGenerated, LibraryAndCliNameTheFileAndLine) {
  const CampaignText valid = CampaignText::Valid(Scratch("valid"));
  const std::vector<TextDefect> defects = Generate();
  std::printf("[          ] %zu malformed campaigns\n", defects.size());
  ASSERT_GE(defects.size(), 50u);
  for (size_t i = 0; i < defects.size(); ++i) {
    const TextDefect& d = defects[i];
    SCOPED_TRACE(d.name);
    CampaignText text = valid;
    d.apply(text);
    const fs::path dir = Scratch("case_" + std::to_string(i));
    text.Write(dir);
    try {
      ReadCampaign(dir);
      ADD_FAILURE() << "read without error";
    } catch (const InputError& e) {
      EXPECT_EQ(e.field(), d.field) << e.what();
      EXPECT_THAT(e.bare_message(), HasSubstr(d.fragment));
    }
    const CliRun run = Fit(dir);
    EXPECT_EQ(run.exit_code, 2) << run.output;
    EXPECT_EQ(run.output.rfind("strokelab: error: " + d.field + ": ", 0), 0u) << run.output;
    EXPECT_THAT(run.output, HasSubstr(d.fragment));
    EXPECT_EQ(run.output.find('\n'), run.output.size() - 1) << "one line: " << run.output;
  }
  fs::remove_all(Scratch("").parent_path());
  fs::remove_all(fs::temp_directory_path() / "strokelab-malformed-base");
}

TEST(MalformedCampaignGenerated, CrlfAndByteOrderMarkAreAccepted) {
  CampaignText text = CampaignText::Valid(Scratch("valid"));
  for (const std::string& file : kFiles) {
    std::string bytes = "\xEF\xBB\xBF";
    for (const std::string& line : text.csv.at(file)) bytes += line + "\r\n";
    text.raw[file] = bytes;
  }
  const fs::path dir = Scratch("crlf");
  text.Write(dir);
  const Campaign campaign = ReadCampaign(dir);
  ASSERT_EQ(campaign.records.size(), 2u);
  EXPECT_EQ(campaign.records[1].size(), static_cast<size_t>(kSamples));
  fs::remove_all(Scratch("").parent_path());
}

}  // namespace
}  // namespace strokelab
