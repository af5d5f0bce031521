// Campaigns in UFF dataset 58 (ASCII and binary) and WAV files with mapping.json (data/mapping.h):
// round trips from the CSV layout, equal to the sample resolution of each format; a stepped-sine
// campaign written as UFF 58 fits to the parameters of its CSV twin; `strokelab synth --format`.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "cli/run_cli.h"
#include "strokelab/base/errors.h"
#include "strokelab/data/mapping.h"
#include "strokelab/data/recordings.h"
#include "strokelab/data/synth.h"
#include "strokelab/identify/fit.h"
#include "strokelab/model/model.h"

#include "recordings_test_util.h"

namespace strokelab {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::testing::HasSubstr;
using recordings_test::ReadText;
using recordings_test::TempDir;

// A small synthetic campaign with noise, offset and hum, and a broadband record among the steps.
Campaign SmallCampaign(ResponseKind kind) {
  SynthOptions o;
  o.frequencies_hz = {8, 13};
  o.amplitudes_v = {0.2, 0.5};
  o.duration_s = 0.25;
  o.settle_s = 0.5;
  o.sample_rate_hz = 4096;
  o.response = kind;
  o.noise_rms_v = 1e-4;
  o.offset_v = 0.01;
  o.hum_v = 0.002;
  o.seed = 5;
  Campaign campaign = Synthesize(PaperModel(), o).campaign;
  campaign.records[3].broadband = true;  // its voltage is a sine, but the layout does not care
  campaign.records[3].nominal_frequency_hz = 0;
  return campaign;
}

// The campaign as the CSV layout gives it back (10 significant digits), the reference of the round trips.
Campaign CsvTwin(const Campaign& campaign, const std::string& name) {
  const fs::path dir = TempDir(name);
  WriteCampaign(campaign, dir);
  return ReadCampaign(dir);
}

void ExpectSameLayout(const Campaign& read, const Campaign& reference) {
  EXPECT_EQ(read.actuator, reference.actuator);
  EXPECT_EQ(read.response, reference.response);
  EXPECT_EQ(read.absolute_scale, reference.absolute_scale);
  ASSERT_EQ(read.records.size(), reference.records.size());
  for (size_t k = 0; k < read.records.size(); ++k) {
    const Recording& a = read.records[k];
    const Recording& b = reference.records[k];
    EXPECT_EQ(a.sample_rate_hz, b.sample_rate_hz) << k;
    EXPECT_EQ(a.broadband, b.broadband) << k;
    EXPECT_EQ(a.nominal_frequency_hz, b.nominal_frequency_hz) << k;
    EXPECT_EQ(a.nominal_amplitude_v, b.nominal_amplitude_v) << k;
    ASSERT_EQ(a.size(), b.size()) << k;
    ASSERT_EQ(a.response.size(), b.response.size()) << k;
  }
}

double Peak(const std::vector<double>& values) {
  double peak = 0;
  for (double v : values) peak = std::max(peak, std::abs(v));
  return peak;
}

TEST(ForeignFormats, Uff58AsciiAndBinaryRoundTripToTheirPrecision) {
  for (ResponseKind kind : {ResponseKind::kForce, ResponseKind::kDisplacement}) {
    const Campaign csv = CsvTwin(SmallCampaign(kind), "uff_csv");
    for (CampaignFormat format : {CampaignFormat::kUff58, CampaignFormat::kUff58Binary}) {
      SCOPED_TRACE(ToString(format));
      const fs::path dir = TempDir(std::string("uff_") + ToString(format));
      MappedWriteOptions options;
      options.format = format;
      WriteMappedCampaign(csv, dir, options);
      EXPECT_TRUE(fs::is_regular_file(dir / "mapping.json"));
      EXPECT_TRUE(fs::is_regular_file(dir / "rec_001.uff"));
      EXPECT_FALSE(fs::exists(dir / "manifest.json"));
      const Campaign read = ReadCampaign(dir);
      ExpectSameLayout(read, csv);
      EXPECT_EQ(read.records[0].name, "rec_001.uff");
      for (size_t k = 0; k < read.records.size(); ++k) {
        // Binary: the doubles themselves. ASCII (E20.12, 13 significant digits) gives back the CSV's
        // 10-digit voltages exactly, and the responses (in SI units, the CSV's sensor volts divided by
        // the sensitivity) within half a unit of the 13th digit (5e-13 relative at most, plus the
        // parse's rounding).
        EXPECT_EQ(read.records[k].voltage_v, csv.records[k].voltage_v) << k;
        if (format == CampaignFormat::kUff58Binary) {
          EXPECT_EQ(read.records[k].response, csv.records[k].response) << k;
        } else {
          for (size_t n = 0; n < read.records[k].size(); ++n)
            ASSERT_NEAR(read.records[k].response[n], csv.records[k].response[n],
                        6e-13 * std::abs(csv.records[k].response[n]))
                << k << " " << n;
        }
      }
    }
  }
}

TEST(ForeignFormats, WavRoundTripsWithinHalfAQuantisationStep) {
  const Campaign csv = CsvTwin(SmallCampaign(ResponseKind::kAcceleration), "wav_csv");
  const double sensitivity = DefaultSensitivity(ResponseKind::kAcceleration);
  for (WavSampleFormat format :
       {WavSampleFormat::kInt16, WavSampleFormat::kInt24, WavSampleFormat::kInt32, WavSampleFormat::kFloat32}) {
    SCOPED_TRACE(ToString(format));
    const fs::path dir = TempDir(std::string("wav_") + ToString(format));
    MappedWriteOptions options;
    options.format = CampaignFormat::kWav;
    options.wav_format = format;
    WriteMappedCampaign(csv, dir, options);
    const Campaign read = ReadCampaign(dir);
    ExpectSameLayout(read, csv);
    EXPECT_EQ(read.records[1].name, "rec_002.wav");
    for (size_t k = 0; k < read.records.size(); ++k) {
      const Recording& a = read.records[k];
      const Recording& b = csv.records[k];
      // Integers: each channel's peak sits on the top code, so full scale is peak x 2^(b-1) / (2^(b-1) - 1)
      // and rounding to the nearest code errs by at most half a step, full scale / 2^b (plus the
      // rounding of the scaling itself, 1e-12 relative). Float32: half an ulp, 2^-24 relative.
      const auto tolerance = [&](const std::vector<double>& values, double value, double unit) {
        if (format == WavSampleFormat::kFloat32) return std::ldexp(std::abs(value), -24) * (1 + 1e-9) + 1e-300;
        const double codes = std::ldexp(1.0, WavBits(format) - 1);
        const double full_scale = Peak(values) * unit * codes / (codes - 1.0);
        return (full_scale / (2.0 * codes) + 1e-12 * full_scale) / unit;
      };
      for (size_t n = 0; n < a.size(); ++n) {
        ASSERT_NEAR(a.voltage_v[n], b.voltage_v[n], tolerance(b.voltage_v, b.voltage_v[n], 1.0)) << k << " " << n;
        ASSERT_NEAR(a.response[n], b.response[n], tolerance(b.response, b.response[n], sensitivity)) << k << " " << n;
      }
    }
  }
  // int16 is coarse: the quantisation is visible, not hidden by the comparison above.
  const fs::path dir = TempDir("wav_int16_visible");
  MappedWriteOptions options;
  options.format = CampaignFormat::kWav;
  options.wav_format = WavSampleFormat::kInt16;
  WriteMappedCampaign(csv, dir, options);
  EXPECT_NE(ReadCampaign(dir).records[0].voltage_v, csv.records[0].voltage_v);
}

TEST(ForeignFormats, MappedCampaignFilesListsTheMappingAndEachFileOnce) {
  const Campaign csv = CsvTwin(SmallCampaign(ResponseKind::kForce), "files_csv");
  const fs::path dir = TempDir("files_uff");
  WriteMappedCampaign(csv, dir);
  EXPECT_EQ(CampaignFiles(dir),
            (std::vector<std::string>{"mapping.json", "rec_001.uff", "rec_002.uff", "rec_003.uff", "rec_004.uff"}));
  // Two records from one file (datasets 1-2 and 3-4): each file is listed once, the records are
  // named by their response dataset.
  json mapping = json::parse(ReadText(dir / "mapping.json"));
  const std::string second = ReadText(dir / "rec_002.uff");
  {
    std::ofstream out(dir / "rec_001.uff", std::ios::app | std::ios::binary);
    out << second;
  }
  mapping["records"][1]["file"] = "rec_001.uff";
  mapping["records"][1]["voltage"] = {{"dataset", 3}};
  mapping["records"][1]["response"] = {{"dataset", 4}};
  std::ofstream(dir / "mapping.json") << mapping.dump(2);
  fs::remove(dir / "rec_002.uff");
  EXPECT_EQ(CampaignFiles(dir),
            (std::vector<std::string>{"mapping.json", "rec_001.uff", "rec_003.uff", "rec_004.uff"}));
  const Campaign read = ReadCampaign(dir);
  EXPECT_EQ(read.records[0].name, "rec_001.uff#dataset2");
  EXPECT_EQ(read.records[1].name, "rec_001.uff#dataset4");
  EXPECT_EQ(read.records[1].voltage_v, csv.records[1].voltage_v);
  // A directory with both descriptions is refused.
  std::ofstream(dir / "manifest.json") << "{}";
  try {
    ReadCampaign(dir);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.bare_message(), HasSubstr("holds both manifest.json and mapping.json"));
  }
}

TEST(ForeignFormats, SensorVoltsInUffNeedTheMappingsSensitivityAndUnitsAreConverted) {
  // A UFF response in volts (as an uncalibrated export) and one in g.
  Campaign campaign = CsvTwin(SmallCampaign(ResponseKind::kAcceleration), "units_csv");
  campaign.records.resize(1);
  const fs::path dir = TempDir("units_uff");
  WriteMappedCampaign(campaign, dir);
  std::string uff = ReadText(dir / "rec_001.uff");
  const size_t label = uff.find("m/s^2");
  ASSERT_NE(label, std::string::npos);
  json mapping = json::parse(ReadText(dir / "mapping.json"));

  // Units 'g': the values are read as g and converted to m/s^2.
  std::string in_g = uff;
  in_g.replace(label, 5, "g    ");
  std::ofstream(dir / "rec_001.uff", std::ios::binary) << in_g;
  const Campaign g = ReadCampaign(dir);
  const double expected_g = 9.80665 * campaign.records[0].response[7];
  EXPECT_NEAR(g.records[0].response[7], expected_g, 1e-12 * std::abs(expected_g));

  // Units 'V' without a sensitivity: refused, naming the mapping's response; with one: divided by it.
  std::string in_v = uff;
  in_v.replace(label, 5, "V    ");
  std::ofstream(dir / "rec_001.uff", std::ios::binary) << in_v;
  try {
    ReadCampaign(dir);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "mapping.json:/response");
    EXPECT_THAT(e.bare_message(), HasSubstr("missing sensitivity_V_per_m_s2: dataset 2 of rec_001.uff holds sensor volts"));
  }
  mapping["response"]["sensitivity_V_per_m_s2"] = 0.5;
  std::ofstream(dir / "mapping.json") << mapping.dump(2);
  const double expected_v = campaign.records[0].response[7] / 0.5;
  EXPECT_NEAR(ReadCampaign(dir).records[0].response[7], expected_v, 1e-12 * std::abs(expected_v));
}

// A stepped-sine campaign written as UFF 58 fits as its CSV twin: binary UFF written from the CSV
// twin holds its very doubles, so the fit is the same to the last bit; ASCII UFF written from the
// synthesis (as `strokelab synth --format uff58` does) holds 13 digits where the CSV holds 10, and
// fits to the same parameters within 1e-6 relative (their standard errors are 1e-4 .. 1e-2 relative).
TEST(ForeignFormats, SteppedSineCampaignInUff58FitsAsItsCsvTwin) {
  SynthOptions o;
  o.frequencies_hz = {6, 8, 9, 11, 13};
  o.amplitudes_v = {0.1, 0.5};
  o.duration_s = 0.5;
  o.settle_s = 4;
  o.sample_rate_hz = 8192;
  o.noise_rms_v = 2e-4;
  o.offset_v = 0.01;
  o.perturb = {{"k_p", 0.05}, {"g", 0.05}};
  o.seed = 21;
  const Synthesis synthesis = Synthesize(PaperModel(), o);
  const fs::path csv_dir = TempDir("fit_csv");
  const fs::path ascii_dir = TempDir("fit_uff58");
  const fs::path binary_dir = TempDir("fit_uff58b");
  WriteSynthesis(synthesis, csv_dir);
  WriteSynthesis(synthesis, ascii_dir, {}, CampaignFormat::kUff58);
  const Campaign csv = ReadCampaign(csv_dir);
  MappedWriteOptions binary;
  binary.format = CampaignFormat::kUff58Binary;
  WriteMappedCampaign(csv, binary_dir, binary);

  const FitResult from_csv = FitCampaign(csv);
  const FitResult from_binary = FitCampaign(ReadCampaign(binary_dir));
  const FitResult from_ascii = FitCampaign(ReadCampaign(ascii_dir));
  ASSERT_TRUE(from_csv.refinement.converged) << from_csv.refinement.report;
  ASSERT_FALSE(from_csv.parameters.empty());
  ASSERT_EQ(from_binary.parameters.size(), from_csv.parameters.size());
  ASSERT_EQ(from_ascii.parameters.size(), from_csv.parameters.size());
  for (size_t i = 0; i < from_csv.parameters.size(); ++i) {
    const FitParameter& p = from_csv.parameters[i];
    SCOPED_TRACE(p.name);
    EXPECT_EQ(from_binary.parameters[i].name, p.name);
    EXPECT_EQ(from_binary.parameters[i].value, p.value);
    EXPECT_EQ(from_binary.parameters[i].standard_error, p.standard_error);
    EXPECT_EQ(from_ascii.parameters[i].name, p.name);
    EXPECT_NEAR(from_ascii.parameters[i].value, p.value, 1e-6 * std::abs(p.value));
  }
}

TEST(ForeignFormats, SynthWritesEachFormatAndFitReadsIt) {
  const std::string grid =
      " --frequencies-hz 8,13 --amplitudes-v 0.2 --duration-s 0.25 --settle-s 0.5 --sample-rate-hz 4096 --seed 3";
  const fs::path csv_dir = TempDir("synth_format_csv");
  ASSERT_EQ(testing::RunCli("synth --out " + csv_dir.string() + grid).exit_code, 0);
  const Campaign csv = ReadCampaign(csv_dir);
  for (const char* format : {"uff58", "uff58b", "wav"}) {
    SCOPED_TRACE(format);
    const fs::path dir = TempDir(std::string("synth_format_") + format);
    const auto result = testing::RunCli("synth --out " + dir.string() + grid + " --format " + format +
                                        (std::string(format) == "wav" ? " --wav-format int24" : ""));
    ASSERT_EQ(result.exit_code, 0) << result.stderr_text;
    EXPECT_THAT(result.stdout_text, HasSubstr(std::string("wrote 2 records (") + format + ", force"));
    EXPECT_TRUE(fs::is_regular_file(dir / "truth.json"));
    const Campaign read = ReadCampaign(dir);
    ASSERT_EQ(read.records.size(), 2u);
    EXPECT_EQ(read.records[1].nominal_frequency_hz, 13.0);
    // Within the coarsest of the formats here (int24: 2^-24 of full scale) of the CSV's values.
    for (size_t n = 0; n < csv.records[1].size(); ++n)
      ASSERT_NEAR(read.records[1].voltage_v[n], csv.records[1].voltage_v[n], 0.2 * 1.1 / (1 << 23)) << n;
  }
  const auto bad = testing::RunCli("synth --out " + csv_dir.string() + grid + " --format mat");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_THAT(bad.stderr_text, HasSubstr("--format: unknown campaign format 'mat' (csv, uff58, uff58b, wav)"));
  const auto wav_only = testing::RunCli("synth --out " + csv_dir.string() + grid + " --wav-format int16");
  EXPECT_EQ(wav_only.exit_code, 2);
  EXPECT_THAT(wav_only.stderr_text, HasSubstr("--wav-format: applies to --format wav only"));
}

// The UFF and WAV seeds of the recordings fuzzer (tests/fuzz/fuzz_recordings.cc) are valid
// campaigns, so that its mutations start from inputs that reach the readers' depths.
TEST(ForeignFormats, TheFuzzersUffAndWavSeedsAreValidCampaigns) {
  const std::pair<const char*, size_t> seeds[] = {{"uff_ascii_force", 2},
                                                 {"uff_binary_two_records_one_file", 2},
                                                 {"wav_int16_velocity", 1},
                                                 {"mixed_uff_and_wav", 2}};
  for (const auto& [seed, records] : seeds) {
    SCOPED_TRACE(seed);
    const std::string input = ReadText(fs::path(STROKELAB_TESTDATA) / ".." / "fuzz" / "corpus" / "recordings" / seed);
    ASSERT_FALSE(input.empty());
    const fs::path dir = TempDir(std::string("seed_") + seed);
    size_t start = 0;
    for (int part = 0;; ++part) {  // as the harness splits and names them
      const size_t end = input.find('\x1e', start);
      const std::string bytes = input.substr(start, end == std::string::npos ? std::string::npos : end - start);
      char name[32];
      std::snprintf(name, sizeof name, "rec_%03d.%s", part, bytes.rfind("RIFF", 0) == 0 ? "wav" : "uff");
      std::ofstream(dir / (part == 0 ? fs::path("mapping.json") : fs::path(name)), std::ios::binary) << bytes;
      if (end == std::string::npos) break;
      start = end + 1;
    }
    EXPECT_EQ(ReadCampaign(dir).records.size(), records);
  }
}

}  // namespace
}  // namespace strokelab
