// The legend: a box in the top-right corner of the plot area with a sample of each labelled
// series (its line, dashes and marker) and its label.
#include <algorithm>
#include <string>
#include <vector>

#include "strokelab/plot/svg_plot.h"
#include "svg_plot_internal.h"

namespace strokelab::plot::svg_internal {

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

}  // namespace strokelab::plot::svg_internal
