// Campaign directories: the real campaign-a, Write -> Read round trips, and the variants of the
// format that are accepted (malformed campaigns: malformed_campaign_test.cc; `strokelab synth`:
// synth_test.cc).
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

#include "recordings_test_util.h"

namespace strokelab {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::testing::HasSubstr;
using recordings_test::Fixture;
using recordings_test::ReadText;
using recordings_test::TempDir;

// %.10g keeps 10 significant digits: 5e-10 relative, plus the sensitivity's division and product.
constexpr double kRoundTripRelative = 1e-9;

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

// ---- Accepted variants (Fixture: recordings_test_util.h) ---------------------------------------

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

}  // namespace
}  // namespace strokelab
