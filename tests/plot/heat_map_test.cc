// Heat maps: one rectangle per drawable cell, the colour map and bar, cells on log axes, the
// checks of the grid.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "strokelab/plot/svg_plot.h"
#include "svg_test_util.h"

namespace strokelab::plot {
namespace {

using namespace svg_test;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

HeatMap SmallMap() {
  HeatMap m;
  m.x = {1, 2, 3, 4};
  m.y = {10, 20, 30};
  m.z = {{0, 1, 2, 3}, {kNaN, 5, 6, 7}, {8, 9, kNaN, 11}};
  m.z_label = "peak stroke [mm]";
  return m;
}

TEST(HeatMapTest, OneRectPerFiniteCellAndAColourBar) {
  Series boundary = Line({1, 4}, {12, 28}, "threshold <x>");
  const std::string svg = HeatMapPlot(SmallMap(), {boundary, Line({1, 4}, {28, 12})}, Axes{});
  EXPECT_EQ(XmlProblem(svg), "");
  EXPECT_EQ(Count(Group(svg, "cells"), "<rect"), 10);
  const std::string bar = Group(svg, "colorbar");
  EXPECT_THAT(bar, HasSubstr("<linearGradient"));
  EXPECT_THAT(bar, HasSubstr("peak stroke [mm]"));
  EXPECT_GE(Texts(bar).size(), 3u);  // tick labels and the z label
  EXPECT_THAT(Texts(Group(svg, "legend")), ElementsAre("threshold &lt;x&gt;"));
  EXPECT_EQ(Elements(svg, "polyline").size(), 4u);  // each overlay on a white halo
}

TEST(HeatMapTest, ColoursRunFromViridisDarkToYellow) {
  const std::string svg = HeatMapPlot(SmallMap(), {}, Axes{});
  EXPECT_THAT(Group(svg, "cells"), HasSubstr("fill=\"#440154\""));  // z = 0, the minimum
  EXPECT_THAT(Group(svg, "cells"), HasSubstr("fill=\"#fde725\""));  // z = 11, the maximum
}

// A fixed colour range (maps side by side on one scale): z beyond it takes the end colours, and the
// data's own extremes no longer do.
TEST(HeatMapTest, FixedColourRangeClampsAndSharesTheScale) {
  HeatMap m = SmallMap();
  m.z_min = 2;
  m.z_max = 6;
  const std::string cells = Group(HeatMapPlot(m, {}, Axes{}), "cells");
  EXPECT_EQ(Count(cells, "fill=\"#440154\""), 3);  // z = 0, 1, 2
  EXPECT_EQ(Count(cells, "fill=\"#fde725\""), 5);  // z = 6, 7, 8, 9, 11
  m.z_min = 0;
  m.log_z = true;
  EXPECT_THROW(HeatMapPlot(m, {}, Axes{}), std::invalid_argument);  // no zero on a log scale
}

// Log-spaced grid on a log axis: cell edges at the (geometric) midpoints, so all cells are equally wide.
TEST(HeatMapTest, NonUniformGridOnLogAxis) {
  HeatMap m;
  m.x = {10, 100, 1000, 10000};
  m.y = {0, 1, 3};  // uneven: edges at 0.5 and 2, outer cells as wide as their neighbours
  m.z = {{1, 2, 3, 4}, {5, 6, 7, 8}, {9, 10, 11, 12}};
  m.log_z = true;
  Axes axes;
  axes.log_x = true;
  const std::string svg = HeatMapPlot(m, {}, axes);
  EXPECT_EQ(XmlProblem(svg), "");
  const std::vector<std::string> cells = Elements(Group(svg, "cells"), "rect");
  ASSERT_EQ(cells.size(), 12u);
  const Rect area = PlotArea(svg);
  for (int ix = 0; ix < 4; ++ix) EXPECT_NEAR(Attribute(cells[ix], "width"), area.width / 4, 0.11) << ix;
  // y edges: -0.5, 0.5, 2, 4 over a range of 4.5
  EXPECT_NEAR(Attribute(cells[0], "height"), area.height * 1.0 / 4.5, 0.11);
  EXPECT_NEAR(Attribute(cells[4], "height"), area.height * 1.5 / 4.5, 0.11);
  EXPECT_NEAR(Attribute(cells[8], "height"), area.height * 2.0 / 4.5, 0.11);
  EXPECT_THAT(TickLabels(svg, "x-axis"), ElementsAre("10", "100", "1000", "10000"));
}

TEST(HeatMapTest, LogZLeavesNonPositiveCellsEmpty) {
  HeatMap m = SmallMap();
  m.log_z = true;  // z = 0 at one cell, plus the two NaN cells
  const std::string svg = HeatMapPlot(m, {}, Axes{});
  EXPECT_EQ(Count(Group(svg, "cells"), "<rect"), 9);
  EXPECT_EQ(XmlProblem(svg), "");
}

TEST(HeatMapTest, RejectsMismatchedShapesNamingTheField) {
  HeatMap m = SmallMap();
  m.z[1].pop_back();
  EXPECT_THROW(
      {
        try {
          HeatMapPlot(m, {}, Axes{});
        } catch (const std::invalid_argument& e) {
          EXPECT_THAT(e.what(), HasSubstr("HeatMap.z[1]"));
          throw;
        }
      },
      std::invalid_argument);
  m = SmallMap();
  m.x = {1, 3, 2, 4};
  EXPECT_THROW(HeatMapPlot(m, {}, Axes{}), std::invalid_argument);
}

}  // namespace
}  // namespace strokelab::plot
