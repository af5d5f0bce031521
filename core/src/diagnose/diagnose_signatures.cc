// Signatures of a base model's mismatch (diagnose.h, step 3): each a measured figure with its
// standard error, and the effects of the library it points to.
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <sstream>

#include "diagnose_internal.h"
#include "strokelab/base/nan.h"
#include "strokelab/identify/frf_fit.h"

namespace strokelab::internal {
namespace {

using Complex = std::complex<double>;
constexpr double kSignificant = 3.0;     // a figure this many standard errors from its null is evidence
constexpr size_t kHotspots = 5;          // worst records listed
constexpr double kWindowContactTimes = 2.0;  // half-width of a contact window, in contact times
constexpr double kMinWindowS = 0.5e-3;       // ... and at least this [s]


Evidence Make(std::string kind, std::string summary, double value, double se, std::vector<Effect> points_to) {
  Evidence e;
  e.kind = std::move(kind);
  e.summary = std::move(summary);
  e.value = value;
  e.standard_error = se;
  e.significance = se > 0 && std::isfinite(se) && std::isfinite(value) ? std::abs(value) / se : 0.0;
  e.points_to = std::move(points_to);
  return e;
}

// RMS over the clear records of the harmonic-h residual in noise units (|dC| / (se sqrt 2): ~1 for
// noise alone).
Evidence HarmonicResidual(int h, std::span<const RecordAnalysis> analyses, const std::vector<RecordMatch>& before) {
  double sum = 0;
  size_t n = 0;
  for (size_t i = 0; i < analyses.size(); ++i) {
    if (!analyses[i].clear || before[i].model.size() < static_cast<size_t>(h) || !analyses[i].usable[h - 1]) continue;
    const double z = std::abs(before[i].measured[h - 1] - before[i].model[h - 1]) /
                     (analyses[i].harmonic_se * std::sqrt(2.0));
    sum += z * z;
    ++n;
  }
  const double rms = n > 0 ? std::sqrt(sum / static_cast<double>(n)) : kNaN;
  const bool even = h % 2 == 0;
  std::vector<Effect> points;
  if (rms > kSignificant) {
    points = even ? std::vector<Effect>{Effect::kQuadraticStiffness, Effect::kForceFactor}
                  : std::vector<Effect>{Effect::kCubicStiffness, Effect::kDryFriction, Effect::kAmplifierSaturation,
                                        Effect::kQuadraticDamping};
  }
  // Noise alone gives an RMS near 1 with a standard error ~ 1 / sqrt(2 n).
  const double se = n > 0 ? 1.0 / std::sqrt(2.0 * static_cast<double>(n)) : kNaN;
  return Make(even ? "even_harmonics" : "odd_harmonics",
              "harmonic " + std::to_string(h) + " of the " + std::to_string(n) +
                  " records clear of the stop misses by " + FormatFigure(rms) +
                  " noise standard errors (RMS; 1 is noise alone)",
              rms - 1.0, se, points);
}

}  // namespace

// Least-squares line y = a + b x; returns (b, se(b)) or NaN for fewer than 3 points.
std::pair<double, double> LineSlope(const std::vector<double>& x, const std::vector<double>& y) {
  const size_t n = x.size();
  if (n < 3) return {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN()};
  double mx = 0, my = 0;
  for (size_t i = 0; i < n; ++i) mx += x[i], my += y[i];
  mx /= static_cast<double>(n), my /= static_cast<double>(n);
  double sxx = 0, sxy = 0;
  for (size_t i = 0; i < n; ++i) sxx += (x[i] - mx) * (x[i] - mx), sxy += (x[i] - mx) * (y[i] - my);
  if (!(sxx > 0)) return {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN()};
  const double b = sxy / sxx, a = my - b * mx;
  double ssr = 0;
  for (size_t i = 0; i < n; ++i) ssr += (y[i] - a - b * x[i]) * (y[i] - a - b * x[i]);
  return {b, std::sqrt(ssr / static_cast<double>(n - 2) / sxx)};
}

Signatures MeasureSignatures(const Campaign& campaign, std::span<const RecordAnalysis> analyses,
                             const std::vector<RecordMatch>& before, const ActuatorModel& base, ResponseKind kind,
                             const FitOptions& options) {
  Signatures s;
  const int orders = options.harmonic_orders;

  // Hotspots: the worst records, each with its worst harmonic.
  std::vector<size_t> order(before.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return before[a].chi2 > before[b].chi2; });
  for (size_t k = 0; k < std::min(kHotspots, order.size()); ++k) {
    const RecordMatch& m = before[order[k]];
    if (m.model.empty()) continue;
    Signatures::Hotspot spot;
    spot.record = m.name;
    spot.frequency_hz = m.frequency_hz;
    spot.amplitude_v = m.amplitude_v;
    spot.chi2_per_residual = m.chi2 / (2.0 * static_cast<double>(orders));
    double worst = -1;
    for (int h = 1; h <= orders; ++h) {
      if (!analyses[order[k]].usable[h - 1]) continue;
      const double miss = std::abs(m.measured[h - 1] - m.model[h - 1]);
      if (miss > worst) worst = miss, spot.harmonic = h;
    }
    const Complex c = m.measured[spot.harmonic - 1], cm = m.model[spot.harmonic - 1];
    spot.magnitude_error = std::abs(cm) / std::abs(c) - 1.0;
    spot.phase_error_rad = std::arg(cm / c);
    s.hotspots.push_back(spot);
  }

  // Amplitude levels: resonance (paper Eq. 3 on the level's clear records), harmonic ratios, contact times.
  std::map<double, std::vector<size_t>> levels;
  for (size_t i = 0; i < analyses.size(); ++i) levels[analyses[i].nominal_amplitude_v].push_back(i);
  std::vector<double> level_v, level_f, level_w;
  for (const auto& [amplitude, members] : levels) {
    Signatures::Level level;
    level.amplitude_v = amplitude;
    std::vector<FrfSample> samples;
    double r2 = 0, r3 = 0, contact = 0;
    size_t spikes = 0;
    for (size_t i : members) {
      const RecordAnalysis& a = analyses[i];
      for (const Spike& spike : a.spikes) contact += spike.ContactTimeS(), ++spikes;
      if (!a.clear) continue;
      ++level.clear_records;
      samples.push_back({a.drive.frequency_hz, EquivalentForceFrf(a.frf, kind, a.drive.frequency_hz, options.mass_kg)});
      r2 += a.harmonics.size() > 1 ? std::abs(a.harmonics[1]) / std::abs(a.harmonics[0]) : 0;
      r3 += a.harmonics.size() > 2 ? std::abs(a.harmonics[2]) / std::abs(a.harmonics[0]) : 0;
    }
    level.second_harmonic_ratio = level.clear_records ? r2 / static_cast<double>(level.clear_records) : kNaN;
    level.third_harmonic_ratio = level.clear_records ? r3 / static_cast<double>(level.clear_records) : kNaN;
    level.mean_contact_time_s = spikes ? contact / static_cast<double>(spikes) : kNaN;
    level.resonance_hz = level.resonance_se_hz = kNaN;
    if (samples.size() >= 3) {
      FrfFitOptions frf;
      frf.mass_kg = options.mass_kg;
      const FrfFitSummary fit = FitLinearFrf(samples, frf);
      if (fit.converged) {
        level.resonance_hz = fit.natural_frequency_rad_s / (2.0 * std::numbers::pi);
        level.resonance_se_hz = fit.natural_frequency_se / (2.0 * std::numbers::pi);
        level_v.push_back(amplitude), level_f.push_back(level.resonance_hz), level_w.push_back(level.resonance_se_hz);
      }
    }
    s.levels.push_back(level);
  }

  // Harmonic balance below the stop.
  s.evidence.push_back(HarmonicResidual(2, analyses, before));
  if (orders >= 3) s.evidence.push_back(HarmonicResidual(3, analyses, before));

  // The resonance against amplitude (two levels: their difference over the combined error).
  if (level_v.size() >= 2) {
    double slope = kNaN, se = kNaN;
    if (level_v.size() == 2) {
      slope = (level_f[1] - level_f[0]) / (level_v[1] - level_v[0]);
      se = std::hypot(level_w[0], level_w[1]) / std::abs(level_v[1] - level_v[0]);
    } else {
      std::tie(slope, se) = LineSlope(level_v, level_f);
    }
    std::vector<Effect> points;
    if (std::abs(slope) > kSignificant * se) points = {Effect::kCubicStiffness};
    s.evidence.push_back(Make("resonance_shift",
                              "the resonance of the records clear of the stop moves by " + FormatFigure(slope) + " +- " +
                                  FormatFigure(se) + " Hz/V with the drive amplitude (" + std::to_string(level_v.size()) +
                                  " levels; a linear suspension keeps it still)",
                              slope, se, points));
  }

  // Contact times against impact strength: log dT vs log peak height (linear stop: 0; Hertz: -1/6).
  {
    std::vector<double> x, y;
    size_t positive = 0, negative = 0;
    for (const RecordAnalysis& a : analyses) {
      for (const Spike& spike : a.spikes) {
        (spike.peak_height > 0 ? positive : negative)++;
        if (spike.ContactTimeS() > 0 && spike.peak_height != 0)
          x.push_back(std::log(std::abs(spike.peak_height))), y.push_back(std::log(spike.ContactTimeS()));
      }
    }
    const auto [slope, se] = LineSlope(x, y);
    if (std::isfinite(slope)) {
      std::vector<Effect> points;
      if (slope < -kSignificant * se) points = {Effect::kHertzianContact};
      s.evidence.push_back(Make("contact_time_trend",
                                "log contact time against log spike height over " + std::to_string(x.size()) +
                                    " impacts: slope " + FormatFigure(slope) + " +- " + FormatFigure(se) +
                                    " (0 for a linear stop, -1/6 for Hertzian contact)",
                                slope, se, points));
    }
    const size_t minority = std::min(positive, negative), total = positive + negative;
    if (total > 0) {
      std::vector<Effect> points;
      if (minority >= 2) points = {Effect::kSecondStop};
      s.evidence.push_back(Make("spike_polarity",
                                std::to_string(minority) + " of " + std::to_string(total) +
                                    " impact spikes have the minority sign (impacts on a second stop have the other sign)",
                                static_cast<double>(minority), 0.0, points));
    }
  }

  // The first harmonic at the largest against the smallest drive amplitude: clipping makes the model
  // overshoot at the top at every frequency (a damping that grows with velocity, most near resonance;
  // a force factor that falls off over the stroke).
  if (levels.size() >= 2) {
    auto mean_error = [&](const std::vector<size_t>& members, double* se) {
      std::vector<double> e;
      for (size_t i : members)
        if (!before[i].model.empty()) e.push_back(std::abs(before[i].model[0]) / std::abs(before[i].measured[0]) - 1.0);
      double m = 0, v = 0;
      for (double x : e) m += x;
      m /= std::max<size_t>(1, e.size());
      for (double x : e) v += (x - m) * (x - m);
      *se = e.size() > 1 ? std::sqrt(v / static_cast<double>(e.size() - 1) / static_cast<double>(e.size())) : kNaN;
      return m;
    };
    double se_top = 0, se_bottom = 0;
    const double top = mean_error(levels.rbegin()->second, &se_top);
    const double bottom = mean_error(levels.begin()->second, &se_bottom);
    const double value = top - bottom, se = std::hypot(se_top, se_bottom);
    std::vector<Effect> points;
    if (value > kSignificant * se) points = {Effect::kAmplifierSaturation, Effect::kQuadraticDamping, Effect::kForceFactor};
    s.evidence.push_back(Make("first_harmonic_vs_amplitude",
                              "the base model's |C_1| is off by " + FormatFigure(100 * top) + " % at " +
                                  FormatFigure(levels.rbegin()->first) + " V and " + FormatFigure(100 * bottom) + " % at " +
                                  FormatFigure(levels.begin()->first) + " V (mean over frequencies)",
                              value, se, points));
  }

  // Time-domain residual near contacts against elsewhere, over the contacting records.
  s.residual_rms_near_contacts = s.residual_rms_elsewhere = kNaN;
  {
    double near_sum = 0, far_sum = 0, window_sum = 0;
    size_t near_n = 0, far_n = 0, windows = 0;
    for (size_t i = 0; i < analyses.size(); ++i) {
      const RecordAnalysis& a = analyses[i];
      if (a.spikes.empty()) continue;
      const Recording* record = nullptr;
      for (const Recording& r : campaign.records)
        if (r.name == a.name) record = &r;
      if (record == nullptr) continue;
      std::vector<double> model;
      try {
        if (const auto orbit = BestMatchingOrbit(base, a, kind, orders)) model = OrbitOnRecordGrid(base, a, *orbit, kind);
      } catch (const std::exception&) {
      }
      if (model.size() < a.window.end) continue;
      double contact = 0;
      for (const Spike& spike : a.spikes) contact += spike.ContactTimeS();
      const double half_s = std::max(kMinWindowS, kWindowContactTimes * contact / static_cast<double>(a.spikes.size()));
      window_sum += half_s, ++windows;
      const auto half = static_cast<long>(half_s * a.sample_rate_hz);
      std::vector<bool> near(a.window.end, false);
      for (const Spike& spike : a.spikes)
        for (long n = static_cast<long>(spike.peak_index) - half; n <= static_cast<long>(spike.peak_index) + half; ++n)
          if (n >= 0 && n < static_cast<long>(near.size())) near[n] = true;
      for (size_t n = a.window.begin; n < a.window.end; ++n) {
        const double r = record->response[n] - a.response_offset - model[n];
        (near[n] ? near_sum : far_sum) += r * r;
        (near[n] ? near_n : far_n)++;
      }
    }
    if (near_n > 0 && far_n > 0) {
      s.contact_window_s = window_sum / static_cast<double>(windows);
      s.residual_rms_near_contacts = std::sqrt(near_sum / static_cast<double>(near_n));
      s.residual_rms_elsewhere = std::sqrt(far_sum / static_cast<double>(far_n));
      const double ratio = s.residual_rms_near_contacts / s.residual_rms_elsewhere;
      std::vector<Effect> points;
      if (ratio > kSignificant) points = {Effect::kContactDamping, Effect::kHertzianContact};
      s.evidence.push_back(Make("contact_windows",
                                "the time-domain residual is " + FormatFigure(ratio) + " times larger within +-" +
                                    FormatFigure(1e3 * s.contact_window_s) + " ms of the impacts than elsewhere",
                                ratio, 0.0, points));
    }
  }
  return s;
}

}  // namespace strokelab::internal
