// The frame every picture shares: checks of the axes, the layout of the plot area (margins for the
// text around it, scales and ticks), the <svg> element, the clip path, the grid, and the axes with
// their ticks, labels and title.
#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "strokelab/plot/svg_plot.h"
#include "svg_plot_internal.h"

namespace strokelab::plot::svg_internal {
namespace {

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

double BottomMargin(const Axes& axes) {
  return kTickLenPx + kTickLabelGapPx + kTickFontPx + (axes.x_label.empty() ? 0 : 10 + kLabelFontPx) + kOuterPadPx + 4;
}

double LeftMargin(const Axes& axes, const AxisTicks& y_ticks) {
  return kOuterPadPx + (axes.y_label.empty() ? 0 : kLabelFontPx + 10) + y_ticks.MaxLabelWidthPx() + kTickLabelGapPx +
         2 + kTickLenPx;
}

}  // namespace

double TopMargin(const Axes& axes) { return kOuterPadPx + (axes.title.empty() ? 6 : kTitleFontPx + 12); }

double PlotHeight(const Axes& axes) { return axes.height_px - TopMargin(axes) - BottomMargin(axes); }

void CheckAxes(const Axes& axes) {
  if (axes.width_px < 200)
    throw std::invalid_argument("Axes.width_px: must be at least 200 (got " + std::to_string(axes.width_px) + ")");
  if (axes.height_px < 150)
    throw std::invalid_argument("Axes.height_px: must be at least 150 (got " + std::to_string(axes.height_px) + ")");
  CheckLimits("x_min", axes.x_min, "x_max", axes.x_max, axes.log_x);
  CheckLimits("y_min", axes.y_min, "y_max", axes.y_max, axes.log_y);
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

std::string ClipId(const Frame& f) {
  return "strokelab-clip-" + Num(f.left, 0) + "-" + Num(f.top, 0) + "-" + Num(f.width, 0) + "-" + Num(f.height, 0);
}

std::string ClipPathDef(const Frame& f) {
  return "<defs>" + Tag("clipPath").Attr("id", ClipId(f)).Open() +
         Tag("rect").Attr("x", f.left).Attr("y", f.top).Attr("width", f.width).Attr("height", f.height).Close() +
         "</clipPath></defs>\n";
}

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

}  // namespace strokelab::plot::svg_internal
