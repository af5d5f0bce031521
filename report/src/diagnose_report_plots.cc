// The figures of the diagnosis page (diagnose_report.h): each an inline SVG from the plot library, or
// a sentence when the diagnosis has no data for it.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <optional>

#include "diagnose_report_internal.h"
#include "strokelab/plot/svg_plot.h"

namespace strokelab::report::diagnose_internal {

plot::Series Line(std::string label, std::string color, bool dashed) {
  plot::Series s;
  s.label = std::move(label);
  s.color = std::move(color);
  s.dashed = dashed;
  return s;
}

plot::Series Dots(std::string label, std::string color, double line_width) {
  plot::Series s = Line(std::move(label), std::move(color));
  s.line = false;
  s.markers = true;
  s.line_width = line_width;
  return s;
}

plot::Axes MakeAxes(std::string title, std::string x_label, std::string y_label, int width_px, int height_px) {
  plot::Axes axes;
  axes.title = std::move(title);
  axes.x_label = std::move(x_label);
  axes.y_label = std::move(y_label);
  axes.width_px = width_px;
  axes.height_px = height_px;
  return axes;
}

std::pair<double, double> Extent(const std::vector<plot::Series>& series, bool x_axis, bool log) {
  double lo = INFINITY, hi = -INFINITY;
  for (const plot::Series& s : series) {
    for (size_t i = 0; i < s.x.size(); ++i) {
      const double v = x_axis ? s.x[i] : s.y[i];
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i]) || (log && !(v > 0))) continue;
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
  }
  return {lo, hi};
}

void PadRange(const std::vector<plot::Series>& series, bool x_axis, bool log, double lo_pad, double hi_pad,
              double* min, double* max) {
  auto [lo, hi] = Extent(series, x_axis, log);
  if (!(lo <= hi)) return;
  if (log) {
    lo = std::log10(lo);
    hi = std::log10(hi);
  }
  const double span = hi > lo ? hi - lo : log ? 0.3 : std::max(0.2 * std::abs(hi), 1e-12);
  *min = log ? std::pow(10.0, lo - lo_pad * span) : lo - lo_pad * span;
  *max = log ? std::pow(10.0, hi + hi_pad * span) : hi + hi_pad * span;
}

namespace {

constexpr size_t kWorstRecords = 3;  // records whose harmonics are shown
// Two pictures side by side fit a 1200 px wide window.
constexpr int kHalfWidthPx = 560;
constexpr const char* kStyleColor = "#7F7F7F";  // legend entries that explain a line style
// Residual bins from small (blue) to large (red): RdYlBu without its pale middle, which would vanish
// on the white page.
constexpr const char* kResidualColors[] = {"#313695", "#4575b4", "#74add1", "#fdae61",
                                           "#f46d43", "#d73027", "#a50026"};
constexpr size_t kMaxResidualBins = std::size(kResidualColors);

bool AnyFinite(const std::vector<plot::Series>& series) {
  for (const plot::Series& s : series) {
    for (size_t i = 0; i < s.y.size(); ++i) {
      if (std::isfinite(s.x[i]) && std::isfinite(s.y[i])) return true;
    }
  }
  return false;
}

// The phase in rad on (-pi, pi] (rad: the unit of every phase strokelab writes).
double WrappedRad(std::complex<double> c) { return std::abs(c) > 0 ? std::arg(c) : NAN; }

// Phases of c[0..n) in rad on (-pi, pi] against h = 1..n; the line breaks where the wrapped phase
// jumps by more than pi between neighbours, rather than sweeping across the plot.
void AddPhases(const std::vector<std::complex<double>>& c, size_t n, plot::Series* s) {
  double previous = NAN;
  for (size_t h = 0; h < n; ++h) {
    const double rad = h < c.size() ? WrappedRad(c[h]) : NAN;
    if (std::abs(rad - previous) > std::numbers::pi) {
      s->x.push_back(static_cast<double>(h) + 0.5);
      s->y.push_back(NAN);
    }
    s->x.push_back(static_cast<double>(h + 1));
    s->y.push_back(rad);
    previous = rad;
  }
}

bool HasChosen(const Diagnosis& d) { return d.chosen >= 0 && d.after.size() == d.before.size(); }

std::string ChosenLabel(const Diagnosis& d) {
  return d.chosen >= 0 && static_cast<size_t>(d.chosen) < d.candidates.size()
             ? "base + " + d.candidates[static_cast<size_t>(d.chosen)].label
             : std::string("chosen model");
}

// ---- harmonics of the worst records -------------------------------------------------------------

Figure HarmonicsFigure(const Diagnosis& d, const char* unit) {
  Figure fig{"harmonics", "Harmonics of the worst records", {}, {}, ""};
  std::vector<size_t> order;
  for (size_t i = 0; i < d.before.size(); ++i) {
    if (std::isfinite(d.before[i].chi2) && !d.before[i].measured.empty()) order.push_back(i);
  }
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return d.before[a].chi2 > d.before[b].chi2; });
  if (order.size() > kWorstRecords) order.resize(kWorstRecords);
  if (order.empty()) {
    fig.caption = "No record has measured harmonics: nothing to compare.";
    return fig;
  }
  const bool chosen = HasChosen(d);
  for (size_t i : order) {
    const RecordMatch& rec = d.before[i];
    const size_t n = rec.measured.size();
    const std::vector<std::complex<double>> none;
    const auto& after_model = chosen ? d.after[i].model : none;
    std::vector<plot::Series> magnitude = {Line("base model", kBaseColor, true), Line(ChosenLabel(d), kChosenColor),
                                           Dots("measured", kMeasuredColor, 2.2)};
    magnitude[0].markers = magnitude[1].markers = true;
    std::vector<plot::Series> phase = magnitude;
    for (plot::Series& s : phase) s.label.clear();  // the magnitude plot beside it has the legend
    const std::vector<std::complex<double>>* sources[] = {&rec.model, &after_model, &rec.measured};
    for (size_t k = 0; k < 3; ++k) {
      for (size_t h = 0; h < n; ++h) {
        magnitude[k].x.push_back(static_cast<double>(h + 1));
        magnitude[k].y.push_back(h < sources[k]->size() ? std::abs((*sources[k])[h]) : NAN);
      }
      AddPhases(*sources[k], n, &phase[k]);
    }
    if (!chosen) {
      magnitude.erase(magnitude.begin() + 1);
      phase.erase(phase.begin() + 1);
    }
    const std::string where = Format(" (%s Hz, %s V, chi2 %s%s)", Num(rec.frequency_hz).c_str(),
                                     Num(rec.amplitude_v).c_str(), Num(rec.chi2, 3).c_str(),
                                     rec.heldout ? ", held out" : "");
    plot::Axes axes = MakeAxes(rec.name + where, "harmonic order h", Format("|C_h| [%s]", unit), kHalfWidthPx, 340);
    axes.log_y = true;
    PadRange(magnitude, false, true, 0.04, 0.08, &axes.y_min, &axes.y_max);
    fig.svgs.push_back(plot::LinePlot(magnitude, axes));
    axes = MakeAxes(rec.name + ": phase", "harmonic order h", "arg C_h [rad]", kHalfWidthPx, 340);
    axes.y_min = -std::numbers::pi;
    axes.y_max = std::numbers::pi;
    fig.svgs.push_back(plot::LinePlot(phase, axes));
  }
  fig.caption = Format("The %zu records the base model fits worst (largest chi-square): measured harmonics as dots, "
                       "the base model dashed%s. Phases relative to the drive in rad, wrapped to \u00b1\u03c0.",
                       order.size(), chosen ? (", " + ChosenLabel(d) + " solid").c_str() : " (nothing was added)");
  return fig;
}

// ---- first-harmonic FRF per amplitude level -----------------------------------------------------

Figure FrfFigure(const Diagnosis& d, const char* unit) {
  Figure fig{"frf", "First-harmonic FRF per amplitude level", {}, {}, ""};
  const AmplitudeLevels levels = GroupAmplitudes(d.before);
  const bool chosen = HasChosen(d);
  // Levels coloured by amplitude with a colour bar (as the sweep's FRF families): a legend entry per
  // level covered the points.
  std::optional<plot::ColorBar> bar;
  if (levels.amplitude_v.size() >= 2) {
    const double lo = levels.amplitude_v.front(), hi = levels.amplitude_v.back();
    bar = plot::ColorBar{"drive amplitude [V]", lo, hi, lo > 0 && hi >= 4 * lo};
  }
  std::vector<plot::Series> series;
  for (size_t level = 0; level < levels.amplitude_v.size(); ++level) {
    std::vector<size_t> members;
    for (size_t i = 0; i < d.before.size(); ++i) {
      if (levels.level_of[i] == level) members.push_back(i);
    }
    std::sort(members.begin(), members.end(),
              [&](size_t a, size_t b) { return d.before[a].frequency_hz < d.before[b].frequency_hz; });
    const std::string color = bar ? plot::ColorBarColor(*bar, levels.amplitude_v[level]) : std::string(kChosenColor);
    plot::Series measured = Dots(bar ? "" : Num(levels.amplitude_v[level], 3) + " V", color, 2.0);
    plot::Series base = Line("", color, true), after = Line("", color);
    for (size_t i : members) {
      const RecordMatch& rec = d.before[i];
      const double v = rec.amplitude_v;
      auto first = [v](const std::vector<std::complex<double>>& c) { return c.empty() ? NAN : std::abs(c[0]) / v; };
      for (plot::Series* s : {&measured, &base, &after}) s->x.push_back(rec.frequency_hz);
      measured.y.push_back(first(rec.measured));
      base.y.push_back(first(rec.model));
      after.y.push_back(chosen ? first(d.after[i].model) : NAN);
    }
    series.push_back(std::move(base));
    if (chosen) series.push_back(std::move(after));
    series.push_back(std::move(measured));
  }
  if (!AnyFinite(series)) {
    fig.caption = "No record has a first harmonic: no FRF to show.";
    return fig;
  }
  if (bar) series.push_back(Dots("dots: measured", kStyleColor, 2.0));
  series.push_back(Line("dashed: base model", kStyleColor, true));
  if (chosen) series.push_back(Line("solid: " + ChosenLabel(d), kStyleColor));
  plot::Axes axes = MakeAxes("|C_1| / V against frequency, per drive amplitude", "drive frequency [Hz]",
                             Format("|C_1| / V [%s/V]", unit), 1000, 480);
  axes.log_x = axes.log_y = true;
  // Room above the data for the legend's rows, so that it covers no point.
  size_t legend_rows = 0;
  for (const plot::Series& s : series) legend_rows += s.label.empty() ? 0 : 1;
  PadRange(series, false, true, 0.06, 0.1 + 0.09 * static_cast<double>(legend_rows), &axes.y_min, &axes.y_max);
  fig.svgs.push_back(bar ? plot::LinePlot(series, axes, *bar) : plot::LinePlot(series, axes));
  fig.caption = "Dots: measured first harmonic over the drive amplitude, coloured by amplitude level (the colour "
                "bar); lines: the models at the same drive.";
  return fig;
}

// ---- residual maps ------------------------------------------------------------------------------

// Bin edges on the 1-2-5 sequence covering [lo, hi] (0 < lo <= hi); every other edge dropped until
// there are few enough bins for distinct colours.
std::vector<double> ResidualEdges(double lo, double hi) {
  std::vector<double> nice;  // from the last value <= lo to the first > hi
  for (double decade = std::pow(10.0, std::floor(std::log10(lo))); nice.empty() || nice.back() <= hi; decade *= 10) {
    for (double m : {1.0, 2.0, 5.0}) {
      if (!nice.empty() && nice.back() > hi) break;
      if (!nice.empty() && m * decade <= lo) nice.clear();
      nice.push_back(m * decade);
    }
  }
  while (nice.size() - 1 > kMaxResidualBins) {
    std::vector<double> thinned;
    for (size_t i = 0; i < nice.size(); i += 2) thinned.push_back(nice[i]);
    if (thinned.back() <= hi) thinned.push_back(nice.back());
    nice = std::move(thinned);
  }
  return nice;
}

// Which bin of `edges` a residual falls in (the last bin closed), or none.
std::optional<size_t> ResidualBin(double nrmse, const std::vector<double>& edges) {
  for (size_t b = 0; b + 1 < edges.size(); ++b) {
    if (nrmse >= edges[b] && (nrmse < edges[b + 1] || b + 2 == edges.size())) return b;
  }
  return std::nullopt;
}

const char* ResidualColor(size_t bin, size_t bins) {
  return kResidualColors[bins == 1 ? 0 : bin * (kMaxResidualBins - 1) / (bins - 1)];
}

std::string ResidualMap(const std::vector<RecordMatch>& records, const std::vector<double>& edges,
                        const std::string& title) {
  std::vector<plot::Series> series;
  plot::Series ring = Dots("", kMeasuredColor, 3.6);
  for (const RecordMatch& rec : records) {
    if (!rec.heldout) continue;
    ring.x.push_back(rec.frequency_hz);
    ring.y.push_back(rec.amplitude_v);
  }
  series.push_back(ring);  // beneath the coloured dots, which leave a black ring
  const size_t bins = edges.size() - 1;
  for (size_t b = 0; b < bins; ++b) series.push_back(Dots("", ResidualColor(b, bins), 2.5));
  for (const RecordMatch& rec : records) {
    const std::optional<size_t> bin = ResidualBin(rec.nrmse, edges);
    if (!bin) continue;
    series[1 + *bin].x.push_back(rec.frequency_hz);
    series[1 + *bin].y.push_back(rec.amplitude_v);
  }
  plot::Axes axes = MakeAxes(title, "drive frequency [Hz]", "drive amplitude [V]", kHalfWidthPx, 400);
  axes.log_x = axes.log_y = true;
  PadRange(series, true, true, 0.06, 0.06, &axes.x_min, &axes.x_max);
  PadRange(series, false, true, 0.12, 0.12, &axes.y_min, &axes.y_max);
  return plot::LinePlot(series, axes);
}

Figure ResidualFigure(const Diagnosis& d) {
  Figure fig{"residual", "Residual maps over frequency and amplitude", {}, {}, ""};
  const bool chosen = HasChosen(d);
  double lo = INFINITY, hi = -INFINITY;
  for (const auto* records : {&d.before, chosen ? &d.after : &d.before}) {
    for (const RecordMatch& rec : *records) {
      if (!(rec.nrmse > 0) || !std::isfinite(rec.nrmse)) continue;
      lo = std::min(lo, rec.nrmse);
      hi = std::max(hi, rec.nrmse);
    }
  }
  if (!(lo <= hi)) {
    fig.caption = "No record has a finite, positive nrmse: no residual map.";
    return fig;
  }
  const std::vector<double> edges = ResidualEdges(lo, hi);
  fig.svgs.push_back(ResidualMap(d.before, edges, "Base model: nrmse per record"));
  if (chosen) fig.svgs.push_back(ResidualMap(d.after, edges, ChosenLabel(d) + ": nrmse per record"));
  // The key lists the bins that hold a record in either map.
  std::vector<bool> used(edges.size() - 1, false);
  for (const auto* records : {&d.before, chosen ? &d.after : &d.before}) {
    for (const RecordMatch& rec : *records) {
      if (const std::optional<size_t> bin = ResidualBin(rec.nrmse, edges)) used[*bin] = true;
    }
  }
  for (size_t b = 0; b < used.size(); ++b) {
    if (used[b]) {
      fig.key.emplace_back(std::string("background: ") + ResidualColor(b, used.size()),
                           "nrmse " + Num(edges[b], 3) + " .. " + Num(edges[b + 1], 3));
    }
  }
  fig.key.emplace_back("background: #ffffff; box-shadow: inset 0 0 0 2px #000000", "ringed: held out");
  fig.caption = std::string("Each record at its estimated drive, coloured by its nrmse (the same colours in both "
                            "maps); records with a zero or undefined nrmse are not drawn.") +
                (chosen ? "" : " Nothing was added to the model, so there is no second map.");
  return fig;
}

// What the unexplained misfit is as a force over the state (MissingForceSurface): a restoring-force
// surface of the force the diagnosed model lacks. Only for a diagnosis with Unexplained.
Figure MissingForceFigure(const Diagnosis& d) {
  Figure fig{"missing_force", "Force the model lacks, over displacement and velocity", {}, {}, ""};
  const MissingForceSurface& s = d.unexplained->missing_force;
  if (s.force_n.empty()) {
    fig.caption = "No surface: " + s.note + ".";
    return fig;
  }
  plot::HeatMap map;
  for (double x : s.x_m) map.x.push_back(1e3 * x);
  for (double v : s.v_m_per_s) map.y.push_back(1e3 * v);
  for (size_t iv = 0; iv < s.v_m_per_s.size(); ++iv) {
    std::vector<double> row;
    for (size_t ix = 0; ix < s.x_m.size(); ++ix) row.push_back(s.force_n[ix * s.v_m_per_s.size() + iv]);
    map.z.push_back(std::move(row));
  }
  map.z_label = "missing force, mean per bin [N]";
  plot::Axes axes;
  axes.title = "Force the diagnosed model lacks (m_p x'' - F(u, x, v))";
  axes.x_label = "displacement x [mm]";
  axes.y_label = "velocity v [mm/s]";
  axes.width_px = 620;
  axes.height_px = 420;
  fig.svgs.push_back(plot::HeatMapPlot(map, {}, axes));
  fig.caption = "Per record and drive phase, the state and the acceleration from the measured harmonics, and the force "
                "the diagnosed model lacks there, m_p x'' - F(u, x, v), less the same on the model's own harmonics (a "
                "restoring-force surface, Masri and Caughey 1979), averaged per bin; blank bins hold fewer than 2 "
                "samples, and phases within 5 % of the stop distance of a stop are left out. RMS " + Num(s.rms_n, 3) +
                " N. Closest single term: " + s.term + ", " + Num(s.term_coefficient, 3) + " " + s.term_unit +
                " (with 1, x and v it explains " + Num(100.0 * s.term_r2, 2) + " % of the variance, 1, x and v alone " +
                Num(100.0 * s.linear_r2, 2) + " %).";
  return fig;
}

}  // namespace

std::vector<Figure> DiagnosisFigures(const Diagnosis& d) {
  const char* unit = UnitOf(d.base.response);
  std::vector<Figure> figures = {HarmonicsFigure(d, unit), FrfFigure(d, unit), CurvesFigure(d.curves), ResidualFigure(d),
                                 ResonanceFigure(d), ContactFigure(d, unit), RatiosFigure(d)};
  if (d.unexplained) figures.push_back(MissingForceFigure(d));  // only an unexplained misfit has one
  return figures;
}

}  // namespace strokelab::report::diagnose_internal
