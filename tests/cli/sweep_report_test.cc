// The sweep command's output (JSON object, --out folder, summary) on synthetic sweep results, so
// that the formatting is checked without running a sweep.
#include "strokelab/report/sweep_report.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "strokelab/model/model.h"

#include "report_test_util.h"

namespace strokelab::report {
namespace {

using ::strokelab::testing::FreshDir;
using ::strokelab::testing::Lines;
using ::strokelab::testing::ReadFile;
using ::testing::HasSubstr;

SweepPoint Point(double f_hz, double v, Branch branch, std::complex<double> h) {
  SweepPoint p;
  p.frequency_hz = f_hz;
  p.amplitude_v = v;
  p.branch = branch;
  p.stable = branch != Branch::kUnstable;
  p.h = h;
  p.first_harmonic_force_n = std::abs(h) * v;
  p.first_harmonic_phase_rad = std::arg(h);
  p.min_displacement_m = -0.5e-3;
  p.max_displacement_m = 0.5e-3;
  p.peak_force_n = p.first_harmonic_force_n;  // a sinusoid unless changed
  p.max_multiplier = branch == Branch::kUnstable ? 1.8 : 0.4;
  return p;
}

// A 4 x 2 grid. At 0.2 V the actuator is bistable between 9 and 11 Hz: the up branch is in contact
// (spiky force), the down branch is not, and an unstable orbit lies between them at 10 Hz. At
// 0.1 V only up points are given (one response: the down sweep follows it). One up point is
// aperiodic and one has a non-finite multiplier.
SweepResult Synthetic() {
  SweepResult r;
  r.frequency_hz = {5.0, 9.0, 10.0, 11.0};
  r.amplitude_v = {0.1, 0.2};
  for (double v : r.amplitude_v) {
    for (double f : r.frequency_hz) {
      const std::complex<double> h(-0.1 * f / 10, 0.2);
      r.points.push_back(Point(f, v, Branch::kUp, h));
      if (v < 0.15) continue;
      SweepPoint& up = r.points.back();
      if (f >= 9.0) {
        up.peak_force_n = 8.0 * up.first_harmonic_force_n;
        up.contacts_per_period = 1.0;
        up.min_displacement_m = -1.004e-3;
      }
      r.points.push_back(Point(f, v, Branch::kDown, 0.5 * h));
      if (f == 10.0) r.points.push_back(Point(f, v, Branch::kUnstable, 0.75 * h));
    }
  }
  r.points[2].period = 0;                 // 10 Hz, 0.1 V, up: aperiodic
  r.points[1].period = 2;                 // 9 Hz, 0.1 V, up: period 2
  r.points[3].max_multiplier = NAN;       // -> null
  for (double f : r.frequency_hz) r.saturation_threshold.push_back({f, 0.05 * f, 0.04 * f});
  r.saturation_threshold[0].lowest_contact_amplitude_v = NAN;  // none found
  r.jump.push_back({0.2, 9.0, 11.0, "grazing", "fold"});
  r.wall_time_s = 0.5;
  r.points_per_second = 16.0;
  return r;
}

std::vector<std::string> Cells(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) cells.push_back(cell);
  if (!line.empty() && line.back() == ',') cells.push_back("");
  return cells;
}


TEST(SweepOutputTest, JsonHasThePromisedKeys) {
  const SweepResult r = Synthetic();
  const nlohmann::json j = SweepToJson(r, PaperModel());
  for (const char* key :
       {"points", "saturation_threshold", "jump", "grid", "model", "wall_time_s", "points_per_second"})
    EXPECT_TRUE(j.contains(key)) << key;
  ASSERT_EQ(j["points"].size(), r.points.size());
  for (const auto& p : j["points"]) {
    for (const char* key : {"frequency_hz", "amplitude_v", "branch", "stable", "period", "first_harmonic_force_n",
                            "first_harmonic_phase_rad", "h_re_n_per_v", "h_im_n_per_v", "min_displacement_m", "max_displacement_m",
                            "peak_force_n", "contacts_per_period", "max_multiplier"})
      EXPECT_TRUE(p.contains(key)) << key << " in " << p.dump();
  }
  EXPECT_EQ(j["points"][0]["branch"], "up");
  EXPECT_EQ(j["points"][0]["period"], 1);
  EXPECT_EQ(j["points"][1]["period"], 2);
  EXPECT_EQ(j["points"][2]["period"], "aperiodic");
  EXPECT_TRUE(j["points"][3]["max_multiplier"].is_null());
  EXPECT_DOUBLE_EQ(j["points"][0]["h_re_n_per_v"].get<double>(), r.points[0].h.real());
  EXPECT_DOUBLE_EQ(j["points"][0]["h_im_n_per_v"].get<double>(), r.points[0].h.imag());
  size_t down = 0, unstable = 0;
  for (const auto& p : j["points"]) {
    down += p["branch"] == "down";
    if (p["branch"] == "unstable") {
      ++unstable;
      EXPECT_EQ(p["stable"], false);
    }
  }
  EXPECT_EQ(down, 4u);
  EXPECT_EQ(unstable, 1u);

  ASSERT_EQ(j["saturation_threshold"].size(), 4u);
  EXPECT_DOUBLE_EQ(j["saturation_threshold"][1]["grazing_amplitude_v"].get<double>(), 0.45);
  EXPECT_TRUE(j["saturation_threshold"][0]["lowest_contact_amplitude_v"].is_null());
  ASSERT_EQ(j["jump"].size(), 1u);
  EXPECT_EQ(j["jump"][0]["from_kind"], "grazing");
  EXPECT_EQ(j["jump"][0]["to_kind"], "fold");
  EXPECT_DOUBLE_EQ(j["jump"][0]["bistable_to_hz"].get<double>(), 11.0);
  EXPECT_EQ(j["grid"]["frequency_hz"].size(), 4u);
  EXPECT_EQ(j["grid"]["amplitude_v"].size(), 2u);
  EXPECT_DOUBLE_EQ(j["model"]["mass_kg"].get<double>(), 0.032);
  EXPECT_DOUBLE_EQ(j["points_per_second"].get<double>(), 16.0);
  // The object survives a round trip through text (no NaN or inf tokens).
  EXPECT_EQ(nlohmann::json::parse(j.dump()), j);
}

TEST(SweepOutputTest, FolderHasTablesPicturesAndSummary) {
  const SweepResult r = Synthetic();
  const std::filesystem::path dir = FreshDir("sweep_folder");
  WriteSweepFolder(r, PaperModel(), dir / "nested");  // creates missing folders
  for (const std::string& name : SweepFolderFiles()) {
    const std::filesystem::path path = dir / "nested" / name;
    ASSERT_TRUE(std::filesystem::is_regular_file(path)) << path;
    EXPECT_GT(std::filesystem::file_size(path), 0u) << path;
    if (path.extension() == ".svg") {
      const std::string svg = ReadFile(path);
      EXPECT_EQ(svg.rfind("<svg", 0), 0u) << name;
      EXPECT_THAT(svg, HasSubstr("</svg>")) << name;
    }
  }

  const auto points = Lines(ReadFile(dir / "nested/points.csv"));
  ASSERT_EQ(points.size(), r.points.size() + 1);
  EXPECT_EQ(points[0],
            "frequency_hz,amplitude_v,branch,stable,period,first_harmonic_force_n,first_harmonic_phase_rad,h_re_n_per_v,h_im_n_per_v,"
            "min_displacement_m,max_displacement_m,peak_force_n,contacts_per_period,max_multiplier");
  const auto aperiodic = Cells(points[3]);
  ASSERT_EQ(aperiodic.size(), 14u) << points[3];
  EXPECT_EQ(aperiodic[2], "up");
  EXPECT_EQ(aperiodic[4], "") << "an aperiodic orbit has no period";
  EXPECT_EQ(Cells(points[1])[4], "1");
  EXPECT_EQ(Cells(points[4])[13], "") << "non-finite as an empty cell";
  EXPECT_THAT(points, ::testing::Contains(HasSubstr(",unstable,0,1,")));

  const auto thresholds = Lines(ReadFile(dir / "nested/saturation_threshold.csv"));
  ASSERT_EQ(thresholds.size(), 5u);
  EXPECT_EQ(thresholds[0], "frequency_hz,grazing_amplitude_v,lowest_contact_amplitude_v");
  EXPECT_EQ(thresholds[2], "9,0.45,0.36");
  EXPECT_EQ(thresholds[1], "5,0.25,");

  const auto jumps = Lines(ReadFile(dir / "nested/jump.csv"));
  ASSERT_EQ(jumps.size(), 2u);
  EXPECT_EQ(jumps[0], "amplitude_v,bistable_from_hz,bistable_to_hz,from_kind,to_kind");
  EXPECT_EQ(jumps[1], "0.2,9,11,grazing,fold");

  const std::string map = ReadFile(dir / "nested/saturation_map.svg");
  EXPECT_THAT(map, HasSubstr("grazing amplitude"));
  EXPECT_THAT(map, HasSubstr("jump (bistable) interval"));
  EXPECT_THAT(ReadFile(dir / "nested/frf_up.svg"), HasSubstr("unstable orbits"));
  EXPECT_THAT(ReadFile(dir / "nested/frf_up.svg"), HasSubstr("drive amplitude [V]"));  // the colour bar
  EXPECT_EQ(ReadFile(dir / "nested/summary.txt"), SweepSummaryText(r));
  EXPECT_THAT(ReadFile(dir / "nested/model.json"), HasSubstr("\"mass_kg\": 0.032"));
}

// One unit for phase: the tables' first_harmonic_phase_rad is in rad, and so is the phase plot.
TEST(SweepOutputTest, ThePhasePlotIsInTheTablesUnit) {
  const std::filesystem::path dir = FreshDir("sweep_phase_unit");
  WriteSweepFolder(Synthetic(), PaperModel(), dir);
  const std::string phase = ReadFile(dir / "frf_phase.svg");
  EXPECT_THAT(phase, HasSubstr("arg H [rad]"));
  EXPECT_THAT(phase, ::testing::Not(HasSubstr("deg")));
}

// An FRF family of 26 amplitudes (0.1 .. 0.6 V): each amplitude its own colour on a sequential map
// with a colour bar (an 8-colour palette repeated, so that 0.1, 0.26, 0.42 and 0.58 V shared one),
// no legend entry per amplitude, and the sweep's jumps marked where its branch leaves the
// bistable interval (the up-sweep at its upper end, the down-sweep at its lower end).
TEST(SweepOutputTest, ManyAmplitudesGetAColourBarAndTheJumpsAreMarked) {
  SweepResult r;
  r.frequency_hz = {5.0, 9.0, 10.0, 11.0, 12.0};
  for (int k = 0; k < 26; ++k) r.amplitude_v.push_back(0.1 + 0.02 * k);
  for (double v : r.amplitude_v) {
    for (double f : r.frequency_hz) {
      r.points.push_back(Point(f, v, Branch::kUp, std::complex<double>(v * f, 1.0)));
      if (f >= 9.0 && f <= 11.0) r.points.push_back(Point(f, v, Branch::kDown, std::complex<double>(0.1 * v * f, 1.0)));
    }
  }
  r.jump.push_back({0.5, 8.5, 11.5, "grazing", "fold"});
  r.amplitude_v[20] = 0.5;  // the jump's amplitude exactly
  for (SweepPoint& p : r.points)
    if (std::abs(p.amplitude_v - 0.5) < 1e-9) p.amplitude_v = 0.5;
  const std::string up = FrfMagnitudeSvg(r, Branch::kUp);
  EXPECT_THAT(up, HasSubstr("<g class=\"colorbar\">"));
  EXPECT_THAT(up, HasSubstr("drive amplitude [V]"));
  EXPECT_THAT(up, ::testing::Not(HasSubstr(">0.1 V<")));  // no legend entry per amplitude
  std::set<std::string> colours;
  for (size_t at = up.find("<polyline"); at != std::string::npos; at = up.find("<polyline", at + 1)) {
    const size_t stroke = up.find("stroke=\"", at) + 8;
    colours.insert(up.substr(stroke, up.find('"', stroke) - stroke));
  }
  EXPECT_GE(colours.size(), 26u);  // 26 amplitudes, and the jump's black
  EXPECT_THAT(up, HasSubstr("jump of the up-sweep"));
  // The up-sweep jumps at 11.5 Hz, between its grid points at 11 and 12 Hz.
  const std::string down = FrfMagnitudeSvg(r, Branch::kDown);
  EXPECT_THAT(down, HasSubstr("jump of the down-sweep"));
  r.jump.clear();
  EXPECT_THAT(FrfMagnitudeSvg(r, Branch::kUp), ::testing::Not(HasSubstr("jump of the")));
}

TEST(SweepOutputTest, WithoutThresholdsTheTablesKeepTheirHeaders) {
  SweepResult r = Synthetic();
  r.saturation_threshold.clear();
  r.jump.clear();
  const std::filesystem::path dir = FreshDir("sweep_no_thresholds");
  WriteSweepFolder(r, PaperModel(), dir);
  EXPECT_EQ(ReadFile(dir / "saturation_threshold.csv"),
            "frequency_hz,grazing_amplitude_v,lowest_contact_amplitude_v\n");
  EXPECT_EQ(ReadFile(dir / "jump.csv"), "amplitude_v,bistable_from_hz,bistable_to_hz,from_kind,to_kind\n");
  EXPECT_THAT(ReadFile(dir / "saturation_map.svg"), ::testing::Not(HasSubstr("grazing amplitude")));
  const nlohmann::json j = SweepToJson(r, PaperModel());
  EXPECT_TRUE(j["saturation_threshold"].is_array() && j["saturation_threshold"].empty());
  EXPECT_TRUE(j["jump"].is_array() && j["jump"].empty());
  EXPECT_THAT(SweepSummaryText(r), HasSubstr("not computed"));
}

TEST(SweepOutputTest, OneFrequencyAndOneAmplitudeStillDraw) {
  SweepResult r;
  r.frequency_hz = {8.0};
  r.amplitude_v = {0.3};
  r.points.push_back(Point(8.0, 0.3, Branch::kUp, {0.1, 0.2}));
  const std::filesystem::path dir = FreshDir("sweep_single");
  WriteSweepFolder(r, PaperModel(), dir);
  EXPECT_EQ(Lines(ReadFile(dir / "points.csv")).size(), 2u);
  EXPECT_THAT(ReadFile(dir / "saturation_map.svg"), HasSubstr("<rect"));
}

TEST(SweepOutputTest, SummaryNamesTheGridThresholdsAndJumps) {
  SweepResult r = Synthetic();
  const std::string text = SweepSummaryText(r);
  EXPECT_THAT(text, HasSubstr("4 values, 5 .. 11 Hz, irregular"));
  EXPECT_THAT(text, HasSubstr("2 values, 0.1 .. 0.2 V, linear"));
  EXPECT_THAT(text, HasSubstr("8 grid points in 0.500 s"));
  EXPECT_THAT(text, HasSubstr("8 up, 4 down, 1 unstable (up/down: 3 touching the stop, 1 with period > 1, 1 aperiodic)"));
  EXPECT_THAT(text, HasSubstr("0.2000 V: 9.0000 .. 11.0000 Hz (bounded by grazing .. fold)"));
  EXPECT_THAT(text, HasSubstr("<- lowest grazing amplitude"));
  // The paper's Eq. 1 grid is recognised as geometric.
  r.frequency_hz.clear();
  for (int n = 1; n <= 117; ++n) r.frequency_hz.push_back(5.0 * std::pow(1.02, n - 1));
  EXPECT_THAT(SweepSummaryText(r), HasSubstr("117 values, 5 .. 49.7267 Hz"));
  EXPECT_THAT(SweepSummaryText(r), HasSubstr("geometric (ratio 1.02)"));
}

TEST(SweepOutputTest, SpikeFactorIsOneForASinusoid) {
  SweepPoint p = Point(8.0, 0.3, Branch::kUp, {0.1, 0.2});
  EXPECT_DOUBLE_EQ(SpikeFactor(p), 1.0);
  p.peak_force_n *= 12.0;
  EXPECT_DOUBLE_EQ(SpikeFactor(p), 12.0);
  p.first_harmonic_force_n = 0.0;
  EXPECT_TRUE(std::isnan(SpikeFactor(p)));
}

}  // namespace
}  // namespace strokelab::report
