// The page's answer to "what does the missing physics change for my control loop?"
// (diagnose_report.h): the saturation maps of the base and the diagnosed model side by side on one
// colour scale, how far the saturation threshold moved per frequency, and the jump intervals of both.
#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "diagnose_report_internal.h"
#include "strokelab/report/sweep_report.h"

namespace strokelab::report::diagnose_internal {
namespace {

// The SpikeFactor range over the stable steady states of both maps, so that one colour means one
// thing in both pictures. NaN when neither has one.
std::pair<double, double> SharedSpikeFactorRange(const DiagnosisMaps& maps) {
  double lo = INFINITY, hi = -INFINITY;
  for (const auto* result : {&maps.base, &maps.diagnosed}) {
    if (!*result) continue;
    for (const SweepPoint& p : (*result)->points) {
      const double z = SpikeFactor(p);
      if (p.branch == Branch::kUnstable || !p.stable || !(z > 0) || !std::isfinite(z)) continue;
      lo = std::min(lo, z), hi = std::max(hi, z);
    }
  }
  return lo <= hi ? std::pair{lo, hi} : std::pair{std::nan(""), std::nan("")};
}

std::string MapFigure(const std::optional<SweepResult>& result, const std::string& note, const std::string& title,
                      const std::pair<double, double>& range) {
  std::string out = "<figure>\n";
  if (result) {
    SaturationMapStyle style;
    style.title = title;
    style.spike_factor_min = range.first;
    style.spike_factor_max = range.second;
    out += SaturationMapSvg(*result, Branch::kUp, style);
    if (!result->failures.empty()) {
      out += "<figcaption class=\"caption\">" +
             Esc(Format("%zu of %zu rows and columns failed numerically and are left blank: ", result->failures.size(),
                        result->amplitude_v.size() + result->frequency_hz.size()));
      for (size_t i = 0; i < result->failures.size(); ++i) out += (i ? "; " : "") + Esc(result->failures[i]);
      out += "</figcaption>\n";
    }
  } else {
    out += "<p class=\"skipped\">" + Esc(title + ": no map, " + note) + "</p>\n";
  }
  return out + "</figure>\n";
}

// A shift with its sign: "+0.0123" [V], "+4.50" [%]; "-" when either side is missing.
std::string SignedVolts(double v) { return std::isfinite(v) ? Format("%+.4f", v) : "-"; }
std::string SignedPercent(double p) { return std::isfinite(p) ? Format("%+.2f", p) : "-"; }

// ThresholdShiftSummary (diagnosis_maps.h).
std::string ShiftSummaryText(const std::vector<ThresholdShift>& shifts) {
  const ThresholdShift* largest = nullptr;
  size_t both = 0, only_base = 0, only_diagnosed = 0;
  double sum_percent = 0;
  for (const ThresholdShift& s : shifts) {
    const bool b = std::isfinite(s.base_grazing_v), d = std::isfinite(s.diagnosed_grazing_v);
    only_base += b && !d;
    only_diagnosed += d && !b;
    if (!b || !d) continue;
    ++both;
    sum_percent += s.GrazingShiftPercent();
    if (!largest || std::abs(s.GrazingShiftV()) > std::abs(largest->GrazingShiftV())) largest = &s;
  }
  auto frequencies = [](size_t n) { return Format("%zu frequenc%s", n, n == 1 ? "y" : "ies"); };
  std::string text;
  if (largest) {
    text = Format("The grazing threshold (drive amplitude at which the stroke first reaches the stop) moves by %s V "
                  "at most, at %s Hz (%s \u2192 %s V, %s %%); by %s %% on average over the %s where both models "
                  "reach the stop.",
                  SignedVolts(largest->GrazingShiftV()).c_str(), Num(largest->frequency_hz).c_str(),
                  Num(largest->base_grazing_v).c_str(), Num(largest->diagnosed_grazing_v).c_str(),
                  SignedPercent(largest->GrazingShiftPercent()).c_str(),
                  SignedPercent(sum_percent / static_cast<double>(both)).c_str(), frequencies(both).c_str());
  } else {
    text = only_base || only_diagnosed ? "At no frequency of the grid do both models reach the stop."
                                       : "Neither model reaches the stop at any frequency of the grid.";
  }
  if (only_base) text += " At " + frequencies(only_base) + " only the base model reaches the stop.";
  if (only_diagnosed) text += " At " + frequencies(only_diagnosed) + " only the diagnosed model reaches the stop.";
  return text;
}

std::string ShiftTable(const std::vector<ThresholdShift>& shifts) {
  std::string rows;
  for (const ThresholdShift& s : shifts) {
    rows += "<tr>" + NumTd(s.frequency_hz) + NumTd(s.base_grazing_v) + NumTd(s.diagnosed_grazing_v) +
            Td(SignedVolts(s.GrazingShiftV()), "num") + Td(SignedPercent(s.GrazingShiftPercent()), "num") +
            NumTd(s.base_lowest_contact_v) + NumTd(s.diagnosed_lowest_contact_v) +
            Td(SignedVolts(s.LowestContactShiftV()), "num") + Td(SignedPercent(s.LowestContactShiftPercent()), "num") +
            "</tr>\n";
  }
  return Table({"f [Hz]", "grazing, base [V]", "grazing, diagnosed [V]", "\u0394 [V]", "\u0394 [%]",
                "lowest contacting, base [V]", "lowest contacting, diagnosed [V]", "\u0394 [V]", "\u0394 [%]"},
               rows, "threshold-shift");
}

std::string Intervals(const std::optional<SweepResult>& result, double amplitude_v) {
  if (!result) return "-";
  bool swept = false;  // a failed row (SweepResult::failures) has no steady states
  for (const SweepPoint& p : result->points) swept = swept || std::abs(p.amplitude_v - amplitude_v) <= 1e-9 * amplitude_v;
  if (!swept) return "not known: this amplitude's row failed";
  std::string text;
  for (const JumpInterval& j : result->jump) {
    if (std::abs(j.amplitude_v - amplitude_v) > 1e-9 * amplitude_v) continue;
    text += (text.empty() ? "" : "; ") + Format("%s \u2013 %s Hz (%s \u2013 %s)", Num(j.bistable_from_hz).c_str(),
                                                Num(j.bistable_to_hz).c_str(), j.from_kind.c_str(), j.to_kind.c_str());
  }
  return text.empty() ? "none" : text;
}

std::string JumpTable(const DiagnosisMaps& maps) {
  std::string rows;
  for (double v : maps.amplitude_v.Values()) {
    const std::string base = Intervals(maps.base, v), diagnosed = Intervals(maps.diagnosed, v);
    if (base == "none" && diagnosed == "none") continue;
    rows += "<tr>" + NumTd(v) + Td(base) + Td(diagnosed) + "</tr>\n";
  }
  if (rows.empty()) return "<p>No jump (bistable) interval on the grid for either model.</p>\n";
  return Table({"V [V]", "bistable, base model", "bistable, diagnosed model"}, rows, "jump-intervals");
}

}  // namespace

std::string MapsSection(const std::string& model_note, const std::vector<Effect>& missing, const DiagnosisMaps* maps) {
  std::string out = "<h2 id=\"maps\">What the missing physics changes for the control loop</h2>\n";
  out += "<p>" + Esc("Diagnosed model: " + model_note + ".") +
         " Model file: <a href=\"model.json\">model.json</a> (for <code>strokelab sweep --model</code>, "
         "<code>strokelab simulate --model</code> and a sweep job's <code>model</code>).</p>\n";
  if (maps == nullptr || !maps->note.empty()) {
    return out + "<p class=\"skipped\">" +
           Esc("Saturation maps " + (maps ? maps->note : std::string("not computed")) + ".") + "</p>\n";
  }
  const DiagnosisMaps& m = *maps;
  out += "<p class=\"caption\">" +
         Esc(Format("Steady states of both models over the campaign's range: %d frequencies %s \u2013 %s Hz "
                    "(geometric) x %d amplitudes %s \u2013 %s V, up-sweep branch, in %s s. Colour: peak force / "
                    "first-harmonic force amplitude (1 for a sinusoidal response, growing with the impacts), one "
                    "scale for both maps; red: grazing amplitude; white dashed: lowest amplitude with a stable "
                    "contacting response; black segments: jump (bistable) intervals.",
                    m.frequency_hz.points, Num(m.frequency_hz.from).c_str(), Num(m.frequency_hz.to).c_str(),
                    m.amplitude_v.points, Num(m.amplitude_v.from).c_str(), Num(m.amplitude_v.to).c_str(),
                    Num(m.seconds, 3).c_str())) +
         "</p>\n";
  const std::pair<double, double> range = SharedSpikeFactorRange(m);
  out += "<div class=\"maps\">\n";
  if (m.same_model) {
    out += MapFigure(m.base, m.base_note, "Base model = diagnosed model: stroke saturation, up-sweep branch", range);
  } else {
    out += MapFigure(m.base, m.base_note, "Base model: stroke saturation, up-sweep branch", range);
    out += MapFigure(m.diagnosed, m.diagnosed_note,
                     "Diagnosed model (+ " + EffectIds(missing) + "): stroke saturation, up-sweep branch",
                     range);
  }
  out += "</div>\n";
  if (m.same_model)
    out += "<p>" + Esc("Nothing missing: the diagnosed model is the base model, so the threshold does not move.") +
           "</p>\n";
  if (!m.base || !m.diagnosed) return out;
  const std::vector<ThresholdShift> shifts = ThresholdShifts(*m.base, *m.diagnosed);
  out += "<h3>Saturation threshold per frequency: base against diagnosed model</h3>\n";
  if (!m.same_model) out += "<p>" + Esc(ShiftSummaryText(shifts)) + "</p>\n";
  out += ShiftTable(shifts);
  out += "<h3>Jump (bistable) intervals per amplitude</h3>\n" + JumpTable(m);
  return out + "<p class=\"meta\">Tables: <a href=\"threshold_shift.csv\">threshold_shift.csv</a>, "
               "<a href=\"jump_intervals.csv\">jump_intervals.csv</a>.</p>\n";
}

}  // namespace strokelab::report::diagnose_internal

namespace strokelab::report {

std::string ThresholdShiftSummary(const std::vector<ThresholdShift>& shifts) {
  return diagnose_internal::ShiftSummaryText(shifts);
}

}  // namespace strokelab::report
