// `strokelab paper --out` end to end (1 s steps, ~0.5 s): its figures show all of their data.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <regex>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "report_test_util.h"
#include "run_cli.h"

namespace {

using ::strokelab::testing::FreshDir;
using ::strokelab::testing::Lines;
using ::strokelab::testing::ReadFile;
using ::strokelab::testing::RunCli;
using ::testing::HasSubstr;

// The numbers of the y axis' tick labels of one of our SVG plots (the typographic minus as "-").
std::vector<double> YTickLabels(const std::string& svg) {
  const size_t begin = svg.find("<g class=\"y-axis\">"), end = svg.find("</g>", begin);
  const std::string axis = svg.substr(begin, end - begin);
  std::vector<double> ticks;
  static const std::regex kLabel(">([0-9.e+-]+)</text>");
  for (auto it = std::sregex_iterator(axis.begin(), axis.end(), kLabel); it != std::sregex_iterator(); ++it)
    ticks.push_back(std::stod((*it)[1]));
  return ticks;
}

// The smallest and largest finite values in the CSV's columns after the first.
std::pair<double, double> ValueRange(const std::vector<std::string>& csv) {
  double smallest = INFINITY, largest = -INFINITY;
  for (size_t row = 1; row < csv.size(); ++row) {
    std::istringstream cells(csv[row]);
    std::string cell;
    std::getline(cells, cell, ',');  // frequency
    while (std::getline(cells, cell, ',')) {
      if (cell.empty()) continue;
      smallest = std::min(smallest, std::stod(cell));
      largest = std::max(largest, std::stod(cell));
    }
  }
  return {smallest, largest};
}

// saturation_onset.svg had its y axis fixed at 0 .. 1 V while the thresholds reach 10 V above the
// resonance: the axis now reaches the data.
TEST(PaperCliTest, SaturationOnsetShowsEveryThreshold) {
  const std::filesystem::path dir = FreshDir("paper_cli");
  const auto r = RunCli("paper --out " + dir.string() + " --step-duration-s 1 --threads 2");
  ASSERT_EQ(r.exit_code, 0) << r.stderr_text;
  const auto [smallest, largest] = ValueRange(Lines(ReadFile(dir / "saturation_onset.csv")));
  ASSERT_GT(largest, 1.0);
  const std::vector<double> ticks = YTickLabels(ReadFile(dir / "saturation_onset.svg"));
  ASSERT_FALSE(ticks.empty());
  // Labelled ticks lie within the axis, so the axis reaches within a tick step of the data's ends.
  EXPECT_GE(ticks.back() * 2.5, largest) << "the y axis stops near " << ticks.back() << " V";
  EXPECT_LE(ticks.front() / 2.5, smallest) << "the y axis starts near " << ticks.front() << " V";
  EXPECT_THAT(ReadFile(dir / "fig4b_frf_phase.svg"), HasSubstr("arg H [rad]"));
}

}  // namespace
