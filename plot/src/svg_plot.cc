// SVG line plots and heat maps, written directly as text. Everything is laid out in the pixel
// space of the final picture; text widths are estimated (no font metrics), so margins are generous.
#include "strokelab/plot/svg_plot.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace strokelab::plot {
namespace {

// ---------------------------------------------------------------------------------------------
// Style. All sizes in [px].

constexpr double kTickFontPx = 12;
constexpr double kLabelFontPx = 13;
constexpr double kTitleFontPx = 15;
constexpr double kLegendFontPx = 12;
// Mean advance of sans-serif glyphs [em]; DejaVu Sans (the usual fallback) is the widest common one.
constexpr double kGlyphWidthEm = 0.6;
constexpr double kBoldWidthFactor = 1.1;
constexpr double kTickLenPx = 5;
constexpr double kMinorTickLenPx = 3;
constexpr double kTickLabelGapPx = 3;
constexpr double kOuterPadPx = 10;
constexpr double kMinTickLabelGapPx = 12;            // horizontal white space between neighbouring tick labels
constexpr double kMinPxPerDecadeForMinorTicks = 30;  // below: no ticks at 2..9 times a decade

constexpr const char* kFontFamily = "Helvetica, Arial, 'DejaVu Sans', sans-serif";
constexpr const char* kTextColor = "#222222";
constexpr const char* kFrameColor = "#444444";
constexpr const char* kGridColor = "#e3e3e3";
constexpr const char* kMinorGridColor = "#f1f1f1";

// Okabe & Ito's colour-blind-safe set, without its yellow (invisible on white) and with grey added.
constexpr std::array<const char*, 8> kPalette = {"#0072B2", "#D55E00", "#009E73", "#CC79A7",
                                                 "#E69F00", "#56B4E9", "#000000", "#7F7F7F"};

// A series with more points than this many per pixel column is decimated (min/max per column).
constexpr double kDecimateAbovePointsPerPx = 4.0;

// viridis (van der Walt, Smith & Firing, matplotlib, CC0) sampled at t = k/16; interpolating
// linearly between these stays within 6/255 of the full 256-entry table.
constexpr std::array<std::array<int, 3>, 17> kViridis = {{
    {68, 1, 84},
    {72, 24, 106},
    {71, 45, 123},
    {66, 64, 134},
    {59, 82, 139},
    {51, 99, 141},
    {44, 114, 142},
    {38, 129, 142},
    {33, 144, 140},
    {31, 159, 136},
    {40, 174, 128},
    {62, 188, 116},
    {93, 201, 99},
    {130, 211, 76},
    {171, 220, 50},
    {213, 226, 26},
    {253, 231, 37},
}};

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Pt {
  double x, y;
};

// ---------------------------------------------------------------------------------------------
// Text and number output.

// A number for an attribute: fixed decimals, trailing zeros dropped. Coordinates far outside the
// picture are clamped so that huge data values cannot produce "inf" or unreadable exponents.
std::string Num(double v, int decimals = 2) {
  if (!std::isfinite(v)) v = 0.0;
  v = std::clamp(v, -1e6, 1e6);
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  std::string s = buf;
  if (s.find('.') != std::string::npos) {
    while (s.back() == '0') s.pop_back();
    if (s.back() == '.') s.pop_back();
  }
  if (s == "-0") s = "0";
  return s;
}

// Number of characters (UTF-8 code points) in `s`.
size_t CodePoints(std::string_view s) {
  return std::count_if(s.begin(), s.end(), [](char c) { return (static_cast<unsigned char>(c) & 0xC0) != 0x80; });
}

double TextWidthPx(std::string_view s, double font_px) {
  return static_cast<double>(CodePoints(s)) * kGlyphWidthEm * font_px;
}

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
                 std::string_view css_class = "") {
  Tag t("text");
  if (!css_class.empty()) t.Attr("class", css_class);
  t.Attr("x", x).Attr("y", y).Attr("font-size", font_px).Attr("text-anchor", anchor);
  return t.Wrap(content);
}

// Where to centre a line of text that would like to be centred on `center` within [lo, hi]: moved
// to stay inside, and shrunk when even that is not enough. `width_factor` widens the estimate (bold).
struct PlacedLine {
  double center, font_px;
};
PlacedLine FitLine(std::string_view text, double font_px, double center, double lo, double hi,
                   double width_factor = 1.0) {
  const double width = width_factor * TextWidthPx(text, font_px);
  if (width > hi - lo) return {(lo + hi) / 2, std::max(8.0, font_px * (hi - lo) / width)};
  return {std::clamp(center, lo + width / 2, hi - width / 2), font_px};
}

// Typographic minus sign (U+2212) instead of a hyphen, as printed tables do.
std::string WithMinusSign(std::string s) {
  if (!s.empty() && s[0] == '-') s.replace(0, 1, "\u2212");
  return s;
}

std::string TrimZeros(std::string s) {
  if (s.find('.') == std::string::npos) return s;
  while (s.back() == '0') s.pop_back();
  if (s.back() == '.') s.pop_back();
  return s;
}

// 2.50e+06 -> 2.5e6
std::string ScientificLabel(double v, int mantissa_decimals) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.*e", std::max(0, mantissa_decimals), v);
  const std::string s = buf;
  const size_t e = s.find('e');
  const int exponent = std::stoi(s.substr(e + 1));
  return WithMinusSign(TrimZeros(s.substr(0, e)) + "e" + WithMinusSign(std::to_string(exponent)));
}

// Plain decimals between 1e-3 and 1e5, "2.5e6" style outside: chosen once per axis so that all
// labels of one axis look alike.
bool UseScientific(double max_abs) { return max_abs >= 1e5 || (max_abs > 0 && max_abs < 1e-3); }

int FloorLog10(double v) { return static_cast<int>(std::floor(std::log10(v) + 1e-9)); }

// A tick on a 1-2-5 grid of spacing `step`, with just enough digits to tell neighbours apart.
std::string FormatTick(double v, double step, bool scientific) {
  if (v == 0.0) {
    if (scientific) return "0";
    v = 0.0;  // never "-0.0"
  }
  if (scientific) return ScientificLabel(v, FloorLog10(std::abs(v)) - FloorLog10(step));
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.*f", std::max(0, -FloorLog10(step)), v);
  return WithMinusSign(buf);
}

// ---------------------------------------------------------------------------------------------
// Ranges, scales and ticks.

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

void Extend(std::optional<Range>& r, double v) {
  if (!r) {
    r = Range{v, v};
  } else {
    r->lo = std::min(r->lo, v);
    r->hi = std::max(r->hi, v);
  }
}

// The smallest step of 1, 2 or 5 times a power of ten that is at least `min_step`.
double NiceStepAtLeast(double min_step) {
  const double magnitude = std::pow(10.0, std::floor(std::log10(min_step)));
  for (double m : {1.0, 2.0, 5.0}) {
    if (m * magnitude >= min_step * (1 - 1e-9)) return m * magnitude;
  }
  return 10 * magnitude;
}

// The 1-2-5 step that puts major ticks at least `min_spacing_px` apart.
double TickStep(Range r, double axis_px, double min_spacing_px) {
  return NiceStepAtLeast((r.hi - r.lo) * min_spacing_px / axis_px);
}

// The largest 1, 2 or 5 times a power of ten at or below v > 0, and the smallest at or above.
double OneTwoFiveBelow(double v) {
  const double magnitude = std::pow(10.0, std::floor(std::log10(v) + 1e-9));
  for (double m : {5.0, 2.0}) {
    if (m * magnitude <= v * (1 + 1e-9)) return m * magnitude;
  }
  return magnitude;
}
double OneTwoFiveAbove(double v) { return NiceStepAtLeast(v); }

// Throws for explicit axis limits that cannot be drawn.
void CheckLimits(const char* lo_name, double lo, const char* hi_name, double hi, bool log) {
  const auto check = [log](const char* name, double v) {
    if (std::isnan(v)) return;
    if (!std::isfinite(v)) throw std::invalid_argument(std::string("Axes.") + name + ": must be finite or NaN");
    if (log && v <= 0) {
      throw std::invalid_argument(std::string("Axes.") + name + ": must be positive on a log axis (got " + Num(v, 6) +
                                  ")");
    }
  };
  check(lo_name, lo);
  check(hi_name, hi);
  if (!std::isnan(lo) && !std::isnan(hi) && !(lo < hi)) {
    throw std::invalid_argument(std::string("Axes.") + lo_name + ": must be below Axes." + hi_name);
  }
}

// Moves the free ends of a range outward to round values, per `fit`.
Range SnapOutward(Range r, bool log, Fit fit, bool free_lo, bool free_hi, double axis_px, double min_spacing_px) {
  if (log) {  // outward to 1, 2 or 5 times a power of ten: whole decades would waste up to one each side
    if (free_lo) r.lo = OneTwoFiveBelow(r.lo);
    if (free_hi) r.hi = OneTwoFiveAbove(r.hi);
    return r;
  }
  if (fit == Fit::kPadToHalfTick) {
    const double pad = 0.02 * (r.hi - r.lo);
    if (free_lo) r.lo -= pad;
    if (free_hi) r.hi += pad;
  }
  double step = TickStep(r, axis_px, min_spacing_px);
  if (fit == Fit::kPadToHalfTick) step /= 2;
  if (free_lo) r.lo = std::floor(r.lo / step + 1e-9) * step;
  if (free_hi) r.hi = std::ceil(r.hi / step - 1e-9) * step;
  return r;
}

// The range an axis shows: explicit limits where given (not NaN), the data elsewhere, widened
// per `fit` on the data-derived sides only.
Range ResolveRange(double user_lo, double user_hi, std::optional<Range> data, bool log, Fit fit, double axis_px,
                   double min_spacing_px) {
  const bool fixed_lo = !std::isnan(user_lo), fixed_hi = !std::isnan(user_hi);
  Range r = data.value_or(log ? Range{1.0, 10.0} : Range{0.0, 1.0});
  if (fixed_lo) r.lo = user_lo;
  if (fixed_hi) r.hi = user_hi;

  if (!(r.lo < r.hi)) {  // one value only, or an explicit limit beyond all the data
    if (log) {
      if (!fixed_hi) r.hi = r.lo * 10.0;
      if (!fixed_lo) r.lo = (fixed_hi ? r.hi : r.lo) / 10.0;
    } else {
      const double ref = fixed_hi && !fixed_lo ? r.hi : r.lo;
      const double half = ref == 0.0 ? 1.0 : 0.1 * std::abs(ref);
      if (fixed_lo) {
        r.hi = r.lo + 2 * half;
      } else if (fixed_hi) {
        r.lo = r.hi - 2 * half;
      } else {
        r = {r.lo - half, r.hi + half};
      }
    }
  }
  if (fit == Fit::kExact) return r;
  const Range unsnapped = r;
  r = SnapOutward(r, log, fit, !fixed_lo, !fixed_hi, axis_px, min_spacing_px);
  // Near the largest doubles snapping can overflow.
  return std::isfinite(r.lo) && std::isfinite(r.hi) ? r : unsnapped;
}

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

// Multiples of `step` inside the range, labelled consistently.
AxisTicks StepTicks(Range r, double step) {
  AxisTicks t;
  const double first = std::ceil(r.lo / step - 1e-9), last = std::floor(r.hi / step + 1e-9);
  // A range too narrow for its magnitude (1e20 + 1e4) has no representable step: no ticks.
  if (!(last - first >= 0 && last - first <= 1000)) return t;
  double max_abs = 0;
  for (int i = 0; i <= static_cast<int>(last - first); ++i) {
    const double k = first + i;
    const double v = k == 0 ? 0.0 : k * step;  // exact zero, never 1e-17
    t.major.push_back(v);
    max_abs = std::max(max_abs, std::abs(v));
  }
  const bool scientific = UseScientific(max_abs);
  for (double v : t.major) t.labels.push_back(FormatTick(v, step, scientific));
  return t;
}

// Whether neighbouring tick labels leave room between them.
bool LabelsFit(const AxisTicks& t, const Scale& s, bool horizontal) {
  for (size_t i = 1; i < t.major.size(); ++i) {
    const double gap = std::abs(s(t.major[i]) - s(t.major[i - 1]));
    const double need =
        horizontal ? 0.5 * (TextWidthPx(t.labels[i], kTickFontPx) + TextWidthPx(t.labels[i - 1], kTickFontPx)) +
                         kMinTickLabelGapPx
                   : 2 * kTickFontPx;
    if (gap < need) return false;
  }
  return true;
}

AxisTicks LinearTicks(const Scale& s, double min_spacing_px, bool horizontal) {
  double step = TickStep(s.range, std::abs(s.px_hi - s.px_lo), min_spacing_px);
  AxisTicks t = StepTicks(s.range, step);
  // A short axis may fit less than two ticks at the least spacing; two labels matter more.
  for (int tries = 0; tries < 6 && t.major.size() < 2; ++tries) {
    step = OneTwoFiveBelow(step * 0.99);
    t = StepTicks(s.range, step);
  }
  if (t.major.size() < 2) return t;
  // Wider steps until the labels no longer collide (long labels on a narrow axis).
  for (int tries = 0; tries < 6 && !LabelsFit(t, s, horizontal); ++tries) {
    step = NiceStepAtLeast(step * 1.01);
    t = StepTicks(s.range, step);
  }
  return t;
}

bool IsPowerOfTen(double v) {
  const double e = std::log10(v);
  return std::abs(e - std::round(e)) < 1e-9;
}

// Ticks at m * 10^d inside the range: labelled where m is in `labelled_mantissas` (and, for m = 1,
// d is a multiple of `every`), minor otherwise.
AxisTicks PowerTicks(Range r, const std::vector<int>& labelled_mantissas, int every) {
  AxisTicks t;
  const int d0 = FloorLog10(r.lo), d1 = FloorLog10(r.hi);
  for (int d = d0; d <= d1; ++d) {
    for (int m = 1; m <= 9; ++m) {
      const double v = m * std::pow(10.0, d);
      if (v < r.lo * (1 - 1e-9) || v > r.hi * (1 + 1e-9)) continue;
      const bool wanted =
          std::find(labelled_mantissas.begin(), labelled_mantissas.end(), m) != labelled_mantissas.end();
      const bool skipped_decade = m == 1 && ((d % every) + every) % every != 0;
      (wanted && !skipped_decade ? t.major : t.minor).push_back(v);
    }
  }
  const bool scientific = !t.major.empty() && (UseScientific(t.major.back()) || UseScientific(t.major.front()));
  for (double v : t.major) t.labels.push_back(FormatTick(v, std::pow(10.0, FloorLog10(v)), scientific));
  return t;
}

// Log ticks: labelled decades (every k-th when crowded; 1, 2 and 5 in each when roomy) with minor
// ticks at 2..9 times each decade. A range of less than two decades gets labels at 1, 2, 5 (or all
// of 1..9) times a power of ten, and failing that, linear ticks.
AxisTicks LogTicks(const Scale& s, double spacing_px, bool horizontal) {
  const double px_per_decade = s.PxPerUnit();
  if (px_per_decade >= 4 * spacing_px) {  // roomy decades: label 1, 2 and 5 in each
    AxisTicks t = PowerTicks(s.range, {1, 2, 5}, 1);
    if (t.major.size() >= 2 && LabelsFit(t, s, horizontal)) return t;
  }
  for (int every : {1, 2, 3, 5, 10, 20, 25, 50, 100, 200}) {  // label every k-th decade
    AxisTicks t = PowerTicks(s.range, {1}, every);
    if (t.major.size() < 2) break;
    if (!LabelsFit(t, s, horizontal)) continue;
    // Crowded decades: 2..9 would blur into a bar, so mark only the unlabelled decades, or nothing.
    if (px_per_decade < kMinPxPerDecadeForMinorTicks) std::erase_if(t.minor, [](double v) { return !IsPowerOfTen(v); });
    if (px_per_decade < 5) t.minor.clear();
    return t;
  }
  for (const std::vector<int>& mantissas : {std::vector<int>{1, 2, 5}, std::vector<int>{1, 2, 3, 4, 5, 6, 7, 8, 9}}) {
    AxisTicks t = PowerTicks(s.range, mantissas, 1);
    if (t.major.size() >= 2 && LabelsFit(t, s, horizontal)) return t;
  }
  return LinearTicks(s, spacing_px, horizontal);  // well under a decade: a 1-2-5 grid reads best
}

AxisTicks MakeTicks(const Scale& s, double spacing_px, bool horizontal) {
  return s.log ? LogTicks(s, spacing_px, horizontal) : LinearTicks(s, spacing_px, horizontal);
}

// ---------------------------------------------------------------------------------------------
// Layout and the parts every picture shares.

// The plot area [px].
struct Frame {
  double left, top, width, height;
  double right() const { return left + width; }
  double bottom() const { return top + height; }
};

double TopMargin(const Axes& axes) { return kOuterPadPx + (axes.title.empty() ? 6 : kTitleFontPx + 12); }

double BottomMargin(const Axes& axes) {
  return kTickLenPx + kTickLabelGapPx + kTickFontPx + (axes.x_label.empty() ? 0 : 10 + kLabelFontPx) + kOuterPadPx + 4;
}

double LeftMargin(const Axes& axes, const AxisTicks& y_ticks) {
  return kOuterPadPx + (axes.y_label.empty() ? 0 : kLabelFontPx + 10) + y_ticks.MaxLabelWidthPx() + kTickLabelGapPx +
         2 + kTickLenPx;
}

// Room on the right for the last x tick label, which is centred on the plot's right edge.
constexpr double kRightMarginPx = 28;

void CheckAxes(const Axes& axes) {
  if (axes.width_px < 200)
    throw std::invalid_argument("Axes.width_px: must be at least 200 (got " + std::to_string(axes.width_px) + ")");
  if (axes.height_px < 150)
    throw std::invalid_argument("Axes.height_px: must be at least 150 (got " + std::to_string(axes.height_px) + ")");
  CheckLimits("x_min", axes.x_min, "x_max", axes.x_max, axes.log_x);
  CheckLimits("y_min", axes.y_min, "y_max", axes.y_max, axes.log_y);
}

void CheckSeries(const std::vector<Series>& series, const char* what) {
  for (size_t i = 0; i < series.size(); ++i) {
    const Series& s = series[i];
    const std::string name = std::string(what) + "[" + std::to_string(i) + "]";
    if (s.x.size() != s.y.size()) {
      throw std::invalid_argument(name + ".x: has " + std::to_string(s.x.size()) + " points but y has " +
                                  std::to_string(s.y.size()));
    }
    if (!(s.line_width > 0) || !std::isfinite(s.line_width)) {
      throw std::invalid_argument(name + ".line_width: must be positive and finite");
    }
  }
}

std::string OpenSvg(const Axes& axes) {
  std::string out = Tag("svg")
                        .Attr("xmlns", "http://www.w3.org/2000/svg")
                        .Attr("version", "1.1")
                        .Attr("width", axes.width_px)
                        .Attr("height", axes.height_px)
                        .Attr("viewBox", "0 0 " + std::to_string(axes.width_px) + " " + std::to_string(axes.height_px))
                        .Attr("font-family", kFontFamily)
                        .Attr("fill", kTextColor)
                        .Open() +
                    "\n";
  if (!axes.title.empty()) out += Tag("title").Wrap(axes.title);
  out += Tag("rect").Attr("width", "100%").Attr("height", "100%").Attr("fill", "#ffffff").Close();
  return out;
}

// A clip path id that is the same for the same rectangle, so two pictures inlined in one HTML page
// never pick up each other's (different) clip rectangle.
std::string ClipId(const Frame& f) {
  return "strokelab-clip-" + Num(f.left, 0) + "-" + Num(f.top, 0) + "-" + Num(f.width, 0) + "-" + Num(f.height, 0);
}

std::string ClipPathDef(const Frame& f) {
  return "<defs>" + Tag("clipPath").Attr("id", ClipId(f)).Open() +
         Tag("rect").Attr("x", f.left).Attr("y", f.top).Attr("width", f.width).Attr("height", f.height).Close() +
         "</clipPath></defs>\n";
}

// Light gridlines at the major ticks (and fainter ones at minor log ticks).
std::string Grid(const Frame& f, const Scale& xs, const AxisTicks& xt, const Scale& ys, const AxisTicks& yt) {
  const auto lines = [&](const std::vector<double>& xv, const std::vector<double>& yv) {
    std::string d;
    for (double v : xv) d += "M" + Num(xs(v), 1) + " " + Num(f.top, 1) + "V" + Num(f.bottom(), 1);
    for (double v : yv) d += "M" + Num(f.left, 1) + " " + Num(ys(v), 1) + "H" + Num(f.right(), 1);
    return d;
  };
  std::string out = "<g class=\"grid\" fill=\"none\" shape-rendering=\"crispEdges\">\n";  // sharp 1 px lines
  // Minor gridlines only where they stay apart; dense ones would grey the whole plot.
  const auto sparse = [](const std::vector<double>& minor, const Scale& s) {
    return s.PxPerUnit() >= kMinPxPerDecadeForMinorTicks ? minor : std::vector<double>{};
  };
  const std::string minor = lines(sparse(xt.minor, xs), sparse(yt.minor, ys));
  if (!minor.empty())
    out += Tag("path").Attr("d", minor).Attr("stroke", kMinorGridColor).Attr("stroke-width", 1).Close();
  out += Tag("path").Attr("d", lines(xt.major, yt.major)).Attr("stroke", kGridColor).Attr("stroke-width", 1).Close();
  return out + "</g>\n";
}

// Box, outward ticks, tick labels, axis labels and title, drawn over the data.
std::string AxesDecoration(const Frame& f, const Axes& axes, const Scale& xs, const AxisTicks& xt, const Scale& ys,
                           const AxisTicks& yt) {
  std::string out;
  out += Tag("rect")
             .Attr("class", "frame")
             .Attr("x", f.left)
             .Attr("y", f.top)
             .Attr("width", f.width)
             .Attr("height", f.height)
             .Attr("fill", "none")
             .Attr("stroke", kFrameColor)
             .Attr("stroke-width", 1)
             .Close();

  // x axis
  std::string d;
  for (double v : xt.major) d += "M" + Num(xs(v), 1) + " " + Num(f.bottom(), 1) + "v" + Num(kTickLenPx);
  for (double v : xt.minor) d += "M" + Num(xs(v), 1) + " " + Num(f.bottom(), 1) + "v" + Num(kMinorTickLenPx);
  out += "<g class=\"x-axis\">\n";
  out += Tag("path").Attr("d", d).Attr("stroke", kFrameColor).Attr("fill", "none").Close();
  const double x_label_baseline = f.bottom() + kTickLenPx + kTickLabelGapPx + 0.8 * kTickFontPx;
  for (size_t i = 0; i < xt.major.size(); ++i) {
    out += Text(xs(xt.major[i]), x_label_baseline, xt.labels[i], kTickFontPx, "middle");
  }
  out += "</g>\n";

  // y axis
  d.clear();
  for (double v : yt.major) d += "M" + Num(f.left, 1) + " " + Num(ys(v), 1) + "h" + Num(-kTickLenPx);
  for (double v : yt.minor) d += "M" + Num(f.left, 1) + " " + Num(ys(v), 1) + "h" + Num(-kMinorTickLenPx);
  out += "<g class=\"y-axis\">\n";
  out += Tag("path").Attr("d", d).Attr("stroke", kFrameColor).Attr("fill", "none").Close();
  for (size_t i = 0; i < yt.major.size(); ++i) {
    out += Text(f.left - kTickLenPx - kTickLabelGapPx, ys(yt.major[i]) + 0.35 * kTickFontPx, yt.labels[i], kTickFontPx,
                "end");
  }
  out += "</g>\n";

  const double center_x = f.left + f.width / 2, center_y = f.top + f.height / 2;
  const double page_right = axes.width_px - kOuterPadPx, page_bottom = axes.height_px - kOuterPadPx;
  if (!axes.x_label.empty()) {
    const PlacedLine p = FitLine(axes.x_label, kLabelFontPx, center_x, kOuterPadPx, page_right);
    out += Text(p.center, x_label_baseline + 10 + kLabelFontPx, axes.x_label, p.font_px, "middle", "x-label");
  }
  if (!axes.y_label.empty()) {
    const PlacedLine p = FitLine(axes.y_label, kLabelFontPx, center_y, kOuterPadPx, page_bottom);
    const double x = kOuterPadPx + 0.8 * kLabelFontPx;
    out += Tag("text")
               .Attr("class", "y-label")
               .Attr("x", x)
               .Attr("y", p.center)
               .Attr("font-size", p.font_px)
               .Attr("text-anchor", "middle")
               .Attr("transform", "rotate(-90 " + Num(x) + " " + Num(p.center) + ")")
               .Wrap(axes.y_label);
  }
  if (!axes.title.empty()) {
    const PlacedLine p = FitLine(axes.title, kTitleFontPx, center_x, kOuterPadPx, page_right, kBoldWidthFactor);
    out += Tag("text")
               .Attr("class", "title")
               .Attr("x", p.center)
               .Attr("y", kOuterPadPx + 0.8 * kTitleFontPx)
               .Attr("font-size", p.font_px)
               .Attr("font-weight", "bold")
               .Attr("text-anchor", "middle")
               .Wrap(axes.title);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Series.

// Runs of consecutive drawable points in pixels; a point that cannot be drawn (non-finite, or
// non-positive on a log axis) ends a run, so the line shows a gap there.
std::vector<std::vector<Pt>> PixelRuns(const Series& s, const Scale& xs, const Scale& ys) {
  std::vector<std::vector<Pt>> runs(1);
  for (size_t i = 0; i < s.x.size(); ++i) {
    if (xs.Accepts(s.x[i]) && ys.Accepts(s.y[i])) {
      runs.back().push_back({xs(s.x[i]), ys(s.y[i])});
    } else if (!runs.back().empty()) {
      runs.emplace_back();
    }
  }
  if (runs.back().empty()) runs.pop_back();
  return runs;
}

// Keeps, for each stretch of consecutive points in one pixel column, the first, lowest, highest
// and last point (in their original order): the drawn line is unchanged at screen resolution and
// single-sample spikes stay visible.
std::vector<Pt> DecimatePerColumn(const std::vector<Pt>& run) {
  std::vector<Pt> out;
  size_t begin = 0;
  while (begin < run.size()) {
    const double column = std::floor(run[begin].x);
    size_t end = begin, lowest = begin, highest = begin;
    while (end < run.size() && std::floor(run[end].x) == column) {
      if (run[end].y < run[lowest].y) lowest = end;
      if (run[end].y > run[highest].y) highest = end;
      ++end;
    }
    std::array<size_t, 4> keep = {begin, lowest, highest, end - 1};
    std::sort(keep.begin(), keep.end());
    for (size_t k = 0; k < keep.size(); ++k) {
      if (k == 0 || keep[k] != keep[k - 1]) out.push_back(run[keep[k]]);
    }
    begin = end;
  }
  return out;
}

std::string PointList(const std::vector<Pt>& run) {
  std::string p;
  p.reserve(run.size() * 12);
  for (const Pt& q : run) {
    if (!p.empty()) p += ' ';
    p += Num(q.x, 1);
    p += ',';
    p += Num(q.y, 1);
  }
  return p;
}

std::string DashArray(double line_width) {
  return Num(4 * std::max(1.0, line_width)) + " " + Num(2.5 * std::max(1.0, line_width));
}

double MarkerRadius(const Series& s) { return std::max(2.5, 1.6 * s.line_width); }

// Colour of each series: its own, or the next palette entry.
std::vector<std::string> SeriesColors(const std::vector<Series>& series) {
  std::vector<std::string> colors;
  size_t next = 0;
  for (const Series& s : series) colors.push_back(s.color.empty() ? kPalette[next++ % kPalette.size()] : s.color);
  return colors;
}

// One series as polylines (one per run) and markers. `halo` draws a wider white line beneath, so
// curves stay visible over a heat map of any colour.
std::string SeriesSvg(const Series& s, const std::string& color, const Scale& xs, const Scale& ys, double plot_width_px,
                      bool halo) {
  std::vector<std::vector<Pt>> runs = PixelRuns(s, xs, ys);
  if (static_cast<double>(s.x.size()) > kDecimateAbovePointsPerPx * plot_width_px) {
    for (auto& run : runs) run = DecimatePerColumn(run);
  }
  std::string out = "<g class=\"series\">\n";
  if (s.line) {
    for (const auto& run : runs) {
      if (run.size() < 2) continue;
      const std::string points = PointList(run);
      if (halo) {
        out += Tag("polyline")
                   .Attr("points", points)
                   .Attr("fill", "none")
                   .Attr("stroke", "#ffffff")
                   .Attr("stroke-opacity", 0.7)
                   .Attr("stroke-width", s.line_width + 2.5)
                   .Attr("stroke-linejoin", "round")
                   .Close();
      }
      Tag line("polyline");
      line.Attr("points", points)
          .Attr("fill", "none")
          .Attr("stroke", color)
          .Attr("stroke-width", s.line_width)
          .Attr("stroke-linejoin", "round")
          .Attr("stroke-linecap", s.dashed ? "butt" : "round");
      if (s.dashed) line.Attr("stroke-dasharray", DashArray(s.line_width));
      out += line.Close();
    }
  }
  // Markers also mark isolated points, which a line alone would not show.
  if (s.markers) {
    const double r = MarkerRadius(s);
    for (const auto& run : runs) {
      for (const Pt& q : run) {
        out += Tag("circle").Attr("cx", q.x).Attr("cy", q.y).Attr("r", r).Attr("fill", color).Close();
      }
    }
  }
  return out + "</g>\n";
}

std::string AllSeries(const std::vector<Series>& series, const Frame& f, const Scale& xs, const Scale& ys, bool halo) {
  const std::vector<std::string> colors = SeriesColors(series);
  std::string out = Tag("g").Attr("class", "data").Attr("clip-path", "url(#" + ClipId(f) + ")").Open() + "\n";
  for (size_t i = 0; i < series.size(); ++i) out += SeriesSvg(series[i], colors[i], xs, ys, f.width, halo);
  return out + "</g>\n";
}

// Legend in the top-right corner of the plot area, for series with a label. `cased` outlines the
// line samples in grey, as overlays on a heat map may be white.
std::string Legend(const std::vector<Series>& series, const Frame& f, bool cased) {
  const std::vector<std::string> colors = SeriesColors(series);
  std::vector<size_t> shown;
  double text_width = 0;
  for (size_t i = 0; i < series.size(); ++i) {
    if (series[i].label.empty()) continue;
    shown.push_back(i);
    text_width = std::max(text_width, TextWidthPx(series[i].label, kLegendFontPx));
  }
  if (shown.empty()) return "";

  constexpr double kPad = 8, kRow = 18, kSample = 26, kSampleGap = 7, kInset = 8;
  const double width = kPad + kSample + kSampleGap + text_width + kPad;
  const double height = 2 * kPad + kRow * static_cast<double>(shown.size()) - 4;
  const double x0 = f.right() - kInset - width, y0 = f.top + kInset;

  std::string out = "<g class=\"legend\">\n";
  out += Tag("rect")
             .Attr("x", x0)
             .Attr("y", y0)
             .Attr("width", width)
             .Attr("height", height)
             .Attr("rx", 3)
             .Attr("fill", "#ffffff")
             .Attr("fill-opacity", 0.85)
             .Attr("stroke", "#cccccc")
             .Close();
  for (size_t row = 0; row < shown.size(); ++row) {
    const Series& s = series[shown[row]];
    const std::string& color = colors[shown[row]];
    const double cy = y0 + kPad + 7 + kRow * static_cast<double>(row);
    const double sx = x0 + kPad;
    if (s.line && cased) {
      out += Tag("line")
                 .Attr("x1", sx)
                 .Attr("y1", cy)
                 .Attr("x2", sx + kSample)
                 .Attr("y2", cy)
                 .Attr("stroke", "#8c8c8c")
                 .Attr("stroke-width", s.line_width + 2)
                 .Close();
    }
    if (s.line) {
      Tag line("line");
      line.Attr("x1", sx).Attr("y1", cy).Attr("x2", sx + kSample).Attr("y2", cy);
      line.Attr("stroke", color).Attr("stroke-width", s.line_width);
      if (s.dashed) line.Attr("stroke-dasharray", DashArray(s.line_width));
      out += line.Close();
    }
    if (s.markers || !s.line) {
      out += Tag("circle")
                 .Attr("cx", sx + kSample / 2)
                 .Attr("cy", cy)
                 .Attr("r", MarkerRadius(s))
                 .Attr("fill", color)
                 .Close();
    }
    out += Text(sx + kSample + kSampleGap, cy + 0.35 * kLegendFontPx, s.label, kLegendFontPx, "start");
  }
  return out + "</g>\n";
}

std::optional<Range> SeriesExtent(const std::vector<Series>& series, bool x_axis, bool log) {
  std::optional<Range> r;
  for (const Series& s : series) {
    const std::vector<double>& v = x_axis ? s.x : s.y;
    const std::vector<double>& other = x_axis ? s.y : s.x;
    for (size_t i = 0; i < v.size(); ++i) {
      // A point whose other coordinate is unusable is not drawn, so it does not widen the axis.
      if (std::isfinite(v[i]) && (!log || v[i] > 0) && std::isfinite(other[i])) Extend(r, v[i]);
    }
  }
  return r;
}

// ---------------------------------------------------------------------------------------------
// Heat maps.

std::string Hex(const std::array<double, 3>& rgb) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "#%02x%02x%02x", static_cast<int>(std::lround(rgb[0])),
                static_cast<int>(std::lround(rgb[1])), static_cast<int>(std::lround(rgb[2])));
  return buf;
}

// viridis at t in [0, 1].
std::string Viridis(double t) {
  const double s = std::clamp(t, 0.0, 1.0) * (kViridis.size() - 1);
  const size_t k = std::min(static_cast<size_t>(s), kViridis.size() - 2);
  const double f = s - static_cast<double>(k);
  std::array<double, 3> rgb;
  for (int c = 0; c < 3; ++c) rgb[c] = kViridis[k][c] + f * (kViridis[k + 1][c] - kViridis[k][c]);
  return Hex(rgb);
}

void CheckGrid(const std::vector<double>& v, const char* name, bool log) {
  if (v.empty()) throw std::invalid_argument(std::string("HeatMap.") + name + ": is empty");
  for (size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i]) || (log && v[i] <= 0)) {
      throw std::invalid_argument(std::string("HeatMap.") + name + "[" + std::to_string(i) + "]: must be finite" +
                                  (log ? " and positive on a log axis" : ""));
    }
    if (i > 0 && !(v[i] > v[i - 1])) {
      throw std::invalid_argument(std::string("HeatMap.") + name + ": must be strictly ascending (at index " +
                                  std::to_string(i) + ")");
    }
  }
}

void CheckHeatMap(const HeatMap& map, const Axes& axes) {
  CheckGrid(map.x, "x", axes.log_x);
  CheckGrid(map.y, "y", axes.log_y);
  if (map.z.size() != map.y.size()) {
    throw std::invalid_argument("HeatMap.z: has " + std::to_string(map.z.size()) + " rows but y has " +
                                std::to_string(map.y.size()) + " values");
  }
  for (size_t iy = 0; iy < map.z.size(); ++iy) {
    if (map.z[iy].size() != map.x.size()) {
      throw std::invalid_argument("HeatMap.z[" + std::to_string(iy) + "]: has " + std::to_string(map.z[iy].size()) +
                                  " values but x has " + std::to_string(map.x.size()));
    }
  }
}

// Cell edges halfway between grid values, measured on the axis (so geometric means on a log axis);
// the outer cells are as wide as their neighbours.
std::vector<double> CellEdges(const std::vector<double>& v, bool log) {
  std::vector<double> t(v.size());
  for (size_t i = 0; i < v.size(); ++i) t[i] = log ? std::log10(v[i]) : v[i];
  std::vector<double> e(v.size() + 1);
  if (v.size() == 1) {
    e = {t[0] - 0.5, t[0] + 0.5};  // a single row or column: one unit (one decade on a log axis)
  } else {
    for (size_t i = 1; i < t.size(); ++i) e[i] = 0.5 * (t[i - 1] + t[i]);
    e.front() = t.front() - (e[1] - t.front());
    e.back() = t.back() + (t.back() - e[e.size() - 2]);
  }
  if (log) {
    for (double& x : e) x = std::pow(10.0, x);
  }
  return e;
}

// What a z value is drawn with: a colour on the colour bar, or nothing (NaN, non-positive on log_z).
struct ColorScale {
  Range range;
  bool log;
  bool Accepts(double z) const { return std::isfinite(z) && (!log || z > 0); }
  double T(double z) const { return log ? std::log10(z) : z; }
  std::string operator()(double z) const { return Viridis((T(z) - T(range.lo)) / (T(range.hi) - T(range.lo))); }
};

ColorScale MakeColorScale(const HeatMap& map) {
  std::optional<Range> r;
  for (const auto& row : map.z) {
    for (double z : row) {
      if (std::isfinite(z) && (!map.log_z || z > 0)) Extend(r, z);
    }
  }
  return {ResolveRange(kNaN, kNaN, r, map.log_z, Fit::kExact, 1, 1), map.log_z};
}

// Pixel positions of cell edges, rounded as written so that neighbouring cells share an edge exactly.
std::vector<double> EdgePixels(const std::vector<double>& edges, const Scale& s) {
  std::vector<double> px;
  for (double e : edges) px.push_back(std::round(s(e) * 10) / 10);
  return px;
}

std::string Cells(const HeatMap& map, const ColorScale& color, const Scale& xs, const Scale& ys, const Frame& f) {
  const std::vector<double> x_px = EdgePixels(CellEdges(map.x, xs.log), xs);
  const std::vector<double> y_px = EdgePixels(CellEdges(map.y, ys.log), ys);
  // crispEdges: neighbouring cells meet without anti-aliased hairline seams.
  std::string out = Tag("g")
                        .Attr("class", "cells")
                        .Attr("clip-path", "url(#" + ClipId(f) + ")")
                        .Attr("shape-rendering", "crispEdges")
                        .Open() +
                    "\n";
  for (size_t iy = 0; iy < map.y.size(); ++iy) {
    for (size_t ix = 0; ix < map.x.size(); ++ix) {
      const double z = map.z[iy][ix];
      if (!color.Accepts(z)) continue;  // no data: transparent
      out += "<rect x=\"" + Num(x_px[ix], 1) + "\" y=\"" + Num(y_px[iy + 1], 1) + "\" width=\"" +
             Num(x_px[ix + 1] - x_px[ix], 1) + "\" height=\"" + Num(y_px[iy] - y_px[iy + 1], 1) + "\" fill=\"" +
             color(z) + "\"/>\n";
    }
  }
  return out + "</g>\n";
}

constexpr double kColorBarGapPx = 22, kColorBarWidthPx = 14;

double ColorBarWidth(const AxisTicks& z_ticks, const std::string& z_label) {
  return kColorBarGapPx + kColorBarWidthPx + kTickLenPx + kTickLabelGapPx + z_ticks.MaxLabelWidthPx() +
         (z_label.empty() ? 0 : 10 + kLabelFontPx) + kOuterPadPx;
}

std::string ColorBar(const Frame& f, const Scale& zs, const AxisTicks& zt, const std::string& z_label) {
  const double x0 = f.right() + kColorBarGapPx;
  std::string out = "<g class=\"colorbar\">\n";
  // The gradient runs bottom (low) to top (high); on log_z the colour is linear in log10(z), as is the bar.
  out += "<defs>" + Tag("linearGradient")
                        .Attr("id", "strokelab-viridis")
                        .Attr("x1", 0)
                        .Attr("y1", 1)
                        .Attr("x2", 0)
                        .Attr("y2", 0)
                        .Open();
  for (size_t k = 0; k < kViridis.size(); ++k) {
    const double t = static_cast<double>(k) / (kViridis.size() - 1);
    out += Tag("stop").Attr("offset", t).Attr("stop-color", Viridis(t)).Close();
  }
  out += "</linearGradient></defs>\n";
  out += Tag("rect")
             .Attr("x", x0)
             .Attr("y", f.top)
             .Attr("width", kColorBarWidthPx)
             .Attr("height", f.height)
             .Attr("fill", "url(#strokelab-viridis)")
             .Attr("stroke", kFrameColor)
             .Attr("stroke-width", 1)
             .Close();
  const double bar_right = x0 + kColorBarWidthPx;
  std::string d;
  for (double v : zt.major) d += "M" + Num(bar_right, 1) + " " + Num(zs(v), 1) + "h" + Num(kTickLenPx);
  for (double v : zt.minor) d += "M" + Num(bar_right, 1) + " " + Num(zs(v), 1) + "h" + Num(kMinorTickLenPx);
  out += Tag("path").Attr("d", d).Attr("stroke", kFrameColor).Attr("fill", "none").Close();
  for (size_t i = 0; i < zt.major.size(); ++i) {
    out += Text(bar_right + kTickLenPx + kTickLabelGapPx, zs(zt.major[i]) + 0.35 * kTickFontPx, zt.labels[i],
                kTickFontPx, "start");
  }
  if (!z_label.empty()) {
    const double x = bar_right + kTickLenPx + kTickLabelGapPx + zt.MaxLabelWidthPx() + 10 + 0.2 * kLabelFontPx;
    const double y = f.top + f.height / 2;
    out += Tag("text")
               .Attr("class", "z-label")
               .Attr("x", x)
               .Attr("y", y)
               .Attr("font-size", kLabelFontPx)
               .Attr("text-anchor", "middle")
               .Attr("transform", "rotate(-90 " + Num(x) + " " + Num(y) + ")")
               .Wrap(z_label);
  }
  return out + "</g>\n";
}

// ---------------------------------------------------------------------------------------------
// Shared plot assembly.

double PlotHeight(const Axes& axes) { return axes.height_px - TopMargin(axes) - BottomMargin(axes); }

// Axis scales and ticks. The plot area's height is fixed by the margins for text; its left edge
// follows from the widest y tick label.
struct PlotGeometry {
  Frame frame;
  Scale xs, ys;
  AxisTicks xt, yt;
};

constexpr double kXTickSpacingPx = 60, kYTickSpacingPx = 40;  // least distance between major ticks

PlotGeometry Layout(const Axes& axes, std::optional<Range> x_data, std::optional<Range> y_data, Fit x_fit, Fit y_fit,
                    double right_margin_px) {
  PlotGeometry g;
  const double top = TopMargin(axes), height = PlotHeight(axes);
  g.ys.log = axes.log_y;
  g.ys.range = ResolveRange(axes.y_min, axes.y_max, y_data, axes.log_y, y_fit, height, kYTickSpacingPx);
  g.ys.px_lo = top + height;
  g.ys.px_hi = top;
  g.yt = MakeTicks(g.ys, kYTickSpacingPx, false);

  const double left = LeftMargin(axes, g.yt);
  const double width = std::max(40.0, axes.width_px - left - right_margin_px);
  g.xs.log = axes.log_x;
  g.xs.range = ResolveRange(axes.x_min, axes.x_max, x_data, axes.log_x, x_fit, width, kXTickSpacingPx);
  g.xs.px_lo = left;
  g.xs.px_hi = left + width;
  g.xt = MakeTicks(g.xs, kXTickSpacingPx, true);
  g.frame = {left, top, width, height};
  return g;
}

}  // namespace

std::string EscapeXml(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\t':
      case '\n':
      case '\r':
        out += c;
        break;
      default:
        // Control characters are not allowed in XML 1.0 at all, even escaped: drop them.
        if (static_cast<unsigned char>(c) >= 0x20) out += c;
    }
  }
  return out;
}

std::string LinePlot(const std::vector<Series>& series, const Axes& axes) {
  CheckAxes(axes);
  CheckSeries(series, "series");
  const PlotGeometry g = Layout(axes, SeriesExtent(series, true, axes.log_x), SeriesExtent(series, false, axes.log_y),
                                Fit::kSnapToTicks, Fit::kPadToHalfTick, kRightMarginPx);

  std::string out = OpenSvg(axes);
  out += ClipPathDef(g.frame);
  out += Grid(g.frame, g.xs, g.xt, g.ys, g.yt);
  out += AllSeries(series, g.frame, g.xs, g.ys, /*halo=*/false);
  out += AxesDecoration(g.frame, axes, g.xs, g.xt, g.ys, g.yt);
  out += Legend(series, g.frame, /*cased=*/false);
  return out + "</svg>\n";
}

std::string HeatMapPlot(const HeatMap& map, const std::vector<Series>& overlays, const Axes& axes) {
  CheckAxes(axes);
  CheckHeatMap(map, axes);
  CheckSeries(overlays, "overlays");
  const ColorScale color = MakeColorScale(map);
  const std::vector<double> xe = CellEdges(map.x, axes.log_x), ye = CellEdges(map.y, axes.log_y);

  // The colour bar spans the plot's height; its tick labels set the right margin.
  const Scale zs{color.range, map.log_z, TopMargin(axes) + PlotHeight(axes), TopMargin(axes)};
  const AxisTicks zt = MakeTicks(zs, kYTickSpacingPx, false);
  const PlotGeometry g = Layout(axes, Range{xe.front(), xe.back()}, Range{ye.front(), ye.back()}, Fit::kExact,
                                Fit::kExact, ColorBarWidth(zt, map.z_label));

  std::string out = OpenSvg(axes);
  out += ClipPathDef(g.frame);
  out += Cells(map, color, g.xs, g.ys, g.frame);
  out += AllSeries(overlays, g.frame, g.xs, g.ys, /*halo=*/true);
  out += AxesDecoration(g.frame, axes, g.xs, g.xt, g.ys, g.yt);
  out += ColorBar(g.frame, zs, zt, map.z_label);
  out += Legend(overlays, g.frame, /*cased=*/true);
  return out + "</svg>\n";
}

}  // namespace strokelab::plot
