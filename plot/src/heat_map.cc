// Heat maps (HeatMapPlot, public): the grid's cells coloured by z on the viridis colour map, a
// colour bar with its ticks and label, and curves drawn over them.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "strokelab/plot/svg_plot.h"
#include "svg_plot_internal.h"

namespace strokelab::plot::svg_internal {
namespace {

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

std::string Hex(const std::array<double, 3>& rgb) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "#%02x%02x%02x", static_cast<int>(std::lround(rgb[0])),
                static_cast<int>(std::lround(rgb[1])), static_cast<int>(std::lround(rgb[2])));
  return buf;
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
  for (const auto& [limit, name] : {std::pair{map.z_min, "z_min"}, std::pair{map.z_max, "z_max"}}) {
    if (!std::isnan(limit) && (!std::isfinite(limit) || (map.log_z && limit <= 0)))
      throw std::invalid_argument(std::string("HeatMap.") + name + ": must be finite" +
                                  (map.log_z ? " and positive with log_z" : "") + " (or NaN: from the data)");
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
  return {ResolveRange(map.z_min, map.z_max, r, map.log_z, Fit::kExact, 1, 1), map.log_z};
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

}  // namespace

std::string Viridis(double t) {
  const double s = std::clamp(t, 0.0, 1.0) * (kViridis.size() - 1);
  const size_t k = std::min(static_cast<size_t>(s), kViridis.size() - 2);
  const double f = s - static_cast<double>(k);
  std::array<double, 3> rgb;
  for (int c = 0; c < 3; ++c) rgb[c] = kViridis[k][c] + f * (kViridis[k + 1][c] - kViridis[k][c]);
  return Hex(rgb);
}

double ColorBarWidth(const AxisTicks& z_ticks, const std::string& z_label) {
  return kColorBarGapPx + kColorBarWidthPx + kTickLenPx + kTickLabelGapPx + z_ticks.MaxLabelWidthPx() +
         (z_label.empty() ? 0 : 10 + kLabelFontPx) + kOuterPadPx;
}

std::string ColorBarSvg(const Frame& f, const Scale& zs, const AxisTicks& zt, const std::string& z_label) {
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

}  // namespace strokelab::plot::svg_internal

namespace strokelab::plot {

std::string HeatMapPlot(const HeatMap& map, const std::vector<Series>& overlays, const Axes& axes) {
  using namespace svg_internal;
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
  out += ColorBarSvg(g.frame, zs, zt, map.z_label);
  out += Legend(overlays, g.frame, /*cased=*/true);
  return out + "</svg>\n";
}

}  // namespace strokelab::plot
