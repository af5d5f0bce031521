// Realistic sample pictures, each checked for well-formedness; written to STROKELAB_PLOT_DEMO_DIR
// (or the test's temporary folder) for looking at.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "strokelab/plot/svg_plot.h"
#include "svg_test_util.h"

namespace strokelab::plot {
namespace {

using namespace svg_test;

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
