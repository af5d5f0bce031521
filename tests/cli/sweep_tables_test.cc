// The one table of columns per sweep row type (report/sweep_tables.h): JSON and back is the
// identity, the CSV has the JSON's columns and values, and a malformed stored row names its column.
#include "strokelab/report/sweep_tables.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "strokelab/base/errors.h"

namespace strokelab::report {
namespace {

using ::testing::HasSubstr;
using nlohmann::json;

SweepPoint Point() {
  SweepPoint p;
  p.frequency_hz = 12.681717581234567;  // 17 significant digits: a CSV cell must keep them all
  p.amplitude_v = 0.4;
  p.branch = Branch::kDown;
  p.stable = false;
  p.period = 2;
  p.h = {-0.125, 3.0e-7};
  p.first_harmonic_force_n = 1.5;
  p.first_harmonic_phase_rad = -2.25;
  p.min_displacement_m = -0.0009;
  p.max_displacement_m = 0.0011;
  p.peak_force_n = 4.75;
  p.contacts_per_period = 1.0;
  p.max_multiplier = std::numeric_limits<double>::infinity();
  return p;
}

TEST(SweepTables, APointSurvivesJsonAndBackExactly) {
  const SweepPoint p = Point();
  const json j = json::parse(RowToJson(p).dump());  // as stored: through JSON text
  EXPECT_TRUE(j["max_multiplier"].is_null()) << "non-finite as null";
  EXPECT_EQ(j["branch"], "down");
  const SweepPoint back = RowFromJson<SweepPoint>(j);
  EXPECT_EQ(back.frequency_hz, p.frequency_hz);
  EXPECT_EQ(back.branch, p.branch);
  EXPECT_EQ(back.stable, p.stable);
  EXPECT_EQ(back.period, p.period);
  EXPECT_EQ(back.h, p.h);
  EXPECT_EQ(back.min_displacement_m, p.min_displacement_m);
  EXPECT_TRUE(std::isnan(back.max_multiplier)) << "null reads back as not-a-number";
}

TEST(SweepTables, AnAperiodicOrbitIsAWordInJsonAndAnEmptyCsvCell) {
  SweepPoint p = Point();
  p.period = 0;
  EXPECT_EQ(RowToJson(p)["period"], "aperiodic");
  EXPECT_EQ(RowFromJson<SweepPoint>(RowToJson(p)).period, 0);
  EXPECT_THAT(CsvLine(p), HasSubstr(",down,0,,1.5,"));
}

TEST(SweepTables, TheCsvHasTheJsonColumnsInOrderAndRoundTripsNumbers) {
  const SweepPoint p = Point();
  const json j = RowToJson(p);
  std::string header = CsvHeader<SweepPoint>();
  ASSERT_EQ(header.back(), '\n');
  header.pop_back();
  std::string line = CsvLine(p);
  line.pop_back();
  std::vector<std::string> names, cells;
  for (size_t from = 0, to;; from = to + 1) {
    to = header.find(',', from);
    names.push_back(header.substr(from, to - from));
    if (to == std::string::npos) break;
  }
  for (size_t from = 0, to;; from = to + 1) {
    to = line.find(',', from);
    cells.push_back(line.substr(from, to - from));
    if (to == std::string::npos) break;
  }
  ASSERT_EQ(names.size(), j.size());
  ASSERT_EQ(cells.size(), names.size());
  for (size_t i = 0; i < names.size(); ++i) {
    ASSERT_TRUE(j.contains(names[i])) << names[i];
    const json& v = j[names[i]];
    if (v.is_number_float()) {
      EXPECT_EQ(std::stod(cells[i]), v.get<double>()) << names[i] << " " << cells[i];
    }
  }
  EXPECT_EQ(cells[0], "12.681717581234567");
  EXPECT_EQ(cells[9], "-0.0009") << "laid out as %g does";
  EXPECT_EQ(cells[3], "0") << "a flag as 0 or 1";
  EXPECT_EQ(cells[13], "") << "non-finite as an empty cell";
}

TEST(SweepTables, TextWithACommaIsQuoted) {
  JumpInterval j{0.2, 9, 11, "fold", "a, \"b\""};
  EXPECT_EQ(CsvHeader<JumpInterval>(), "amplitude_v,bistable_from_hz,bistable_to_hz,from_kind,to_kind\n");
  EXPECT_EQ(CsvLine(j), "0.2,9,11,fold,\"a, \"\"b\"\"\"\n");
}

TEST(SweepTables, AMalformedStoredRowNamesItsColumn) {
  json j = RowToJson(SaturationThreshold{9, 0.45, NAN});
  EXPECT_TRUE(j["lowest_contact_amplitude_v"].is_null());
  j.erase("grazing_amplitude_v");
  try {
    RowFromJson<SaturationThreshold>(j);
    FAIL() << "a missing column was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "grazing_amplitude_v");
  }
  json p = RowToJson(Point());
  p["branch"] = "sideways";
  EXPECT_THROW(RowFromJson<SweepPoint>(p), InputError);
  p = RowToJson(Point());
  p["stable"] = "yes";
  try {
    RowFromJson<SweepPoint>(p);
    FAIL() << "a string flag was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "stable");
  }
}

}  // namespace
}  // namespace strokelab::report
