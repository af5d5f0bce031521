#include "format.h"
#include "strokelab/report/sweep_report.h"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <optional>
#include <stdexcept>

#include "strokelab/base/json_number.h"
#include "strokelab/model/model_json.h"
#include "strokelab/plot/svg_plot.h"
#include "strokelab/report/sweep_tables.h"

namespace strokelab::report {
namespace {

using nlohmann::json;

// The FRF families colour each amplitude on a sequential colour map with a colour bar (as the
// saturation map does), so that 26 amplitudes keep 26 colours and no legend covers the curves. One
// amplitude has no range to colour: it gets a legend entry instead.
constexpr const char* kSingleAmplitudeColor = "#0072B2";
std::optional<plot::ColorBar> AmplitudeBar(const SweepResult& r) {
  if (r.amplitude_v.size() < 2) return std::nullopt;
  return plot::ColorBar{"drive amplitude [V]", r.amplitude_v.front(), r.amplitude_v.back(), false};
}
std::string AmplitudeColor(const SweepResult& r, size_t i) {
  const std::optional<plot::ColorBar> bar = AmplitudeBar(r);
  return bar ? plot::ColorBarColor(*bar, r.amplitude_v[i]) : std::string(kSingleAmplitudeColor);
}

// A table's rows as a JSON array and as CSV, header first (sweep_tables.h).
template <class Row>
json RowsToJson(const std::vector<Row>& rows) {
  json list = json::array();
  for (const Row& row : rows) list.push_back(RowToJson(row));
  return list;
}


template <class Row>
std::string CsvText(const std::vector<Row>& rows) {
  std::string text = CsvHeader<Row>();
  for (const Row& row : rows) text += CsvLine(row);
  return text;
}

void WriteFile(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

// The index of `value` in `grid` (equal to within rounding), if it is on the grid.
std::optional<size_t> GridIndex(const std::vector<double>& grid, double value) {
  for (size_t i = 0; i < grid.size(); ++i) {
    if (std::abs(grid[i] - value) <= 1e-9 * std::max(1.0, std::abs(value))) return i;
  }
  return std::nullopt;
}

// The result's points arranged on the grid: [amplitude index][frequency index].
struct BranchGrid {
  static constexpr size_t kNone = static_cast<size_t>(-1);
  std::vector<std::vector<size_t>> up, down;  // index into result.points, or kNone
  std::vector<std::vector<size_t>> unstable;  // per amplitude: unstable orbits (any frequency)

  explicit BranchGrid(const SweepResult& r)
      : up(r.amplitude_v.size(), std::vector<size_t>(r.frequency_hz.size(), kNone)),
        down(up),
        unstable(r.amplitude_v.size()) {
    for (size_t k = 0; k < r.points.size(); ++k) {
      const SweepPoint& p = r.points[k];
      const auto ia = GridIndex(r.amplitude_v, p.amplitude_v);
      const auto jf = GridIndex(r.frequency_hz, p.frequency_hz);
      if (!ia || !jf) continue;  // off the grid: in the tables, not in the pictures
      if (p.branch == Branch::kUnstable || !p.stable) {
        unstable[*ia].push_back(k);
      } else {
        size_t& slot = (p.branch == Branch::kUp ? up : down)[*ia][*jf];
        if (slot == kNone) slot = k;
      }
    }
  }

  // The steady state an up- (or down-) sweep is on at a grid point. Where only one stable
  // response exists both sweeps follow it, so a missing branch falls back to the other one.
  size_t On(Branch branch, size_t ia, size_t jf) const {
    const size_t own = (branch == Branch::kUp ? up : down)[ia][jf];
    return own != kNone ? own : (branch == Branch::kUp ? down : up)[ia][jf];
  }
};

// "117 values, 5 .. 50 Hz, linear" (or geometric, or irregular spacing).
std::string AxisText(const std::vector<double>& v, const char* unit) {
  if (v.empty()) return "no values";
  if (v.size() == 1) return Format("1 value, %.6g %s", v[0], unit);
  bool linear = true, geometric = v.front() > 0;
  const double step = v[1] - v[0], ratio = v[1] / v[0];
  for (size_t i = 1; i < v.size(); ++i) {
    linear = linear && std::abs(v[i] - v[i - 1] - step) <= 1e-9 * std::abs(v.back());
    geometric = geometric && std::abs(v[i] / v[i - 1] - ratio) <= 1e-9 * ratio;
  }
  const char* spacing = linear ? "linear" : geometric ? "geometric" : "irregular";
  std::string text = Format("%zu values, %.6g .. %.6g %s, %s", v.size(), v.front(), v.back(), unit, spacing);
  if (geometric && !linear) text += Format(" (ratio %.6g)", ratio);
  return text;
}

std::string VoltsOrDash(double v) { return std::isfinite(v) ? Format("%8.4f V", v) : std::string("       - "); }

// Phase in rad, the unit of the tables' first_harmonic_phase_rad, on (-pi/2, 3 pi/2]: paper Eq. 3
// runs from pi (below resonance) to 0 (above) without wrapping there, and a response past pi stays
// continuous.
double PhaseRad(double rad) {
  constexpr double kPi = std::numbers::pi;
  while (rad <= -kPi / 2) rad += 2 * kPi;
  while (rad > 3 * kPi / 2) rad -= 2 * kPi;
  return rad;
}

plot::Series Curve(std::string label, std::string color) {
  plot::Series s;
  s.label = std::move(label);
  s.color = std::move(color);
  return s;
}

// One saturation map: SpikeFactor of one branch over the grid, with the thresholds and jumps on top.
std::string SaturationMap(const SweepResult& r, const BranchGrid& grid, Branch branch,
                          const SaturationMapStyle& style = {}) {
  plot::HeatMap map;
  map.x = r.frequency_hz;
  map.y = r.amplitude_v;
  map.log_z = true;
  map.z_min = style.spike_factor_min;
  map.z_max = style.spike_factor_max;
  map.z_label = "peak force / first-harmonic force amplitude";
  for (size_t ia = 0; ia < r.amplitude_v.size(); ++ia) {
    std::vector<double> row(r.frequency_hz.size(), NAN);
    for (size_t jf = 0; jf < r.frequency_hz.size(); ++jf) {
      if (const size_t k = grid.On(branch, ia, jf); k != BranchGrid::kNone) row[jf] = SpikeFactor(r.points[k]);
    }
    map.z.push_back(std::move(row));
  }
  std::vector<plot::Series> overlays;
  if (!r.saturation_threshold.empty()) {
    plot::Series grazing = Curve("grazing amplitude", "#ff3b30");
    plot::Series contact = Curve("lowest contacting amplitude", "#ffffff");
    contact.dashed = true;
    for (const SaturationThreshold& t : r.saturation_threshold) {
      grazing.x.push_back(t.frequency_hz);
      grazing.y.push_back(t.grazing_amplitude_v);
      contact.x.push_back(t.frequency_hz);
      contact.y.push_back(t.lowest_contact_amplitude_v);
    }
    grazing.line_width = contact.line_width = 2.0;
    overlays.push_back(std::move(contact));
    overlays.push_back(std::move(grazing));  // on top where the two coincide
  }
  if (!r.jump.empty()) {
    // Each bistable interval as a horizontal segment at its amplitude; NaN breaks between segments.
    plot::Series jumps = Curve("jump (bistable) interval", "#000000");
    jumps.markers = true;
    jumps.line_width = 2.5;
    for (const JumpInterval& j : r.jump) {
      jumps.x.insert(jumps.x.end(), {j.bistable_from_hz, j.bistable_to_hz, NAN});
      jumps.y.insert(jumps.y.end(), {j.amplitude_v, j.amplitude_v, NAN});
    }
    overlays.push_back(std::move(jumps));
  }
  plot::Axes axes;
  axes.title = !style.title.empty() ? style.title
                                    : std::string("Stroke saturation, ") + ToString(branch) +
                                          "-sweep branch: peak force / |C1(f)|";
  axes.x_label = "drive frequency [Hz]";
  axes.y_label = "drive amplitude [V]";
  axes.log_x = true;
  axes.width_px = 820;
  axes.height_px = 480;
  return plot::HeatMapPlot(map, overlays, axes);
}

// |H| or arg H [rad] of the steady state at point k.
double FrfValue(const SweepResult& r, size_t k, bool phase) {
  return phase ? PhaseRad(std::arg(r.points[k].h)) : std::abs(r.points[k].h);
}

// Where a sweep along `branch` jumps at amplitude index ia: each jump interval's end that the sweep
// leaves it by (the up-sweep at bistable_to_hz, the down-sweep at bistable_from_hz), drawn as a
// vertical segment at that frequency from the last grid point on the branch before the jump to the
// first after it, with a dot at each end.
void AddJumps(const SweepResult& r, const BranchGrid& grid, Branch branch, size_t ia, bool phase, plot::Series* jumps) {
  const std::vector<double>& f = r.frequency_hz;
  for (const JumpInterval& j : r.jump) {
    if (std::abs(j.amplitude_v - r.amplitude_v[ia]) > 1e-9 * std::max(1.0, std::abs(j.amplitude_v))) continue;
    const double at_hz = branch == Branch::kUp ? j.bistable_to_hz : j.bistable_from_hz;
    if (!std::isfinite(at_hz) || f.size() < 2 || at_hz <= f.front() || at_hz >= f.back()) continue;
    const size_t after = static_cast<size_t>(std::upper_bound(f.begin(), f.end(), at_hz) - f.begin());
    const size_t from = branch == Branch::kUp ? after - 1 : after, to = branch == Branch::kUp ? after : after - 1;
    const size_t k_from = grid.On(branch, ia, from), k_to = grid.On(branch, ia, to);
    if (k_from == BranchGrid::kNone || k_to == BranchGrid::kNone) continue;
    jumps->x.insert(jumps->x.end(), {at_hz, at_hz, NAN});
    jumps->y.insert(jumps->y.end(), {FrfValue(r, k_from, phase), FrfValue(r, k_to, phase), NAN});
  }
}

// |H| (or arg H) against frequency, one line per amplitude coloured by amplitude, for one branch;
// unstable orbits as dots; the jumps of the sweep along the branch marked.
std::vector<plot::Series> FrfSeries(const SweepResult& r, const BranchGrid& grid, Branch branch, bool phase,
                                    bool with_unstable) {
  std::vector<plot::Series> series;
  plot::Series jumps = Curve("jump of the " + std::string(ToString(branch)) + "-sweep", "#000000");
  jumps.markers = true;
  jumps.line_width = 1.2;
  jumps.dashed = true;
  for (size_t ia = 0; ia < r.amplitude_v.size(); ++ia) {
    plot::Series s = Curve(AmplitudeBar(r) ? "" : Format("%g V", r.amplitude_v[ia]), AmplitudeColor(r, ia));
    s.x = r.frequency_hz;
    for (size_t jf = 0; jf < r.frequency_hz.size(); ++jf) {
      const size_t k = grid.On(branch, ia, jf);
      s.y.push_back(k == BranchGrid::kNone ? NAN : FrfValue(r, k, phase));
    }
    series.push_back(std::move(s));
    AddJumps(r, grid, branch, ia, phase, &jumps);
  }
  bool any = false;
  if (with_unstable) {
    for (size_t ia = 0; ia < r.amplitude_v.size(); ++ia) {
      plot::Series dots = Curve("", AmplitudeColor(r, ia));
      dots.line = false;
      dots.markers = true;
      dots.line_width = 1.2;
      for (size_t k : grid.unstable[ia]) {
        dots.x.push_back(r.points[k].frequency_hz);
        dots.y.push_back(FrfValue(r, k, phase));
      }
      any = any || !dots.x.empty();
      series.push_back(std::move(dots));
    }
  }
  if (any) {
    plot::Series legend = Curve("dots: unstable orbits", "#7F7F7F");
    legend.line = false;
    legend.markers = true;
    legend.line_width = 1.2;
    series.push_back(std::move(legend));
  }
  if (!jumps.x.empty()) series.push_back(std::move(jumps));  // on top
  return series;
}

// A family of curves, with the amplitude colour bar when there are several amplitudes.
std::string FrfPlot(const SweepResult& r, const std::vector<plot::Series>& series, const plot::Axes& axes) {
  const std::optional<plot::ColorBar> bar = AmplitudeBar(r);
  return bar ? plot::LinePlot(series, axes, *bar) : plot::LinePlot(series, axes);
}

plot::Axes FrfAxes(std::string title, std::string y_label) {
  plot::Axes axes;
  axes.title = std::move(title);
  axes.x_label = "drive frequency [Hz]";
  axes.y_label = std::move(y_label);
  axes.log_x = true;
  return axes;
}

}  // namespace

double SpikeFactor(const SweepPoint& point) {
  if (!(point.first_harmonic_force_n > 0) || !std::isfinite(point.peak_force_n)) return NAN;
  return point.peak_force_n / point.first_harmonic_force_n;
}

json SweepToJson(const SweepResult& r, const ActuatorModel& model) {
  json points = RowsToJson(r.points), thresholds = RowsToJson(r.saturation_threshold), jumps = RowsToJson(r.jump);
  return {
      {"points", std::move(points)},
      {"saturation_threshold", std::move(thresholds)},
      {"jump", std::move(jumps)},
      {"grid", {{"frequency_hz", JsonNumbers(r.frequency_hz)}, {"amplitude_v", JsonNumbers(r.amplitude_v)}}},
      {"model", ModelToJson(model)},
      {"wall_time_s", JsonNumber(r.wall_time_s)},
      {"points_per_second", JsonNumber(r.points_per_second)},
  };
}

std::string SweepSummaryText(const SweepResult& r) {
  std::string text = "Steady-state sweep\n";
  text += "  frequency  " + AxisText(r.frequency_hz, "Hz") + "\n";
  text += "  amplitude  " + AxisText(r.amplitude_v, "V") + "\n";
  text += Format("  %zu grid points in %.3f s (%.4g grid points/s)\n", r.frequency_hz.size() * r.amplitude_v.size(),
                 r.wall_time_s, r.points_per_second);

  size_t counts[3] = {0, 0, 0}, multi_period = 0, aperiodic = 0, contacting = 0;
  for (const SweepPoint& p : r.points) {
    ++counts[static_cast<int>(p.branch)];
    if (p.branch == Branch::kUnstable) continue;
    if (p.period == 0) ++aperiodic;
    if (p.period > 1) ++multi_period;
    if (p.contacts_per_period > 0) ++contacting;
  }
  text += Format("  steady states: %zu up, %zu down, %zu unstable (up/down: %zu touching the stop, %zu with period > 1, "
                 "%zu aperiodic)\n",
                 counts[0], counts[1], counts[2], contacting, multi_period, aperiodic);

  text += "\nSaturation threshold (drive amplitude) per frequency:\n";
  const auto& th = r.saturation_threshold;
  if (th.empty()) {
    text += "  not computed\n";
  } else {
    text += "  frequency      grazing    lowest contacting\n";
    size_t lowest = th.size();
    for (size_t i = 0; i < th.size(); ++i) {
      if (std::isfinite(th[i].grazing_amplitude_v) &&
          (lowest == th.size() || th[i].grazing_amplitude_v < th[lowest].grazing_amplitude_v))
        lowest = i;
    }
    const size_t step = std::max<size_t>(1, (th.size() + 9) / 10);
    for (size_t i = 0; i < th.size(); ++i) {
      if (i % step != 0 && i != th.size() - 1 && i != lowest) continue;
      text += Format("  %8.3f Hz  %s   %s%s\n", th[i].frequency_hz, VoltsOrDash(th[i].grazing_amplitude_v).c_str(),
                     VoltsOrDash(th[i].lowest_contact_amplitude_v).c_str(),
                     i == lowest ? "   <- lowest grazing amplitude" : "");
    }
  }

  text += "\nJump (bistable) intervals per amplitude:\n";
  if (th.empty() && r.jump.empty()) {
    text += "  not computed\n";
  } else if (r.jump.empty()) {
    text += "  none on the grid\n";
  }
  for (const JumpInterval& j : r.jump) {
    text += Format("  %8.4f V: %.4f .. %.4f Hz (bounded by %s .. %s)\n", j.amplitude_v, j.bistable_from_hz,
                   j.bistable_to_hz, j.from_kind.c_str(), j.to_kind.c_str());
  }
  return text;
}

const std::vector<std::string>& SweepFolderFiles() {
  static const std::vector<std::string> files = {
      "model.json",       "points.csv",    "saturation_threshold.csv", "jump.csv",
      "saturation_map.svg", "saturation_map_down.svg", "frf_up.svg", "frf_down.svg",
      "frf_phase.svg",    "summary.txt"};
  return files;
}

std::string SaturationMapSvg(const SweepResult& r, Branch branch, const SaturationMapStyle& style) {
  return SaturationMap(r, BranchGrid(r), branch, style);
}

std::string FrfMagnitudeSvg(const SweepResult& r, Branch branch) {
  return FrfPlot(r, FrfSeries(r, BranchGrid(r), branch, false, true),
                 FrfAxes(branch == Branch::kUp ? "First-order FRF |H|, up-sweep branch (paper Fig. 10)"
                                               : "First-order FRF |H|, down-sweep branch",
                         "|H| [N/V]"));
}

void WriteSweepFolder(const SweepResult& r, const ActuatorModel& model, const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw std::runtime_error("cannot create " + dir.string() + ": " + ec.message());

  WriteFile(dir / "model.json", ModelToJson(model).dump(2) + "\n");

  WriteFile(dir / "points.csv", CsvText(r.points));
  WriteFile(dir / "saturation_threshold.csv", CsvText(r.saturation_threshold));
  WriteFile(dir / "jump.csv", CsvText(r.jump));

  const BranchGrid grid(r);
  WriteFile(dir / "saturation_map.svg", SaturationMap(r, grid, Branch::kUp));
  WriteFile(dir / "saturation_map_down.svg", SaturationMap(r, grid, Branch::kDown));
  WriteFile(dir / "frf_up.svg", FrfMagnitudeSvg(r, Branch::kUp));
  WriteFile(dir / "frf_down.svg", FrfMagnitudeSvg(r, Branch::kDown));
  std::vector<plot::Series> phase = FrfSeries(r, grid, Branch::kUp, true, false);
  for (plot::Series& s : FrfSeries(r, grid, Branch::kDown, true, false)) {
    if (s.color == "#000000") continue;  // the down-sweep's jumps: the up-sweep's are drawn
    s.label.clear();  // one legend entry per amplitude
    s.dashed = true;
    phase.push_back(std::move(s));
  }
  for (const bool down : {false, true}) {  // legend entries for the two line styles
    plot::Series style = Curve(down ? "down branch" : "up branch", "#7F7F7F");
    style.dashed = down;
    phase.push_back(std::move(style));
  }
  WriteFile(dir / "frf_phase.svg",
            FrfPlot(r, phase, FrfAxes("First-order FRF phase: up branch solid, down branch dashed", "arg H [rad]")));
  WriteFile(dir / "summary.txt", SweepSummaryText(r));
}

}  // namespace strokelab::report
