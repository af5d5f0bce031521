// Axis ranges and tick choice: the range an axis shows (explicit limits, or the data snapped
// outward to round values), and where its labelled and minor ticks go, with their labels.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "svg_plot_internal.h"

namespace strokelab::plot::svg_internal {
namespace {

// ---------------------------------------------------------------------------------------------
// Tick labels.

// Typographic minus sign (U+2212) instead of a hyphen, as printed tables do.
std::string WithMinusSign(std::string s) {
  if (!s.empty() && s[0] == '-') s.replace(0, 1, "\u2212");
  return s;
}

std::string TrimZeros(std::string s) {
  if (s.find('.') == std::string::npos) return s;
  while (s.back() == '0') s.pop_back();
  if (s.back() == '.') s.pop_back();
  return s;
}

// 2.50e+06 -> 2.5e6
std::string ScientificLabel(double v, int mantissa_decimals) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.*e", std::max(0, mantissa_decimals), v);
  const std::string s = buf;
  const size_t e = s.find('e');
  const int exponent = std::stoi(s.substr(e + 1));
  return WithMinusSign(TrimZeros(s.substr(0, e)) + "e" + WithMinusSign(std::to_string(exponent)));
}

// Plain decimals between 1e-3 and 1e5, "2.5e6" style outside: chosen once per axis so that all
// labels of one axis look alike.
bool UseScientific(double max_abs) { return max_abs >= 1e5 || (max_abs > 0 && max_abs < 1e-3); }

int FloorLog10(double v) { return static_cast<int>(std::floor(std::log10(v) + 1e-9)); }

// A tick on a 1-2-5 grid of spacing `step`, with just enough digits to tell neighbours apart.
std::string FormatTick(double v, double step, bool scientific) {
  if (v == 0.0) {
    if (scientific) return "0";
    v = 0.0;  // never "-0.0"
  }
  if (scientific) return ScientificLabel(v, FloorLog10(std::abs(v)) - FloorLog10(step));
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.*f", std::max(0, -FloorLog10(step)), v);
  return WithMinusSign(buf);
}

// ---------------------------------------------------------------------------------------------
// Steps, ranges and ticks.

// The smallest step of 1, 2 or 5 times a power of ten that is at least `min_step`.
double NiceStepAtLeast(double min_step) {
  const double magnitude = std::pow(10.0, std::floor(std::log10(min_step)));
  for (double m : {1.0, 2.0, 5.0}) {
    if (m * magnitude >= min_step * (1 - 1e-9)) return m * magnitude;
  }
  return 10 * magnitude;
}

// The 1-2-5 step that puts major ticks at least `min_spacing_px` apart.
double TickStep(Range r, double axis_px, double min_spacing_px) {
  return NiceStepAtLeast((r.hi - r.lo) * min_spacing_px / axis_px);
}

// The largest 1, 2 or 5 times a power of ten at or below v > 0, and the smallest at or above.
double OneTwoFiveBelow(double v) {
  const double magnitude = std::pow(10.0, std::floor(std::log10(v) + 1e-9));
  for (double m : {5.0, 2.0}) {
    if (m * magnitude <= v * (1 + 1e-9)) return m * magnitude;
  }
  return magnitude;
}
double OneTwoFiveAbove(double v) { return NiceStepAtLeast(v); }

// Moves the free ends of a range outward to round values, per `fit`.
Range SnapOutward(Range r, bool log, Fit fit, bool free_lo, bool free_hi, double axis_px, double min_spacing_px) {
  if (log) {  // outward to 1, 2 or 5 times a power of ten: whole decades would waste up to one each side
    if (free_lo) r.lo = OneTwoFiveBelow(r.lo);
    if (free_hi) r.hi = OneTwoFiveAbove(r.hi);
    return r;
  }
  if (fit == Fit::kPadToHalfTick) {
    const double pad = 0.02 * (r.hi - r.lo);
    if (free_lo) r.lo -= pad;
    if (free_hi) r.hi += pad;
  }
  double step = TickStep(r, axis_px, min_spacing_px);
  if (fit == Fit::kPadToHalfTick) step /= 2;
  if (free_lo) r.lo = std::floor(r.lo / step + 1e-9) * step;
  if (free_hi) r.hi = std::ceil(r.hi / step - 1e-9) * step;
  return r;
}

// Multiples of `step` inside the range, labelled consistently.
AxisTicks StepTicks(Range r, double step) {
  AxisTicks t;
  const double first = std::ceil(r.lo / step - 1e-9), last = std::floor(r.hi / step + 1e-9);
  // A range too narrow for its magnitude (1e20 + 1e4) has no representable step: no ticks.
  if (!(last - first >= 0 && last - first <= 1000)) return t;
  double max_abs = 0;
  for (int i = 0; i <= static_cast<int>(last - first); ++i) {
    const double k = first + i;
    const double v = k == 0 ? 0.0 : k * step;  // exact zero, never 1e-17
    t.major.push_back(v);
    max_abs = std::max(max_abs, std::abs(v));
  }
  const bool scientific = UseScientific(max_abs);
  for (double v : t.major) t.labels.push_back(FormatTick(v, step, scientific));
  return t;
}

// Whether neighbouring tick labels leave room between them.
bool LabelsFit(const AxisTicks& t, const Scale& s, bool horizontal) {
  for (size_t i = 1; i < t.major.size(); ++i) {
    const double gap = std::abs(s(t.major[i]) - s(t.major[i - 1]));
    const double need =
        horizontal ? 0.5 * (TextWidthPx(t.labels[i], kTickFontPx) + TextWidthPx(t.labels[i - 1], kTickFontPx)) +
                         kMinTickLabelGapPx
                   : 2 * kTickFontPx;
    if (gap < need) return false;
  }
  return true;
}

AxisTicks LinearTicks(const Scale& s, double min_spacing_px, bool horizontal) {
  double step = TickStep(s.range, std::abs(s.px_hi - s.px_lo), min_spacing_px);
  AxisTicks t = StepTicks(s.range, step);
  // A short axis may fit less than two ticks at the least spacing; two labels matter more.
  for (int tries = 0; tries < 6 && t.major.size() < 2; ++tries) {
    step = OneTwoFiveBelow(step * 0.99);
    t = StepTicks(s.range, step);
  }
  if (t.major.size() < 2) return t;
  // Wider steps until the labels no longer collide (long labels on a narrow axis).
  for (int tries = 0; tries < 6 && !LabelsFit(t, s, horizontal); ++tries) {
    step = NiceStepAtLeast(step * 1.01);
    t = StepTicks(s.range, step);
  }
  return t;
}

bool IsPowerOfTen(double v) {
  const double e = std::log10(v);
  return std::abs(e - std::round(e)) < 1e-9;
}

// Ticks at m * 10^d inside the range: labelled where m is in `labelled_mantissas` (and, for m = 1,
// d is a multiple of `every`), minor otherwise.
AxisTicks PowerTicks(Range r, const std::vector<int>& labelled_mantissas, int every) {
  AxisTicks t;
  const int d0 = FloorLog10(r.lo), d1 = FloorLog10(r.hi);
  for (int d = d0; d <= d1; ++d) {
    for (int m = 1; m <= 9; ++m) {
      const double v = m * std::pow(10.0, d);
      if (v < r.lo * (1 - 1e-9) || v > r.hi * (1 + 1e-9)) continue;
      const bool wanted =
          std::find(labelled_mantissas.begin(), labelled_mantissas.end(), m) != labelled_mantissas.end();
      const bool skipped_decade = m == 1 && ((d % every) + every) % every != 0;
      (wanted && !skipped_decade ? t.major : t.minor).push_back(v);
    }
  }
  const bool scientific = !t.major.empty() && (UseScientific(t.major.back()) || UseScientific(t.major.front()));
  for (double v : t.major) t.labels.push_back(FormatTick(v, std::pow(10.0, FloorLog10(v)), scientific));
  return t;
}

// Whether the labelled ticks reach near both ends of the axis: neither end lies further from its
// nearest label than a quarter of the axis (in decades). Labels at 6, 7, 8, 9, 10 on an axis to
// 14 Hz left its last third, where records at 11 and 13 Hz were, without a label.
bool LabelsCoverRange(const AxisTicks& t, Range r) {
  if (t.major.empty()) return false;
  const double quarter = 0.25 * std::log10(r.hi / r.lo);
  return std::log10(t.major.front() / r.lo) <= quarter && std::log10(r.hi / t.major.back()) <= quarter;
}

// Log ticks: labelled decades (every k-th when crowded; 1, 2 and 5 in each when roomy) with minor
// ticks at 2..9 times each decade. A range of less than two decades gets labels at 1, 2, 5 (or all
// of 1..9) times a power of ten, and failing that (labels that collide or leave an end of the axis
// bare), linear ticks.
AxisTicks LogTicks(const Scale& s, double spacing_px, bool horizontal) {
  const double px_per_decade = s.PxPerUnit();
  if (px_per_decade >= 4 * spacing_px) {  // roomy decades: label 1, 2 and 5 in each
    AxisTicks t = PowerTicks(s.range, {1, 2, 5}, 1);
    if (t.major.size() >= 2 && LabelsFit(t, s, horizontal) && LabelsCoverRange(t, s.range)) return t;
  }
  for (int every : {1, 2, 3, 5, 10, 20, 25, 50, 100, 200}) {  // label every k-th decade
    AxisTicks t = PowerTicks(s.range, {1}, every);
    if (t.major.size() < 2) break;
    if (!LabelsFit(t, s, horizontal)) continue;
    // Crowded decades: 2..9 would blur into a bar, so mark only the unlabelled decades, or nothing.
    if (px_per_decade < kMinPxPerDecadeForMinorTicks) std::erase_if(t.minor, [](double v) { return !IsPowerOfTen(v); });
    if (px_per_decade < 5) t.minor.clear();
    return t;
  }
  for (const std::vector<int>& mantissas : {std::vector<int>{1, 2, 5}, std::vector<int>{1, 2, 3, 4, 5, 6, 7, 8, 9}}) {
    AxisTicks t = PowerTicks(s.range, mantissas, 1);
    if (t.major.size() >= 2 && LabelsFit(t, s, horizontal) && LabelsCoverRange(t, s.range)) return t;
  }
  return LinearTicks(s, spacing_px, horizontal);  // well under a decade: a 1-2-5 grid reads best
}

}  // namespace

void Extend(std::optional<Range>& r, double v) {
  if (!r) {
    r = Range{v, v};
  } else {
    r->lo = std::min(r->lo, v);
    r->hi = std::max(r->hi, v);
  }
}

Range ResolveRange(double user_lo, double user_hi, std::optional<Range> data, bool log, Fit fit, double axis_px,
                   double min_spacing_px) {
  const bool fixed_lo = !std::isnan(user_lo), fixed_hi = !std::isnan(user_hi);
  Range r = data.value_or(log ? Range{1.0, 10.0} : Range{0.0, 1.0});
  if (fixed_lo) r.lo = user_lo;
  if (fixed_hi) r.hi = user_hi;

  if (!(r.lo < r.hi)) {  // one value only, or an explicit limit beyond all the data
    if (log) {
      if (!fixed_hi) r.hi = r.lo * 10.0;
      if (!fixed_lo) r.lo = (fixed_hi ? r.hi : r.lo) / 10.0;
    } else {
      const double ref = fixed_hi && !fixed_lo ? r.hi : r.lo;
      const double half = ref == 0.0 ? 1.0 : 0.1 * std::abs(ref);
      if (fixed_lo) {
        r.hi = r.lo + 2 * half;
      } else if (fixed_hi) {
        r.lo = r.hi - 2 * half;
      } else {
        r = {r.lo - half, r.hi + half};
      }
    }
  }
  if (fit == Fit::kExact) return r;
  const Range unsnapped = r;
  r = SnapOutward(r, log, fit, !fixed_lo, !fixed_hi, axis_px, min_spacing_px);
  // Near the largest doubles snapping can overflow.
  return std::isfinite(r.lo) && std::isfinite(r.hi) ? r : unsnapped;
}

AxisTicks MakeTicks(const Scale& s, double spacing_px, bool horizontal) {
  return s.log ? LogTicks(s, spacing_px, horizontal) : LinearTicks(s, spacing_px, horizontal);
}

}  // namespace strokelab::plot::svg_internal
