// The diagnosis page's figures against drive amplitude (diagnose_report.h), one point per amplitude
// level of Signatures::levels: resonance, contact time, harmonic ratios.
#include <algorithm>
#include <cmath>
#include <numbers>

#include "diagnose_report_internal.h"
#include "strokelab/plot/svg_plot.h"

namespace strokelab::report::diagnose_internal {
namespace {

constexpr int kLevelWidthPx = 640;

// Axes of a per-level figure: drive amplitude over all the campaign's levels (so that one can see
// where, say, contacts begin), the legend's `legend_rows` kept clear of the data.
plot::Axes LevelAxes(std::string title, std::string y_label, const std::vector<plot::Series>& series,
                     const std::vector<Signatures::Level>& levels, bool log_y, size_t legend_rows) {
  plot::Axes axes = MakeAxes(std::move(title), "drive amplitude [V]", std::move(y_label), kLevelWidthPx, 400);
  plot::Series all = Line("", "");
  for (const Signatures::Level& level : levels) {
    all.x.push_back(level.amplitude_v);
    all.y.push_back(1.0);
  }
  // Stepped-sine levels are often geometric (0.05, 0.1, 0.2, 0.4 V): a log axis spaces them evenly.
  const auto [lo, hi] = Extent({all}, true, true);
  axes.log_x = lo > 0 && hi >= 4 * lo;
  PadRange({all}, true, axes.log_x, 0.08, 0.08, &axes.x_min, &axes.x_max);
  axes.log_y = log_y;
  PadRange(series, false, log_y, 0.1, 0.12 + 0.12 * static_cast<double>(legend_rows), &axes.y_min, &axes.y_max);
  return axes;
}

}  // namespace

Figure ResonanceFigure(const Diagnosis& d) {
  Figure fig{"resonance", "Resonance against drive amplitude", {}, {}, ""};
  plot::Series points = Dots("resonance of paper Eq. 3, per level", kChosenColor, 2.2);
  points.line = true;
  plot::Series bars = Line("+- one standard error", kChosenColor);
  for (const Signatures::Level& level : d.signatures.levels) {
    if (!std::isfinite(level.resonance_hz)) continue;
    points.x.push_back(level.amplitude_v);
    points.y.push_back(level.resonance_hz);
    if (!(level.resonance_se_hz > 0)) continue;
    bars.x.insert(bars.x.end(), {level.amplitude_v, level.amplitude_v, NAN});
    bars.y.insert(bars.y.end(),
                  {level.resonance_hz - level.resonance_se_hz, level.resonance_hz + level.resonance_se_hz, NAN});
  }
  if (points.x.empty()) {
    fig.caption = "No amplitude level has 3 or more records clear of the stop: no resonance per level.";
    return fig;
  }
  std::vector<plot::Series> series = {bars, points};
  const ActuatorModel& m = d.base.model;
  const double natural_hz = std::sqrt(m.stiffness_n_per_m / m.mass_kg) / (2 * std::numbers::pi);
  const bool with_base = std::isfinite(natural_hz) && natural_hz > 0;
  if (with_base) {
    plot::Series base = Line("base model sqrt(k_p/m_p)/2pi", kBaseColor, true);
    base.x = {points.x.front(), points.x.front()};
    base.y = {natural_hz, natural_hz};
    series.push_back(std::move(base));
  }
  const plot::Axes axes = LevelAxes("Resonance per amplitude level", "resonance [Hz]", series, d.signatures.levels,
                                    false, series.size());
  // The base model's resonance is one number for every amplitude: a line across the whole axis
  // (between the levels that have a resonance it had no length when only one has).
  if (with_base) series.back().x = {axes.x_min, axes.x_max};
  fig.svgs.push_back(plot::LinePlot(series, axes));
  fig.caption = points.x.size() == 1
                    ? Format("Only one amplitude level (%s V) has 3 or more records clear of the stop, so no trend "
                             "with amplitude can be read here. ",
                             Num(points.x.front(), 3).c_str())
                    : std::string();
  fig.caption += "A linear suspension keeps its resonance at every amplitude; a drift with amplitude points to a "
                 "stiffness nonlinearity (up: hardening, down: softening).";
  return fig;
}

Figure ContactFigure(const Diagnosis& d, const char* unit) {
  Figure fig{"contact", "Contact times and the residual near contacts", {}, {}, ""};
  const Signatures& s = d.signatures;
  const double near = s.residual_rms_near_contacts, elsewhere = s.residual_rms_elsewhere;
  const std::string residual =
      std::isfinite(near) || std::isfinite(elsewhere)
          ? Format("Time-domain residual RMS of the base model over the contacting records: %s %s within +-%s ms of "
                   "the contacts, %s %s elsewhere (ratio %s).",
                   Num(near).c_str(), unit, Num(s.contact_window_s * 1e3, 3).c_str(), Num(elsewhere).c_str(), unit,
                   Num(near / elsewhere, 3).c_str())
          : std::string("No contacts: no time-domain residual near contacts.");
  plot::Series times = Dots("mean contact time", kChosenColor, 2.2);
  times.line = true;
  for (const Signatures::Level& level : s.levels) {
    if (!std::isfinite(level.mean_contact_time_s)) continue;
    times.x.push_back(level.amplitude_v);
    times.y.push_back(level.mean_contact_time_s * 1e3);
  }
  if (times.x.empty()) {
    fig.caption = "No contact times: no amplitude level has impact spikes. " + residual;
    return fig;
  }
  fig.svgs.push_back(plot::LinePlot(
      {times}, LevelAxes("Mean contact time per amplitude level", "contact time [ms]", {times}, s.levels, false, 1)));
  fig.caption = "A linear stop's contact time does not depend on the impact speed; a falling trend points to a "
                "Hertzian contact. " + residual;
  return fig;
}

Figure RatiosFigure(const Diagnosis& d) {
  Figure fig{"ratios", "Even and odd harmonics against amplitude", {}, {}, ""};
  plot::Series even = Line("|C_2| / |C_1| (even)", kBaseColor), odd = Line("|C_3| / |C_1| (odd)", kChosenColor);
  even.markers = odd.markers = true;
  bool positive = true;
  for (const Signatures::Level& level : d.signatures.levels) {
    for (auto [series, value] : {std::pair{&even, level.second_harmonic_ratio}, {&odd, level.third_harmonic_ratio}}) {
      if (!std::isfinite(value)) continue;
      series->x.push_back(level.amplitude_v);
      series->y.push_back(value);
      positive = positive && value > 0;
    }
  }
  if (even.x.empty() && odd.x.empty()) {
    fig.caption = "No amplitude level has records clear of the stop: no harmonic ratios.";
    return fig;
  }
  fig.svgs.push_back(plot::LinePlot({even, odd}, LevelAxes("Harmonic ratios of the records clear of the stop",
                                                            "ratio [dimensionless]", {even, odd}, d.signatures.levels, positive, 2)));
  fig.caption = "Clear of the stop a linear model has no harmonics. An even ratio growing with amplitude points to "
                "an asymmetric suspension (k2), an odd one to a cubic stiffness (k3) or dry friction.";
  return fig;
}

}  // namespace strokelab::report::diagnose_internal
