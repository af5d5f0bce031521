// Line plots: well-formed output, escaping, linear and log ticks, ranges, gaps, decimation,
// colours, and the checks of the input.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>
#include <sstream>
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
using ::testing::Not;

constexpr double kInf = std::numeric_limits<double>::infinity();
const std::string kMinus = "\u2212";      // tick labels use the typographic minus sign
constexpr double kPixelTolerance = 0.06;  // coordinates are written to 0.1 px

struct Point {
  double x, y;
};

std::vector<Point> PolylinePoints(const std::string& polyline) {
  const size_t b = polyline.find("points=\"") + 8;
  std::istringstream in(polyline.substr(b, polyline.find('"', b) - b));
  std::vector<Point> out;
  std::string pair;
  while (in >> pair) {
    const size_t comma = pair.find(',');
    out.push_back({std::stod(pair.substr(0, comma)), std::stod(pair.substr(comma + 1))});
  }
  return out;
}

std::vector<double> Numbers(const std::vector<std::string>& labels) {
  std::vector<double> out;
  for (const std::string& l : labels) {
    const bool negative = l.rfind(kMinus, 0) == 0;
    const double magnitude = std::stod(negative ? l.substr(kMinus.size()) : l);
    out.push_back(negative ? -magnitude : magnitude);
  }
  return out;
}

TEST(LinePlotTest, IsWellFormedSvg) {
  Series dots = Line({1, 2, 3}, {3, 1, 2}, "measured");
  dots.markers = true;
  dots.line = false;
  Series dashed = Line({1, 2, 3}, {1, 2, 3}, "model");
  dashed.dashed = true;
  Axes axes;
  axes.title = "Stroke";
  axes.x_label = "time [s]";
  axes.y_label = "x [mm]";
  const std::string svg = LinePlot({dots, dashed, Line({1, 3}, {2, 2})}, axes);
  EXPECT_EQ(XmlProblem(svg), "");
  EXPECT_EQ(svg.rfind("<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\"", 0), 0u);
  EXPECT_THAT(svg, HasSubstr("<clipPath"));
  EXPECT_THAT(svg, HasSubstr("stroke-dasharray"));
  EXPECT_EQ(Count(Group(svg, "data"), "<circle"), 3);
  EXPECT_THAT(Texts(Group(svg, "legend")), ElementsAre("measured", "model"));  // unlabelled series left out
}

TEST(LinePlotTest, EmptyPlotIsStillWellFormed) {
  EXPECT_EQ(XmlProblem(LinePlot({}, Axes{})), "");
  EXPECT_EQ(XmlProblem(LinePlot({Line({kNaN}, {kNaN})}, Axes{})), "");
}

TEST(LinePlotTest, EscapesAllText) {
  Axes axes;
  axes.title = "a<b & \"c\"";
  axes.x_label = "f > 0";
  axes.y_label = "|H| <dB>";
  const std::string svg = LinePlot({Line({0, 1}, {0, 1}, "R&D\x01")}, axes);
  EXPECT_EQ(XmlProblem(svg), "");
  EXPECT_THAT(svg, HasSubstr("a&lt;b &amp; &quot;c&quot;"));
  EXPECT_THAT(svg, HasSubstr("f &gt; 0"));
  EXPECT_THAT(svg, HasSubstr("|H| &lt;dB&gt;"));
  EXPECT_THAT(svg, HasSubstr(">R&amp;D<"));
  EXPECT_THAT(svg, Not(HasSubstr("a<b")));
}

// Default size (720 x 440): ticks at least 60 px apart across and 40 px up.
TEST(LinePlotTest, LinearTicksAreOneTwoFiveMultiples) {
  Axes axes;
  axes.x_min = 0, axes.x_max = 100, axes.y_min = 0, axes.y_max = 1;
  std::string svg = LinePlot({Line({0, 100}, {0, 1})}, axes);
  EXPECT_THAT(TickLabels(svg, "x-axis"), ElementsAre("0", "10", "20", "30", "40", "50", "60", "70", "80", "90", "100"));
  EXPECT_THAT(TickLabels(svg, "y-axis"), ElementsAre("0.0", "0.2", "0.4", "0.6", "0.8", "1.0"));

  axes.y_min = -2, axes.y_max = 2;
  svg = LinePlot({Line({0, 100}, {0, 1})}, axes);
  EXPECT_THAT(TickLabels(svg, "y-axis"), ElementsAre(kMinus + "2.0", kMinus + "1.5", kMinus + "1.0", kMinus + "0.5",
                                                     "0.0", "0.5", "1.0", "1.5", "2.0"));
}

TEST(LinePlotTest, LargeValuesUseCompactScientificLabels) {
  Axes axes;
  axes.x_min = 0, axes.x_max = 2e6;
  axes.y_min = 0, axes.y_max = 4e-4;
  const std::string svg = LinePlot({Line({0, 2e6}, {0, 4e-4})}, axes);
  const std::vector<std::string> x = TickLabels(svg, "x-axis");
  EXPECT_EQ(x.front(), "0");
  EXPECT_THAT(x, ::testing::Contains("1e6"));
  EXPECT_THAT(x, ::testing::Contains("1.2e6"));
  EXPECT_THAT(TickLabels(svg, "y-axis"), ::testing::Contains("1e" + kMinus + "4"));
}

// Ticks of a range taken from the data: a 1-2-5 step, first and last tick at the range ends.
TEST(LinePlotTest, DataRangeSnapsToNiceTicks) {
  const std::string svg = LinePlot({Line({0.13, 7.9}, {-3.3, 41.0})}, Axes{});
  for (const char* axis : {"x-axis", "y-axis"}) {
    const std::vector<double> v = Numbers(TickLabels(svg, axis));
    ASSERT_GE(v.size(), 3u) << axis;
    const double step = v[1] - v[0];
    const double mantissa = step / std::pow(10.0, std::floor(std::log10(step) + 1e-9));
    EXPECT_TRUE(std::abs(mantissa - 1) < 1e-9 || std::abs(mantissa - 2) < 1e-9 || std::abs(mantissa - 5) < 1e-9)
        << axis << " step " << step;
    for (size_t i = 1; i < v.size(); ++i) EXPECT_NEAR(v[i] - v[i - 1], step, 1e-9 * step) << axis;
  }
  const std::vector<double> x = Numbers(TickLabels(svg, "x-axis"));
  EXPECT_LE(x.front(), 0.13);
  EXPECT_GE(x.back(), 7.9);
}

TEST(LinePlotTest, ExplicitRangeIsHonoured) {
  Axes axes;
  axes.x_min = 2.0, axes.x_max = 3.0;  // y stays NaN: from the data
  const std::string svg = LinePlot({Line(Linspace(0, 10, 11), Linspace(0, 10, 11))}, axes);
  const std::vector<double> x = Numbers(TickLabels(svg, "x-axis"));
  EXPECT_DOUBLE_EQ(x.front(), 2.0);
  EXPECT_DOUBLE_EQ(x.back(), 3.0);
  const std::vector<double> y = Numbers(TickLabels(svg, "y-axis"));
  EXPECT_LE(y.front(), 0.0);
  EXPECT_GE(y.back(), 10.0);
}

TEST(LinePlotTest, LogAxisTicksAtDecadesWithMinorTicks) {
  Axes axes;
  axes.log_x = true;
  axes.log_y = true;
  // The range snaps outward to 1, 2 or 5 times a power of ten: [1, 10000] x [1e-6, 1].
  const std::string svg = LinePlot({Line({1.5, 20, 8000}, {1.1e-6, 1e-3, 0.7})}, axes);
  EXPECT_THAT(TickLabels(svg, "x-axis"), ElementsAre("1", "10", "100", "1000", "10000"));
  EXPECT_THAT(TickLabels(svg, "y-axis"),
              ElementsAre("1e" + kMinus + "6", "1e" + kMinus + "5", "1e" + kMinus + "4", "1e" + kMinus + "3",
                          "1e" + kMinus + "2", "1e" + kMinus + "1", "1e0"));
  // Each of the 4 decades on x has 8 minor ticks (2..9) besides its labelled one.
  EXPECT_EQ(Count(Group(svg, "x-axis"), "M"), 5 + 4 * 8);
}

TEST(LinePlotTest, NarrowLogRangeStillGetsLabels) {
  Axes axes;
  axes.log_y = true;
  axes.y_min = 2, axes.y_max = 30;
  const std::string svg = LinePlot({Line({0, 1}, {3, 20})}, axes);
  EXPECT_THAT(TickLabels(svg, "y-axis"), ElementsAre("2", "5", "10", "20"));
}

TEST(LinePlotTest, NonFinitePointsSplitTheLine) {
  for (double bad : {kNaN, kInf, -kInf}) {
    const std::string svg = LinePlot({Line(Linspace(0, 9, 10), {0, 1, 2, 3, 4, bad, 6, 7, 8, 9})}, Axes{});
    const std::vector<std::string> lines = Elements(Group(svg, "series"), "polyline");
    ASSERT_EQ(lines.size(), 2u) << bad;
    EXPECT_EQ(PolylinePoints(lines[0]).size(), 5u);
    EXPECT_EQ(PolylinePoints(lines[1]).size(), 4u);
    EXPECT_EQ(XmlProblem(svg), "");
  }
}

TEST(LinePlotTest, NonPositiveValuesAreSkippedOnLogAxes) {
  Axes axes;
  axes.log_y = true;
  const std::string svg = LinePlot({Line({1, 2, 3, 4, 5, 6}, {1, 10, 0, -5, 100, 1000})}, axes);
  const std::vector<std::string> lines = Elements(Group(svg, "series"), "polyline");
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_EQ(PolylinePoints(lines[0]).size(), 2u);
  EXPECT_EQ(PolylinePoints(lines[1]).size(), 2u);
  EXPECT_THAT(TickLabels(svg, "y-axis"), ElementsAre("1", "10", "100", "1000"));  // the range ignores them too
}

// 51,200 samples of zero with one spike up and one down: the polyline shrinks to a few points per
// pixel column, and both spikes are still drawn to their full height.
TEST(LinePlotTest, DecimationKeepsExtremes) {
  const int n = 51200;
  std::vector<double> x(n), y(n, 0.0);
  for (int i = 0; i < n; ++i) x[i] = i * 1e-5;
  y[12345] = 10.0;
  y[40001] = -7.0;
  Axes axes;
  axes.y_min = -20, axes.y_max = 20;
  const std::string svg = LinePlot({Line(x, y)}, axes);
  const std::vector<std::string> lines = Elements(Group(svg, "series"), "polyline");
  ASSERT_EQ(lines.size(), 1u);
  const std::vector<Point> points = PolylinePoints(lines[0]);
  const Rect area = PlotArea(svg);
  EXPECT_LE(points.size(), static_cast<size_t>(4 * area.width));

  const auto y_px = [&](double v) { return area.y + area.height * (20 - v) / 40; };
  double top = 1e9, bottom = -1e9;
  for (const Point& p : points) top = std::min(top, p.y), bottom = std::max(bottom, p.y);
  EXPECT_NEAR(top, y_px(10.0), kPixelTolerance);
  EXPECT_NEAR(bottom, y_px(-7.0), kPixelTolerance);
}

TEST(LinePlotTest, DefaultPaletteGivesDistinctColours) {
  std::vector<Series> series;
  for (int i = 0; i < 8; ++i) series.push_back(Line({0, 1}, {0.0 + i, 1.0 + i}));
  series[3].color = "#123456";
  const std::string svg = LinePlot(series, Axes{});
  std::set<std::string> colours;
  for (const std::string& l : Elements(svg, "polyline")) {
    const size_t b = l.find("stroke=\"") + 8;
    colours.insert(l.substr(b, l.find('"', b) - b));
  }
  EXPECT_EQ(colours.size(), 8u);
  EXPECT_TRUE(colours.count("#123456"));
}

TEST(LinePlotTest, RejectsBadInputNamingTheField) {
  const auto message = [](const std::vector<Series>& s, const Axes& a) {
    try {
      LinePlot(s, a);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_THAT(message({Line({1, 2}, {1}), Line({1, 2, 3}, {1, 2})}, Axes{}), HasSubstr("series[0].x"));
  Axes axes;
  axes.x_min = 3, axes.x_max = 1;
  EXPECT_THAT(message({}, axes), HasSubstr("Axes.x_min"));
  axes = Axes{};
  axes.log_y = true;
  axes.y_min = 0;
  EXPECT_THAT(message({}, axes), HasSubstr("Axes.y_min"));
  axes = Axes{};
  axes.width_px = 10;
  EXPECT_THAT(message({}, axes), HasSubstr("Axes.width_px"));
}

// Many curves coloured by a value (FRFs by drive amplitude): a colour bar instead of a legend entry
// per curve, each curve its own colour on the sequential map, from viridis dark to yellow.
TEST(LinePlotTest, ColourBarColoursCurvesByValue) {
  const ColorBar bar{"drive amplitude [V]", 0.1, 0.6, false};
  EXPECT_EQ(ColorBarColor(bar, 0.1), "#440154");
  EXPECT_EQ(ColorBarColor(bar, 0.6), "#fde725");
  EXPECT_EQ(ColorBarColor(bar, 9.0), "#fde725");  // beyond the range: the end colour
  std::vector<Series> curves;
  std::set<std::string> colours;
  for (int k = 0; k < 26; ++k) {
    const double v = 0.1 + 0.02 * k;
    Series s = Line({1, 2, 3}, {v, 2 * v, v});
    s.color = ColorBarColor(bar, v);
    colours.insert(s.color);
    curves.push_back(s);
  }
  EXPECT_EQ(colours.size(), 26u);
  curves.push_back(Line({1, 3}, {0.5, 0.5}, "jumps"));
  const std::string svg = LinePlot(curves, Axes{}, bar);
  EXPECT_EQ(XmlProblem(svg), "");
  EXPECT_THAT(Group(svg, "colorbar"), HasSubstr("drive amplitude [V]"));
  EXPECT_THAT(Texts(Group(svg, "legend")), ElementsAre("jumps"));
  EXPECT_THROW(LinePlot(curves, Axes{}, ColorBar{"x", 1, 1, false}), std::invalid_argument);
  EXPECT_THROW(ColorBarColor(ColorBar{"x", 0, 1, true}, 0.5), std::invalid_argument);
}

// A log axis over less than a decade (records at 5.5 .. 13 Hz) has labels up to its end: 1..9 times a
// power of ten labelled 6, 7, 8, 9, 10 and left 11 .. 14 Hz bare; 1-2-5 steps reach it.
TEST(LinePlotTest, LogAxisUnderADecadeIsLabelledToItsEnds) {
  Axes axes;
  axes.log_x = true;
  axes.width_px = 480;
  axes.x_min = 5.2;  // padded limits, as the diagnosis report's residual maps set them
  axes.x_max = 13.8;
  const std::string svg = LinePlot({Line({5.5, 8, 11, 13}, {1, 2, 3, 4})}, axes);
  const std::vector<double> labels = Numbers(Texts(Group(svg, "x-axis")));
  ASSERT_GE(labels.size(), 3u);
  EXPECT_GE(labels.back(), 12.0);
  EXPECT_LE(labels.front(), 6.0);
}

}  // namespace
}  // namespace strokelab::plot
