// SVG pictures for reports, the CLI's figure folders and the web page: line plots with axes,
// ticks, legends, log axes; and heat maps with overlaid curves. Output is a self-contained SVG string.
#pragma once

#include <string>
#include <vector>

namespace strokelab::plot {

struct Series {
  std::string label;          // legend text; empty: not in the legend
  std::vector<double> x, y;   // same length; non-finite points break the line
  std::string color;          // CSS color; empty: next in the default palette
  double line_width = 1.5;
  bool markers = false;       // draw a dot at each point
  bool line = true;           // draw the connecting polyline
  bool dashed = false;
};

struct Axes {
  std::string title;
  std::string x_label, y_label;
  bool log_x = false, log_y = false;
  // Ranges: NaN means "from the data" (with a small margin, rounded to nice ticks).
  double x_min = 0.0 / 0.0, x_max = 0.0 / 0.0, y_min = 0.0 / 0.0, y_max = 0.0 / 0.0;
  int width_px = 720, height_px = 440;
};

std::string LinePlot(const std::vector<Series>& series, const Axes& axes);

// A colour bar beside a line plot whose curves are coloured by a value (one FRF per drive
// amplitude): the heat maps' sequential colour map (viridis) over [min, max], so that many curves
// stay told apart where a palette would repeat and a legend would cover them.
struct ColorBar {
  std::string label;
  double min = 0.0, max = 1.0;  // finite, min < max (positive on a log scale)
  bool log = false;
};
// The colour of `value` on the bar's colour map (values beyond the range take the end colour).
std::string ColorBarColor(const ColorBar& bar, double value);
// LinePlot with `bar` on the right; series colour themselves (ColorBarColor) and only labelled
// series enter the legend.
std::string LinePlot(const std::vector<Series>& series, const Axes& axes, const ColorBar& bar);

// A heat map of z over a rectilinear grid (x ascending, y ascending; z[iy][ix], NaN: no data) with
// a colour bar labelled `z_label`, and curves drawn on top of it (threshold, jump boundaries).
// Spacing may vary (log-spaced frequencies): cell edges lie midway between grid values as the
// axis shows them (geometric means on a log axis). With log_z, z <= 0 is left empty like NaN.
struct HeatMap {
  std::vector<double> x, y;
  std::vector<std::vector<double>> z;
  std::string z_label;
  bool log_z = false;
  // The colour bar's range: NaN means "from the data". Fixed, it lets maps drawn side by side share
  // one scale; z beyond it takes the end colour.
  double z_min = 0.0 / 0.0, z_max = 0.0 / 0.0;
};
std::string HeatMapPlot(const HeatMap& map, const std::vector<Series>& overlays, const Axes& axes);

// Escapes &, <, >, " for use in SVG text and attributes; drops control characters XML 1.0 forbids.
std::string EscapeXml(const std::string& text);

}  // namespace strokelab::plot
