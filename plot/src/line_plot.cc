// Line plots (LinePlot, public): each series as polylines broken at points that cannot be drawn,
// decimated per pixel column when dense, with markers; and the series' colours, dashes and marker
// sizes, which the legend shares.
#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "strokelab/plot/svg_plot.h"
#include "svg_plot_internal.h"

namespace strokelab::plot::svg_internal {
namespace {

// A series with more points than this many per pixel column is decimated (min/max per column).
constexpr double kDecimateAbovePointsPerPx = 4.0;

struct Pt {
  double x, y;
};

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

}  // namespace

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

std::string DashArray(double line_width) {
  return Num(4 * std::max(1.0, line_width)) + " " + Num(2.5 * std::max(1.0, line_width));
}

double MarkerRadius(const Series& s) { return std::max(2.5, 1.6 * s.line_width); }

std::vector<std::string> SeriesColors(const std::vector<Series>& series) {
  std::vector<std::string> colors;
  size_t next = 0;
  for (const Series& s : series) colors.push_back(s.color.empty() ? kPalette[next++ % kPalette.size()] : s.color);
  return colors;
}

std::string AllSeries(const std::vector<Series>& series, const Frame& f, const Scale& xs, const Scale& ys, bool halo) {
  const std::vector<std::string> colors = SeriesColors(series);
  std::string out = Tag("g").Attr("class", "data").Attr("clip-path", "url(#" + ClipId(f) + ")").Open() + "\n";
  for (size_t i = 0; i < series.size(); ++i) out += SeriesSvg(series[i], colors[i], xs, ys, f.width, halo);
  return out + "</g>\n";
}

}  // namespace strokelab::plot::svg_internal

namespace strokelab::plot {

namespace {

// A line plot, with a colour bar on the right when `bar` is given.
std::string LinePlotWith(const std::vector<Series>& series, const Axes& axes, const ColorBar* bar) {
  using namespace svg_internal;
  CheckAxes(axes);
  CheckSeries(series, "series");
  std::optional<Scale> zs;
  AxisTicks zt;
  double right_margin_px = kRightMarginPx;
  if (bar) {
    zs = Scale{{bar->min, bar->max}, bar->log, TopMargin(axes) + PlotHeight(axes), TopMargin(axes)};
    zt = MakeTicks(*zs, kYTickSpacingPx, false);
    right_margin_px = std::max(right_margin_px, ColorBarWidth(zt, bar->label));
  }
  const PlotGeometry g = Layout(axes, SeriesExtent(series, true, axes.log_x), SeriesExtent(series, false, axes.log_y),
                                Fit::kSnapToTicks, Fit::kPadToHalfTick, right_margin_px);

  std::string out = OpenSvg(axes);
  out += ClipPathDef(g.frame);
  out += Grid(g.frame, g.xs, g.xt, g.ys, g.yt);
  out += AllSeries(series, g.frame, g.xs, g.ys, /*halo=*/false);
  out += AxesDecoration(g.frame, axes, g.xs, g.xt, g.ys, g.yt);
  if (bar) out += ColorBarSvg(g.frame, *zs, zt, bar->label);
  out += Legend(series, g.frame, /*cased=*/false);
  return out + "</svg>\n";
}

void CheckColorBar(const ColorBar& bar) {
  if (!std::isfinite(bar.min) || !std::isfinite(bar.max) || !(bar.min < bar.max))
    throw std::invalid_argument("ColorBar.max: min and max must be finite with min < max");
  if (bar.log && !(bar.min > 0)) throw std::invalid_argument("ColorBar.min: must be positive on a log scale");
}

}  // namespace

std::string LinePlot(const std::vector<Series>& series, const Axes& axes) {
  return LinePlotWith(series, axes, nullptr);
}

std::string LinePlot(const std::vector<Series>& series, const Axes& axes, const ColorBar& bar) {
  CheckColorBar(bar);
  return LinePlotWith(series, axes, &bar);
}

std::string ColorBarColor(const ColorBar& bar, double value) {
  CheckColorBar(bar);
  const auto t = [&](double v) { return bar.log ? std::log10(v) : v; };
  if (std::isnan(value) || (bar.log && !(value > 0))) return svg_internal::Viridis(0);
  return svg_internal::Viridis((t(value) - t(bar.min)) / (t(bar.max) - t(bar.min)));
}

}  // namespace strokelab::plot
