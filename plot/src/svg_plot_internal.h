// Pieces shared by the files of the SVG pictures (svg_writer.cc, axis_ticks.cc, plot_frame.cc,
// line_plot.cc, legend.cc, heat_map.cc); not a public API. Everything is laid out in the pixel space
// of the final picture; text widths are estimated (no font metrics), so margins are generous.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "strokelab/plot/svg_plot.h"

namespace strokelab::plot::svg_internal {

// ---------------------------------------------------------------------------------------------
// Style, in one place for all pictures. All sizes in [px].

inline constexpr double kTickFontPx = 12;
inline constexpr double kLabelFontPx = 13;
inline constexpr double kTitleFontPx = 15;
inline constexpr double kLegendFontPx = 12;
// Mean advance of sans-serif glyphs [em]; DejaVu Sans (the usual fallback) is the widest common one.
inline constexpr double kGlyphWidthEm = 0.6;
inline constexpr double kBoldWidthFactor = 1.1;
inline constexpr double kTickLenPx = 5;
inline constexpr double kMinorTickLenPx = 3;
inline constexpr double kTickLabelGapPx = 3;
inline constexpr double kOuterPadPx = 10;
inline constexpr double kMinTickLabelGapPx = 12;            // horizontal white space between neighbouring tick labels
inline constexpr double kMinPxPerDecadeForMinorTicks = 30;  // below: no ticks at 2..9 times a decade

inline constexpr const char* kFontFamily = "Helvetica, Arial, 'DejaVu Sans', sans-serif";
inline constexpr const char* kTextColor = "#222222";
inline constexpr const char* kFrameColor = "#444444";
inline constexpr const char* kGridColor = "#e3e3e3";
inline constexpr const char* kMinorGridColor = "#f1f1f1";

// Okabe & Ito's colour-blind-safe set, without its yellow (invisible on white) and with grey added.
inline constexpr std::array<const char*, 8> kPalette = {"#0072B2", "#D55E00", "#009E73", "#CC79A7",
                                                        "#E69F00", "#56B4E9", "#000000", "#7F7F7F"};

// ---------------------------------------------------------------------------------------------
// Text and number output (svg_writer.cc).

// A number for an attribute: fixed decimals, trailing zeros dropped. Coordinates far outside the
// picture are clamped so that huge data values cannot produce "inf" or unreadable exponents.
std::string Num(double v, int decimals = 2);

double TextWidthPx(std::string_view s, double font_px);

// Builds one element: Tag("line").Attr("x1", 3).Close() gives <line x1="3"/>.
class Tag {
 public:
  explicit Tag(std::string_view name) : name_(name), text_("<" + name_) {}
  Tag& Attr(std::string_view key, double value) { return Raw(key, Num(value)); }
  Tag& Attr(std::string_view key, std::string_view value) { return Raw(key, EscapeXml(std::string(value))); }
  std::string Close() const { return text_ + "/>\n"; }
  std::string Open() const { return text_ + ">"; }
  // <name ...>escaped text</name>
  std::string Wrap(const std::string& content) const { return Open() + EscapeXml(content) + "</" + name_ + ">\n"; }

 private:
  Tag& Raw(std::string_view key, const std::string& value) {
    text_ += ' ';
    text_ += key;
    text_ += "=\"";
    text_ += value;
    text_ += '"';
    return *this;
  }
  std::string name_;
  std::string text_;
};

// <text> with its baseline at y.
std::string Text(double x, double y, const std::string& content, double font_px, const char* anchor,
                 std::string_view css_class = "");

// Where to centre a line of text that would like to be centred on `center` within [lo, hi]: moved
// to stay inside, and shrunk when even that is not enough. `width_factor` widens the estimate (bold).
struct PlacedLine {
  double center, font_px;
};
PlacedLine FitLine(std::string_view text, double font_px, double center, double lo, double hi,
                   double width_factor = 1.0);

// ---------------------------------------------------------------------------------------------
// Ranges, scales and ticks (axis_ticks.cc).

struct Range {
  double lo, hi;
};

// Maps data values to pixels along one axis; a log axis maps log10(value) linearly.
struct Scale {
  Range range;
  bool log = false;
  double px_lo = 0, px_hi = 1;  // pixel positions of range.lo and range.hi

  double T(double v) const { return log ? std::log10(v) : v; }
  double operator()(double v) const {
    return px_lo + (T(v) - T(range.lo)) / (T(range.hi) - T(range.lo)) * (px_hi - px_lo);
  }
  // Whether v can be placed on this axis at all.
  bool Accepts(double v) const { return std::isfinite(v) && (!log || v > 0); }
  double PxPerUnit() const { return std::abs(px_hi - px_lo) / (T(range.hi) - T(range.lo)); }
};

// How a range taken from the data is widened.
enum class Fit {
  kExact,         // as is (heat maps: the cells fill the box)
  kSnapToTicks,   // outward to the next major tick (x axes)
  kPadToHalfTick  // a small margin, then outward to half a tick step (y axes: curves clear the box)
};

void Extend(std::optional<Range>& r, double v);

// The range an axis shows: explicit limits where given (not NaN), the data elsewhere, widened
// per `fit` on the data-derived sides only.
Range ResolveRange(double user_lo, double user_hi, std::optional<Range> data, bool log, Fit fit, double axis_px,
                   double min_spacing_px);

struct AxisTicks {
  std::vector<double> major;        // labelled, in data units
  std::vector<std::string> labels;  // one per major tick
  std::vector<double> minor;        // unlabelled (log axes)

  double MaxLabelWidthPx() const {
    double w = 0;
    for (const auto& l : labels) w = std::max(w, TextWidthPx(l, kTickFontPx));
    return w;
  }
};

AxisTicks MakeTicks(const Scale& s, double spacing_px, bool horizontal);

// ---------------------------------------------------------------------------------------------
// Layout and the parts every picture shares (plot_frame.cc).

// The plot area [px].
struct Frame {
  double left, top, width, height;
  double right() const { return left + width; }
  double bottom() const { return top + height; }
};

double TopMargin(const Axes& axes);
double PlotHeight(const Axes& axes);

// Room on the right for the last x tick label, which is centred on the plot's right edge.
inline constexpr double kRightMarginPx = 28;

void CheckAxes(const Axes& axes);

std::string OpenSvg(const Axes& axes);

// A clip path id that is the same for the same rectangle, so two pictures inlined in one HTML page
// never pick up each other's (different) clip rectangle.
std::string ClipId(const Frame& f);
std::string ClipPathDef(const Frame& f);

// Light gridlines at the major ticks (and fainter ones at minor log ticks).
std::string Grid(const Frame& f, const Scale& xs, const AxisTicks& xt, const Scale& ys, const AxisTicks& yt);

// Box, outward ticks, tick labels, axis labels and title, drawn over the data.
std::string AxesDecoration(const Frame& f, const Axes& axes, const Scale& xs, const AxisTicks& xt, const Scale& ys,
                           const AxisTicks& yt);

// Axis scales and ticks. The plot area's height is fixed by the margins for text; its left edge
// follows from the widest y tick label.
struct PlotGeometry {
  Frame frame;
  Scale xs, ys;
  AxisTicks xt, yt;
};

inline constexpr double kXTickSpacingPx = 60, kYTickSpacingPx = 40;  // least distance between major ticks

PlotGeometry Layout(const Axes& axes, std::optional<Range> x_data, std::optional<Range> y_data, Fit x_fit, Fit y_fit,
                    double right_margin_px);

// ---------------------------------------------------------------------------------------------
// Series (line_plot.cc) and their legend (legend.cc).

void CheckSeries(const std::vector<Series>& series, const char* what);

std::string DashArray(double line_width);
double MarkerRadius(const Series& s);

// Colour of each series: its own, or the next palette entry.
std::vector<std::string> SeriesColors(const std::vector<Series>& series);

// The series as polylines and markers, clipped to the plot area. `halo` draws a wider white line
// beneath each, so curves stay visible over a heat map of any colour.
std::string AllSeries(const std::vector<Series>& series, const Frame& f, const Scale& xs, const Scale& ys, bool halo);

// Legend in the top-right corner of the plot area, for series with a label. `cased` outlines the
// line samples in grey, as overlays on a heat map may be white.
std::string Legend(const std::vector<Series>& series, const Frame& f, bool cased);

// ---------------------------------------------------------------------------------------------
// The sequential colour map and its bar (heat_map.cc), shared by heat maps and coloured line plots.

// viridis at t in [0, 1] (clamped).
std::string Viridis(double t);
// Width of a colour bar right of the plot area, with its tick labels and label.
double ColorBarWidth(const AxisTicks& z_ticks, const std::string& z_label);
// The bar right of the plot area `f`, its gradient running bottom (zs.range.lo) to top.
std::string ColorBarSvg(const Frame& f, const Scale& zs, const AxisTicks& zt, const std::string& z_label);

}  // namespace strokelab::plot::svg_internal
