#include "strokelab/plot/svg_plot.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <regex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace strokelab::plot {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::Not;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
const std::string kMinus = "\u2212";      // tick labels use the typographic minus sign
constexpr double kPixelTolerance = 0.06;  // coordinates are written to 0.1 px

// ---------------------------------------------------------------------------------------------
// A small XML well-formedness checker: one root element, tags nest and close in order, attribute
// values are quoted, text and attribute values use only the predefined entities. Returns "" when
// well formed, else what is wrong and where.

bool IsNameChar(char c) {
  return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == ':' || c == '.';
}

std::string CheckEntities(const std::string& s, size_t offset) {
  static const std::regex kEntity("^&(amp|lt|gt|quot|apos|#[0-9]+|#x[0-9a-fA-F]+);");
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '<') return "bare '<' at " + std::to_string(offset + i);
    if (s[i] == '&' && !std::regex_search(s.substr(i, 12), kEntity))
      return "bad entity at " + std::to_string(offset + i);
    if (static_cast<unsigned char>(s[i]) < 0x20 && s[i] != '\n' && s[i] != '\t' && s[i] != '\r') {
      return "control character at " + std::to_string(offset + i);
    }
  }
  return "";
}

std::string XmlProblem(const std::string& xml) {
  std::vector<std::string> open;
  int roots = 0;
  size_t i = 0;
  while (i < xml.size()) {
    const size_t lt = xml.find('<', i);
    const std::string text = xml.substr(i, lt == std::string::npos ? std::string::npos : lt - i);
    if (std::string e = CheckEntities(text, i); !e.empty()) return e;
    if (open.empty() && text.find_first_not_of(" \t\r\n") != std::string::npos)
      return "text outside the root at " + std::to_string(i);
    if (lt == std::string::npos) break;
    i = lt;
    if (xml.compare(i, 2, "<?") == 0 || xml.compare(i, 4, "<!--") == 0) {
      const std::string end = xml[i + 1] == '?' ? "?>" : "-->";
      const size_t e = xml.find(end, i);
      if (e == std::string::npos) return "unterminated declaration at " + std::to_string(i);
      i = e + end.size();
      continue;
    }
    const bool closing = xml.compare(i, 2, "</") == 0;
    size_t p = i + (closing ? 2 : 1);
    const size_t name_begin = p;
    while (p < xml.size() && IsNameChar(xml[p])) ++p;
    const std::string name = xml.substr(name_begin, p - name_begin);
    if (name.empty()) return "missing tag name at " + std::to_string(i);
    if (closing) {
      if (p >= xml.size() || xml[p] != '>') return "malformed end tag at " + std::to_string(i);
      if (open.empty() || open.back() != name)
        return "</" + name + "> does not close the open element at " + std::to_string(i);
      open.pop_back();
      i = p + 1;
      continue;
    }
    if (open.empty() && ++roots > 1) return "second root element at " + std::to_string(i);
    while (true) {  // attributes
      while (p < xml.size() && std::isspace(static_cast<unsigned char>(xml[p]))) ++p;
      if (p >= xml.size()) return "unterminated tag <" + name;
      if (xml.compare(p, 2, "/>") == 0) {
        p += 2;
        break;
      }
      if (xml[p] == '>') {
        open.push_back(name);
        ++p;
        break;
      }
      const size_t attr_begin = p;
      while (p < xml.size() && IsNameChar(xml[p])) ++p;
      if (p == attr_begin || xml.compare(p, 2, "=\"") != 0)
        return "malformed attribute in <" + name + " at " + std::to_string(p);
      const size_t value_end = xml.find('"', p + 2);
      if (value_end == std::string::npos) return "unterminated attribute value at " + std::to_string(p);
      if (std::string e = CheckEntities(xml.substr(p + 2, value_end - p - 2), p + 2); !e.empty()) return e;
      p = value_end + 1;
    }
    i = p;
  }
  if (!open.empty()) return "<" + open.back() + "> is never closed";
  if (roots != 1) return "no root element";
  return "";
}

TEST(XmlCheckerTest, CatchesWhatItShould) {
  EXPECT_EQ(XmlProblem("<a x=\"1\"><b/>t &amp; u</a>"), "");
  EXPECT_NE(XmlProblem("<a><b></a></b>"), "");
  EXPECT_NE(XmlProblem("<a>x < y</a>"), "");
  EXPECT_NE(XmlProblem("<a>x & y</a>"), "");
  EXPECT_NE(XmlProblem("<a x=1/>"), "");
  EXPECT_NE(XmlProblem("<a>"), "");
  EXPECT_NE(XmlProblem("<a/><b/>"), "");
}

// ---------------------------------------------------------------------------------------------
// Reading our own output back.

// The content of the first <g class="name"> ... </g> (these groups hold no nested <g>).
std::string Group(const std::string& svg, const std::string& css_class) {
  const std::string open = "<g class=\"" + css_class + "\"";
  const size_t b = svg.find(open);
  if (b == std::string::npos) return "";
  const size_t e = svg.find("</g>", b);
  return svg.substr(b, e - b);
}

std::vector<std::string> Texts(const std::string& svg_part) {
  static const std::regex kText("<text[^>]*>([^<]*)</text>");
  std::vector<std::string> out;
  for (std::sregex_iterator it(svg_part.begin(), svg_part.end(), kText), end; it != end; ++it) out.push_back((*it)[1]);
  return out;
}

int Count(const std::string& s, const std::string& what) {
  int n = 0;
  for (size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

std::vector<std::string> TickLabels(const std::string& svg, const char* axis) { return Texts(Group(svg, axis)); }

double Attribute(const std::string& element, const std::string& name) {
  const std::regex re(" " + name + "=\"([-0-9.e]+)\"");
  std::smatch m;
  if (!std::regex_search(element, m, re)) return kNaN;
  return std::stod(m[1]);
}

struct Rect {
  double x, y, width, height;
};

// The plot area, as the clip path's rectangle.
Rect PlotArea(const std::string& svg) {
  const size_t b = svg.find("<clipPath");
  const std::string clip = svg.substr(b, svg.find("</clipPath>", b) - b);
  return {Attribute(clip, "x"), Attribute(clip, "y"), Attribute(clip, "width"), Attribute(clip, "height")};
}

std::vector<std::string> Elements(const std::string& svg_part, const std::string& tag) {
  const std::regex re("<" + tag + "\\b[^>]*>");
  std::vector<std::string> out;
  for (std::sregex_iterator it(svg_part.begin(), svg_part.end(), re), end; it != end; ++it) out.push_back(it->str());
  return out;
}

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

Series Line(std::vector<double> x, std::vector<double> y, std::string label = "") {
  Series s;
  s.x = std::move(x);
  s.y = std::move(y);
  s.label = std::move(label);
  return s;
}

std::vector<double> Linspace(double a, double b, int n) {
  std::vector<double> v(n);
  for (int i = 0; i < n; ++i) v[i] = a + (b - a) * i / (n - 1);
  return v;
}

// ---------------------------------------------------------------------------------------------
// Line plots.

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

TEST(EscapeXmlTest, EscapesMarkupAndDropsControlCharacters) {
  EXPECT_EQ(EscapeXml("<a href=\"x\">&</a>"), "&lt;a href=&quot;x&quot;&gt;&amp;&lt;/a&gt;");
  EXPECT_EQ(EscapeXml("tab\there\x07"), "tab\there");
  EXPECT_EQ(EscapeXml("\u00b5m"), "\u00b5m");  // UTF-8 passes through
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

// ---------------------------------------------------------------------------------------------
// Heat maps.

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

// ---------------------------------------------------------------------------------------------
// Realistic sample pictures, each checked for well-formedness; written to STROKELAB_PLOT_DEMO_DIR
// (or the test's temporary folder) for looking at.

TEST(DemoTest, RealisticPicturesAreWellFormed) {
  const char* env_dir = std::getenv("STROKELAB_PLOT_DEMO_DIR");
  const std::string dir = env_dir ? env_dir : ::testing::TempDir();
  std::vector<std::string> written;
  auto save = [&](const std::string& name, const std::string& svg) {
    EXPECT_EQ(XmlProblem(svg), "") << name;
    std::ofstream(dir + "/" + name) << svg;
    written.push_back(svg);
  };

  // A bouncing stroke: decaying oscillation, clipped at an end stop, with a noisy measurement.
  const int n = 51200;
  Series model, measured, stop;
  for (int i = 0; i < n; ++i) {
    const double t = 0.1 * i / (n - 1);
    const double x = 1.4 * std::exp(-t / 0.04) * std::sin(2 * M_PI * 62 * t);
    model.x.push_back(t * 1e3);
    model.y.push_back(std::max(x, -0.8));
    measured.x.push_back(t * 1e3);
    measured.y.push_back(std::max(x, -0.8) + 0.03 * std::sin(i * 12.9898) + (i == 30000 ? 0.9 : 0.0));
  }
  for (int i = 0; i < 200; ++i) measured.y[20000 + i] = kNaN;  // a dropout
  measured.label = "measured (51,200 samples)";
  measured.line_width = 1.0;
  model.label = "model";
  model.dashed = true;
  stop.label = "end stop";
  stop.x = {0, 100};
  stop.y = {-0.8, -0.8};
  stop.color = "#7F7F7F";
  stop.line_width = 1.0;
  Axes axes;
  axes.title = "Stroke after a 12 V step";
  axes.x_label = "time [ms]";
  axes.y_label = "displacement [mm]";
  save("plot_demo_line.svg", LinePlot({measured, model, stop}, axes));

  // A frequency response on log-log axes with markers.
  Series mag, fit;
  for (double f = 5; f < 3000; f *= 1.15) {
    const double r = f / 180, h = 1 / std::sqrt(std::pow(1 - r * r, 2) + std::pow(2 * 0.08 * r, 2));
    mag.x.push_back(f), mag.y.push_back(h * (1 + 0.05 * std::sin(f)));
    fit.x.push_back(f), fit.y.push_back(h);
  }
  mag.label = "measured";
  mag.markers = true;
  mag.line = false;
  fit.label = "fit: f0 = 180 Hz, \u03b6 = 0.08";
  Axes bode;
  bode.title = "Compliance |X/F|";
  bode.x_label = "frequency [Hz]";
  bode.y_label = "|X/F| [normalised]";
  bode.log_x = bode.log_y = true;
  save("plot_demo_bode.svg", LinePlot({fit, mag}, bode));

  // A peak-stroke map over drive frequency (log-spaced) and amplitude, with a threshold curve.
  HeatMap map;
  for (double f = 20; f <= 2000; f *= 1.08) map.x.push_back(f);
  map.y = Linspace(0.5, 12, 47);
  map.z_label = "peak stroke [mm]";
  Series threshold, jump;
  for (double f : map.x) {
    threshold.x.push_back(f);
    threshold.y.push_back(2 + 8 * std::abs(std::log10(f / 180)));
  }
  for (double v : map.y) {
    std::vector<double> row;
    for (double f : map.x) {
      const double r = f / 180, h = 1 / std::sqrt(std::pow(1 - r * r, 2) + std::pow(2 * 0.15 * r, 2));
      row.push_back(v * h * 0.12 > 4 && f > 400 && f < 500 ? kNaN : v * h * 0.12);
    }
    map.z.push_back(row);
  }
  threshold.label = "contact threshold";
  threshold.line_width = 2;
  threshold.color = "#ffffff";
  jump.x = {150, 150, 240};
  jump.y = {0.5, 6, 12};
  jump.label = "jump boundary";
  jump.dashed = true;
  Axes heat;
  heat.title = "Peak stroke vs drive";
  heat.x_label = "drive frequency [Hz]";
  heat.y_label = "drive amplitude [V]";
  heat.log_x = true;
  save("plot_demo_heatmap.svg", HeatMapPlot(map, {threshold, jump}, heat));
  map.log_z = true;
  save("plot_demo_heatmap_logz.svg", HeatMapPlot(map, {}, heat));
  ASSERT_EQ(written.size(), 4u);
  // The 51,200-sample trace is decimated per pixel column, yet its one-sample spike survives.
  EXPECT_LT(written[0].size(), 200'000u);
}

}  // namespace
}  // namespace strokelab::plot
