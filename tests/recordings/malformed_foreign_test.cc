// Malformed UFF 58, WAV and mapping files, generated: a valid small campaign (WriteMappedCampaign)
// is broken one way at a time; each must be refused by ReadCampaign with an InputError whose field
// names the file and line (UFF ASCII, and a 58b dataset's header), the byte offset (58b data, WAV
// chunks) or the mapping's JSON pointer, and whose message names the dataset; `strokelab fit --data`
// gives the same error and exits 2.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli/run_cli.h"
#include "strokelab/base/errors.h"
#include "strokelab/data/mapping.h"
#include "strokelab/data/recordings.h"

#include "recordings_test_util.h"

namespace strokelab {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::testing::HasSubstr;
using recordings_test::ReadText;
using recordings_test::TempDir;

constexpr size_t kValues = 40;  // per dataset: 10 data lines of 4E20.12
// Line numbers of the UFF files WriteMappedCampaign writes (one file per record: the voltage as
// dataset 1, the response as dataset 2): -1, 58, records 1-11, 10 data lines, -1.
constexpr size_t kDataset2 = 25;                 // its opening -1
constexpr size_t kRecord6(size_t open) { return open + 7; }
constexpr size_t kRecord7(size_t open) { return open + 8; }
constexpr size_t kRecord8(size_t open) { return open + 9; }
constexpr size_t kRecord9(size_t open) { return open + 10; }

Campaign TwoRecords() {
  Campaign campaign;
  campaign.actuator = "malformed";
  for (int r = 0; r < 2; ++r) {
    Recording rec;
    rec.sample_rate_hz = 1000;
    rec.nominal_frequency_hz = 8 + r;
    rec.nominal_amplitude_v = 0.2;
    for (size_t n = 0; n < kValues; ++n) {
      rec.voltage_v.push_back(0.2 * std::sin(0.05 * static_cast<double>(n) * (r + 1)));
      rec.response.push_back(0.5 * std::cos(0.05 * static_cast<double>(n)) - 0.1);
    }
    campaign.records.push_back(rec);
  }
  return campaign;
}

fs::path WriteValid(const std::string& name, CampaignFormat format) {
  const fs::path dir = TempDir(name);
  MappedWriteOptions options;
  options.format = format;
  options.wav_format = WavSampleFormat::kInt16;
  WriteMappedCampaign(TwoRecords(), dir, options);
  return dir;
}

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  size_t start = 0;
  while (start < text.size()) {
    const size_t end = text.find('\n', start);
    lines.push_back(text.substr(start, end - start));
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return lines;
}

std::string Join(const std::vector<std::string>& lines) {
  std::string out;
  for (const std::string& line : lines) out += line + "\n";
  return out;
}

// Edits line `line` (from 1) of `file` in `dir`.
void EditLine(const fs::path& dir, const std::string& file, size_t line,
              const std::function<void(std::string&)>& edit) {
  std::vector<std::string> lines = Lines(ReadText(dir / file));
  edit(lines.at(line - 1));
  std::ofstream(dir / file, std::ios::binary) << Join(lines);
}

void Replace(std::string& text, size_t begin, size_t width, const std::string& value) {
  text.replace(begin, width, value);
}

void ExpectRefused(const fs::path& dir, const std::string& field, const std::string& fragment) {
  try {
    ReadCampaign(dir);
    ADD_FAILURE() << "accepted; expected " << field << ": " << fragment;
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), field) << e.what();
    EXPECT_THAT(e.bare_message(), HasSubstr(fragment)) << e.what();
  }
}

TEST(MalformedUff, AsciiDefectsNameTheFileDatasetAndLine) {
  const auto check = [](const std::string& name, const std::function<void(const fs::path&)>& breaks,
                        const std::string& field, const std::string& fragment) {
    SCOPED_TRACE(name);
    const fs::path dir = WriteValid("uff_" + name, CampaignFormat::kUff58);
    breaks(dir);
    ExpectRefused(dir, field, fragment);
  };
  // A file cut inside dataset 2's values (after 6 lines of 4).
  check(
      "truncated",
      [](const fs::path& dir) {
        std::vector<std::string> lines = Lines(ReadText(dir / "rec_002.uff"));
        lines.resize(kDataset2 + 12 + 6);
        std::ofstream(dir / "rec_002.uff", std::ios::binary) << Join(lines);
      },
      "rec_002.uff:43", "dataset 2 (58): truncated dataset: the file ends after 24 of its 40 values");
  check(
      "cut in header",
      [](const fs::path& dir) {
        std::vector<std::string> lines = Lines(ReadText(dir / "rec_001.uff"));
        lines.resize(kDataset2 + 5);
        std::ofstream(dir / "rec_001.uff", std::ios::binary) << Join(lines);
      },
      "rec_001.uff:31", "dataset 2 (58): truncated dataset: the file ends in its header (record 5 of 11)");
  check(
      "bad record 7",
      [](const fs::path& dir) { EditLine(dir, "rec_001.uff", kRecord7(1), [](std::string& l) { l = "  four  forty  one"; }); },
      "rec_001.uff:9", "dataset 1 (58): bad header line: expected the data form");
  check(
      "bad type line",
      [](const fs::path& dir) { EditLine(dir, "rec_001.uff", kDataset2 + 1, [](std::string& l) { l = "  fifty-eight"; }); },
      "rec_001.uff:26", "dataset 2 (?): bad header line: expected the dataset type (I6)");
  check(
      "no delimiter",
      [](const fs::path& dir) { EditLine(dir, "rec_002.uff", kDataset2, [](std::string& l) { l = "    -2"; }); },
      "rec_002.uff:25", "dataset 2 (?): bad header line: expected -1 opening a dataset, got '-2'");
  check(
      "one value more announced",
      [](const fs::path& dir) { EditLine(dir, "rec_001.uff", kRecord7(1), [](std::string& l) { Replace(l, 10, 10, "        41"); }); },
      "rec_001.uff:24", "dataset 1 (58): wrong record length: the dataset ends after 40 of the 41 values record 7 announces");
  check(
      "one value fewer announced",
      [](const fs::path& dir) { EditLine(dir, "rec_002.uff", kRecord7(kDataset2), [](std::string& l) { Replace(l, 10, 10, "        39"); }); },
      "rec_002.uff:47", "dataset 2 (58): wrong record length: more than the 39 values record 7 announces");
  check(
      "function type 4",
      [](const fs::path& dir) { EditLine(dir, "rec_001.uff", kRecord6(kDataset2), [](std::string& l) { Replace(l, 0, 5, "    4"); }); },
      "rec_001.uff:32",
      "dataset 2 (58): function type 4 (frequency response function) is not supported: strokelab reads time "
      "responses (function type 1)");
  check(
      "function type 99",
      [](const fs::path& dir) { EditLine(dir, "rec_002.uff", kRecord6(1), [](std::string& l) { Replace(l, 0, 5, "   99"); }); },
      "rec_002.uff:8", "dataset 1 (58): function type 99 (unknown) is not supported");
  check(
      "complex",
      [](const fs::path& dir) { EditLine(dir, "rec_001.uff", kRecord7(1), [](std::string& l) { Replace(l, 0, 10, "         6"); }); },
      "rec_001.uff:9", "dataset 1 (58): complex ordinate data (type 6) is not supported");
  check(
      "uneven",
      [](const fs::path& dir) { EditLine(dir, "rec_001.uff", kRecord7(1), [](std::string& l) { Replace(l, 20, 10, "         0"); }); },
      "rec_001.uff:9", "dataset 1 (58): uneven abscissa spacing is not supported");
  check(
      "frequency abscissa",
      [](const fs::path& dir) { EditLine(dir, "rec_002.uff", kRecord8(kDataset2), [](std::string& l) { Replace(l, 0, 10, "        18"); }); },
      "rec_002.uff:34", "dataset 2 (58): the abscissa is frequency (specific data type 18), not time");
  check(
      "not a number",
      [](const fs::path& dir) { EditLine(dir, "rec_001.uff", 17, [](std::string& l) { Replace(l, 20, 20, "   1.0E+00x1.0E+00 "); }); },
      "rec_001.uff:17", "dataset 1 (58): '1.0E+00x1.0E+00' is not a finite number");
  check(
      "beyond the double range",
      [](const fs::path& dir) { EditLine(dir, "rec_001.uff", 17, [](std::string& l) { Replace(l, 20, 20, "          1.0E+400"); }); },
      "rec_001.uff:17", "dataset 1 (58): '1.0E+400' is not a finite number");
  check(
      "voltage in newtons",
      [](const fs::path& dir) { EditLine(dir, "rec_001.uff", kRecord9(1), [](std::string& l) { Replace(l, 47, 1, "N"); }); },
      "rec_001.uff:11", "dataset 1 (58): the voltage's units are 'N'; the drive must be in volts (V)");
  check(
      "force as velocity",
      [](const fs::path& dir) { EditLine(dir, "rec_002.uff", kRecord9(kDataset2), [](std::string& l) { Replace(l, 0, 10, "        11"); }); },
      "rec_002.uff:35", "dataset 2 (58): its specific data type 11 is velocity, the mapping's response is force");
  check(
      "unknown unit",
      [](const fs::path& dir) { EditLine(dir, "rec_002.uff", kRecord9(kDataset2), [](std::string& l) { Replace(l, 47, 1, "W"); }); },
      "rec_002.uff:35", "dataset 2 (58): units 'W' are not known for a force response (V, mV, N, kN, mN, lbf)");
}

// Below the normal range is still a number: a subnormal is read as one (std::from_chars alone
// refuses it as out of range), as the CSV reader reads it.
TEST(MalformedUff, ASubnormalValueIsANumber) {
  const fs::path dir = WriteValid("uff_subnormal", CampaignFormat::kUff58);
  EditLine(dir, "rec_001.uff", 17, [](std::string& l) { Replace(l, 20, 20, "         1.0E-320"); });
  const Campaign read = ReadCampaign(dir);
  bool found = false;
  for (const double v : read.records[0].voltage_v) found = found || (v > 0 && v < 1e-300);
  EXPECT_TRUE(found) << "no subnormal sample in rec_001's voltage";
}

TEST(MalformedUff, BinaryDefectsNameTheHeaderLineOrTheByteOffset) {
  const fs::path valid = WriteValid("uff58b_valid", CampaignFormat::kUff58Binary);
  const std::string bytes = ReadText(valid / "rec_001.uff");
  ASSERT_EQ(ReadCampaign(valid).records.size(), 2u);
  // Dataset 1's data starts after its 13 ASCII lines; dataset 2 opens 320 bytes later plus "    -1\n".
  size_t data_start = 0;
  for (int i = 0; i < 13; ++i) data_start = bytes.find('\n', data_start) + 1;
  const auto check = [&](const std::string& name, const std::string& broken, const std::string& field,
                         const std::string& fragment) {
    SCOPED_TRACE(name);
    const fs::path dir = WriteValid("uff58b_" + name, CampaignFormat::kUff58Binary);
    std::ofstream(dir / "rec_001.uff", std::ios::binary) << broken;
    ExpectRefused(dir, field, fragment);
  };
  std::string b = bytes;
  b.resize(data_start + 100);
  check("truncated", b, "rec_001.uff:byte " + std::to_string(data_start + 100),
        "dataset 1 (58b): truncated dataset: the file ends 100 bytes into its 320 bytes of data");
  b = bytes;
  b.replace(b.find("         320"), 12, "         312");
  check("byte count", b, "rec_001.uff:2",
        "dataset 1 (58b): wrong record length: the header line announces 312 bytes, record 7 40 values of 8 bytes (320)");
  b = bytes;
  b.insert(data_start + 80, std::string(8, '\x01'));  // a value too many
  check("long data", b, "rec_001.uff:byte " + std::to_string(data_start + 320),
        "dataset 1 (58b): wrong record length: no closing -1 after its 320 bytes of data");
  b = bytes;
  b.replace(b.find("    58b") + 13, 6, "     1");  // floating-point format 1 (DEC VMS)
  check("vax", b, "rec_001.uff:2", "dataset 1 (58b): floating-point format 1 is not supported (only 2, IEEE 754)");
}

// The WAV file's chunk offsets: RIFF header 0-11, "fmt " at 12 (16 bytes of body), "data" at 36.
TEST(MalformedWav, ChunkDefectsNameTheChunkAndItsOffset) {
  const fs::path valid = WriteValid("wav_valid", CampaignFormat::kWav);
  const std::string bytes = ReadText(valid / "rec_002.wav");
  ASSERT_EQ(bytes.size(), 44u + kValues * 4);
  ASSERT_EQ(ReadCampaign(valid).records.size(), 2u);
  const auto put32 = [](std::string& b, size_t at, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) b[at + i] = static_cast<char>((v >> (8 * i)) & 0xFF);
  };
  const auto check = [&](const std::string& name, const std::string& broken, const std::string& field,
                         const std::string& fragment) {
    SCOPED_TRACE(name);
    const fs::path dir = WriteValid("wav_" + name, CampaignFormat::kWav);
    std::ofstream(dir / "rec_002.wav", std::ios::binary) << broken;
    ExpectRefused(dir, field, fragment);
  };
  std::string b = bytes;
  put32(b, 40, 1000);
  check("data too long", b, "rec_002.wav:byte 36",
        "chunk 'data': size 1000 runs past the end of the file (160 bytes follow its header)");
  b = bytes;
  put32(b, 40, 158);
  check("partial frame", b, "rec_002.wav:byte 36", "chunk 'data': size 158 is not a whole number of frames of 4 bytes");
  b = bytes;
  put32(b, 16, 12);
  check("short fmt", b, "rec_002.wav:byte 12", "chunk 'fmt ': size 12, at least 16 expected");
  b = bytes;
  put32(b, 16, 0x7FFFFFFF);
  check("fmt too long", b, "rec_002.wav:byte 12", "chunk 'fmt ': size 2147483647 runs past the end of the file");
  b = bytes;
  b[32] = 6;  // block align
  check("block align", b, "rec_002.wav:byte 32", "chunk 'fmt ': block align 6, expected 2 channels x 2 bytes");
  b = bytes;
  b[34] = 8;
  b[32] = 2;
  check("8 bits", b, "rec_002.wav:byte 34", "chunk 'fmt ': 8-bit PCM samples are not supported");
  b = bytes.substr(0, 36);
  check("no data", b, "rec_002.wav", "no 'data' chunk");
  b = bytes.substr(0, 40);
  check("cut chunk header", b, "rec_002.wav:byte 36", "truncated chunk header: 4 bytes left");
  // An unknown chunk before "data" is skipped (with its pad byte).
  b = bytes.substr(0, 36) + std::string("LIST\x03\0\0\0abc\0", 12) + bytes.substr(36);
  const fs::path dir = WriteValid("wav_list_chunk", CampaignFormat::kWav);
  std::ofstream(dir / "rec_002.wav", std::ios::binary) << b;
  EXPECT_EQ(ReadCampaign(dir).records.at(1).size(), kValues);
}

TEST(MalformedMapping, SelectionsAndUnitsAreCheckedAgainstTheFiles) {
  const auto check = [](const std::string& name, CampaignFormat format, const std::function<void(json&)>& edit,
                        const std::string& field, const std::string& fragment) {
    SCOPED_TRACE(name);
    const fs::path dir = WriteValid("mapping_" + name, format);
    json mapping = json::parse(ReadText(dir / "mapping.json"));
    edit(mapping);
    std::ofstream(dir / "mapping.json") << mapping.dump(2);
    ExpectRefused(dir, field, fragment);
  };
  check("missing channel", CampaignFormat::kWav, [](json& m) { m["records"][1]["response"]["channel"] = 3; },
        "mapping.json:/records/1/response/channel", "channel 3, but 'rec_002.wav' holds 2 channel(s)");
  check("missing dataset", CampaignFormat::kUff58, [](json& m) { m["voltage"]["dataset"] = 5; },
        "mapping.json:/records/0/voltage/dataset", "dataset 5, but 'rec_001.uff' holds 2 dataset(s)");
  check("dataset of a WAV", CampaignFormat::kWav, [](json& m) { m["records"][0]["voltage"] = {{"dataset", 1}}; },
        "mapping.json:/records/0/voltage", "'rec_001.wav' is a WAV file: select its voltage by \"channel\"");
  check("channel of a UFF", CampaignFormat::kUff58, [](json& m) { m["response"].erase("dataset"); m["response"]["channel"] = 2; },
        "mapping.json:/records/0/response", "'rec_001.uff' is a UFF file: select its response by \"dataset\"");
  check("no sensitivity for WAV", CampaignFormat::kWav, [](json& m) { m["response"].erase("sensitivity_V_per_N"); },
        "mapping.json:/response", "missing sensitivity_V_per_N: channel 2 of rec_001.wav holds sensor volts");
  check("missing file", CampaignFormat::kUff58, [](json& m) { m["records"][1]["file"] = "rec_009.uff"; },
        "mapping.json:/records/1/file", "file 'rec_009.uff' not found");
  check("unknown kind", CampaignFormat::kUff58, [](json& m) { m["response"]["kind"] = "torque"; },
        "mapping.json:/response/kind", "unknown kind \"torque\"");
  check("rate disagrees", CampaignFormat::kUff58, [](json& m) { m["sample_rate_hz"] = 1024; },
        "mapping.json:/sample_rate_hz", "sample_rate_hz 1024 disagrees with dataset 1 of rec_001.uff's 1000 Hz");
  check("same channel twice", CampaignFormat::kWav, [](json& m) { m["records"][0]["response"]["channel"] = 1; },
        "mapping.json:/records/0/response", "selects the voltage's channel too");
  check("zero channel", CampaignFormat::kWav, [](json& m) { m["voltage"]["channel"] = 0; },
        "mapping.json:/voltage/channel", "expected a whole number >= 1");
  check("wrong format", CampaignFormat::kWav, [](json& m) { m["format"] = "strokelab-mapping/2"; },
        "mapping.json:/format", "unsupported format");
}

TEST(MalformedMapping, ADatasetThatIsNot58IsCountedAndRefusedWhenSelected) {
  const fs::path dir = WriteValid("mapping_151", CampaignFormat::kUff58);
  const std::string header = "    -1\n   151\nmodel\ndescription\nprogram\ndate\ndate\nprogram\ndate\n    -1\n";
  const std::string datasets = ReadText(dir / "rec_001.uff");
  std::ofstream(dir / "rec_001.uff", std::ios::binary) << header + datasets;
  ExpectRefused(dir, "mapping.json:/records/0/voltage/dataset",
                "dataset 1 of 'rec_001.uff' (line 1) is a dataset 151, not 58");
  json mapping = json::parse(ReadText(dir / "mapping.json"));
  mapping["records"][0]["voltage"] = {{"dataset", 2}};
  mapping["records"][0]["response"] = {{"dataset", 3}};
  std::ofstream(dir / "mapping.json") << mapping.dump(2);
  EXPECT_EQ(ReadCampaign(dir).records.at(0).size(), kValues);
}

TEST(MalformedForeignCli, FitNamesTheDatasetAndLineAndExitsTwo) {
  const fs::path dir = WriteValid("cli_uff", CampaignFormat::kUff58);
  EditLine(dir, "rec_002.uff", kRecord6(kDataset2), [](std::string& l) { Replace(l, 0, 5, "    2"); });
  const auto result = testing::RunCli("fit --data " + dir.string());
  EXPECT_EQ(result.exit_code, 2) << result.stderr_text;
  EXPECT_THAT(result.stderr_text,
              HasSubstr("rec_002.uff:32: dataset 2 (58): function type 2 (auto spectrum) is not supported"));
}

}  // namespace
}  // namespace strokelab
