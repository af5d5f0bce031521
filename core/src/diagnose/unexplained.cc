// The open-world test (diagnose.h, Unexplained): is what the diagnosed model leaves on the held-out
// records noise? If not, where is it and what does it look like?
#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <numbers>
#include <span>
#include <sstream>

#include "diagnose_internal.h"
#include "strokelab/base/chi_square.h"
#include "strokelab/base/parallel_for.h"

namespace strokelab::internal {
namespace {

constexpr double kUndefined = std::numeric_limits<double>::quiet_NaN();
constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kDegreesPerRadian = 180.0 / std::numbers::pi;
constexpr size_t kMaxPlaces = 8;
constexpr int kPhaseSamples = 360;  // residual waveform over one drive period, 1 degree apart
// Worst harmonics that lie within this relative spread in Hz, across records of different drive
// frequencies, point to one resonance rather than to the drive.
constexpr double kSameFrequencySpread = 0.15;

double WrapDegrees(double degrees) { return std::fmod(std::fmod(degrees, 360.0) + 360.0, 360.0); }

// The residual waveform sum_h Re(dC_h e^{j h theta}) over one drive period: where |r| peaks [deg].
double ResidualPeakPhaseDeg(const RecordMatch& m) {
  double best = -1.0, best_theta = 0.0;
  for (int k = 0; k < kPhaseSamples; ++k) {
    const double theta = kTwoPi * k / kPhaseSamples;
    double r = 0.0;
    for (size_t h = 0; h < m.measured.size() && h < m.model.size(); ++h)
      if (m.harmonic_chi2[h] > 0)
        r += std::real((m.measured[h] - m.model[h]) * std::polar(1.0, static_cast<double>(h + 1) * theta));
    if (std::abs(r) > best) best = std::abs(r), best_theta = theta;
  }
  return best_theta * kDegreesPerRadian;
}

// Circular mean of the impacts' drive phases theta = 2 pi f n / fs + phi [deg]; NaN without impacts.
double ImpactPhaseDeg(const RecordAnalysis& a) {
  if (a.spikes.empty()) return kUndefined;
  std::complex<double> sum = 0.0;
  for (const Spike& s : a.spikes) {
    const double cycles = a.drive.frequency_hz * static_cast<double>(s.peak_index) / a.sample_rate_hz;
    sum += std::polar(1.0, kTwoPi * (cycles - std::floor(cycles)) + a.drive.phase_rad);
  }
  return WrapDegrees(std::arg(sum) * kDegreesPerRadian);
}

// Words for what the places share: one frequency in Hz across drive frequencies (a resonance), the
// fundamental, or harmonics; and where in the period against the impacts.
std::string Describe(const Unexplained& u) {
  std::ostringstream out;
  out << "the diagnosed model misses the held-out records by " << FormatFigure(u.misfit_to_noise)
      << " times the noise (chi-square " << FormatFigure(u.heldout_chi2, 4) << " against " << FormatFigure(u.expected_chi2, 4)
      << " from noise and the fitted parameters' own error, p = " << FormatFigure(u.p_value, 2) << ")";
  if (u.places.empty()) {
    out << ", spread over the records with none beyond noise on its own";
    return out.str();
  }
  out << "; worst in " << u.places.size() << " record" << (u.places.size() > 1 ? "s" : "") << " (";
  for (size_t i = 0; i < u.places.size() && i < 3; ++i)
    out << (i ? ", " : "") << u.places[i].record << " at " << FormatFigure(u.places[i].frequency_hz) << " Hz, "
        << FormatFigure(u.places[i].amplitude_v) << " V: " << FormatFigure(u.places[i].chi2_per_residual) << " x noise";
  out << (u.places.size() > 3 ? ", ..." : "") << ")";
  double lo = std::numeric_limits<double>::infinity(), hi = 0, drive_lo = lo, drive_hi = 0;
  int fundamental = 0;
  for (const auto& p : u.places) {
    lo = std::min(lo, p.worst_harmonic_hz), hi = std::max(hi, p.worst_harmonic_hz);
    drive_lo = std::min(drive_lo, p.frequency_hz), drive_hi = std::max(drive_hi, p.frequency_hz);
    fundamental += p.worst_harmonic == 1;
  }
  const bool several_drives = drive_hi > drive_lo * (1 + kSameFrequencySpread);
  if (fundamental == static_cast<int>(u.places.size())) {
    out << "; at the drive frequency itself (harmonic 1): a force the model lacks that follows the drive";
  } else if (several_drives && hi <= lo * (1 + kSameFrequencySpread)) {
    out << "; near " << FormatFigure(0.5 * (lo + hi)) << " Hz whatever the drive frequency: a resonance near that "
        << "frequency that the model lacks (a mode that rings when excited)";
  } else {
    out << "; in harmonics";
    for (size_t i = 0; i < u.places.size() && i < 3; ++i) out << (i ? "," : "") << " " << u.places[i].worst_harmonic;
    out << " of the drive";
  }
  const Unexplained::Place& worst = u.places.front();
  if (std::isfinite(worst.impact_phase_deg)) {
    const double lag = WrapDegrees(worst.residual_peak_phase_deg - worst.impact_phase_deg + 180.0) - 180.0;
    out << "; in " << worst.record << " the residual peaks " << FormatFigure(std::abs(lag)) << " degrees of the period "
        << (lag >= 0 ? "after" : "before") << " the impacts";
  } else {
    out << "; in " << worst.record << " the residual peaks at drive phase " << FormatFigure(worst.residual_peak_phase_deg)
        << " degrees, with no impact";
  }
  return out.str();
}

// One record's test size: the open-world test's kUnexplainedP shared over the records (Bonferroni), so
// that a campaign's noise alone marks any record with at most that probability.
double PerRecordTestSize(size_t records) {
  return kUnexplainedP / static_cast<double>(std::max<size_t>(1, records));
}

// The parameters' error's mean share of a residual's variance over the records, 1 + P / M (M: the fit
// records' residuals).
double MeanInflation(const std::vector<RecordMatch>& matches, size_t parameters) {
  double fit_residuals = 0;
  for (const RecordMatch& m : matches)
    if (!m.heldout && std::isfinite(m.chi2)) fit_residuals += m.residuals;
  return 1.0 + static_cast<double>(parameters) / std::max(1.0, fit_residuals);
}

// The held-out chi-square of `matches` against noise alone (Unexplained's figures, no places), the
// parameters' error counted record by record where `leverage` is given, else by its mean; false when
// there is nothing held out to test.
bool HeldOutFigures(const std::vector<RecordMatch>& matches, size_t parameters, const HeldOutLeverage* leverage,
                    Unexplained* u) {
  std::vector<double> harmonic_sum, harmonic_count;
  for (const RecordMatch& m : matches) {
    if (!std::isfinite(m.chi2)) continue;
    if (m.heldout) {
      u->heldout_chi2 += m.chi2;
      u->heldout_residuals += m.residuals;
    }
    harmonic_sum.resize(std::max(harmonic_sum.size(), m.harmonic_chi2.size()), 0.0);
    harmonic_count.resize(harmonic_sum.size(), 0.0);
    for (size_t h = 0; h < m.harmonic_chi2.size(); ++h)
      if (m.harmonic_chi2[h] > 0) harmonic_sum[h] += m.harmonic_chi2[h], harmonic_count[h] += 2;
  }
  // A model that finds no orbit for a held-out record misses it beyond any noise.
  bool orbit_missing = false;
  for (const RecordMatch& m : matches) orbit_missing |= m.heldout && !std::isfinite(m.chi2);
  if (u->heldout_residuals == 0 && !orbit_missing) return false;
  const double k = std::max(1, u->heldout_residuals);
  if (leverage) {
    // The test is on leverage->chi2 ~ chi-square(R); the plain chi-square crosses it where it exceeds
    // the quantile by what the parameters' error explains of these residuals.
    u->expected_chi2 = std::max(leverage->expected_chi2, k);
    u->threshold_chi2 = ChiSquareQuantile(kUnexplainedP, k) + (u->heldout_chi2 - leverage->chi2);
    u->p_value = orbit_missing ? 0.0 : ChiSquareUpperTail(leverage->chi2, k);
  } else {
    const double inflation = MeanInflation(matches, parameters);
    u->expected_chi2 = inflation * k;
    u->threshold_chi2 = inflation * ChiSquareQuantile(kUnexplainedP, k);
    u->p_value = orbit_missing ? 0.0 : ChiSquareUpperTail(u->heldout_chi2 / inflation, k);
  }
  u->misfit_to_noise = std::sqrt(u->heldout_chi2 / u->expected_chi2);
  for (size_t h = 0; h < harmonic_sum.size(); ++h)
    u->harmonic_chi2_per_residual.push_back(harmonic_count[h] > 0 ? harmonic_sum[h] / harmonic_count[h] : kUndefined);
  return true;
}

// A record's place: where it is and how its harmonics miss (`a`: its analysis, may be null).
Unexplained::Place PlaceOf(const RecordMatch& m, const RecordAnalysis* a) {
  Unexplained::Place p;
  p.record = m.name;
  p.frequency_hz = m.frequency_hz, p.amplitude_v = m.amplitude_v;
  p.heldout = m.heldout;
  p.chi2_per_residual = m.residuals > 0 ? m.chi2 / m.residuals : kUndefined;
  if (!m.harmonic_chi2.empty()) {
    p.worst_harmonic = static_cast<int>(std::max_element(m.harmonic_chi2.begin(), m.harmonic_chi2.end()) -
                                        m.harmonic_chi2.begin()) + 1;
    p.worst_harmonic_hz = p.worst_harmonic * m.frequency_hz;
    p.residual_peak_phase_deg = ResidualPeakPhaseDeg(m);
  }
  p.impact_phase_deg = a ? ImpactPhaseDeg(*a) : kUndefined;
  return p;
}

}  // namespace

bool HeldOutWithinNoise(const std::vector<RecordMatch>& matches) {
  double chi2 = 0;
  int residuals = 0;
  for (const RecordMatch& m : matches) {
    if (!m.heldout) continue;
    if (!std::isfinite(m.chi2)) return false;  // no orbit: beyond any noise
    chi2 += m.chi2, residuals += m.residuals;
  }
  return residuals == 0 || ChiSquareUpperTail(chi2, residuals) >= kUnexplainedP;
}

std::optional<Unexplained> FindUnexplained(const std::vector<RecordMatch>& matches,
                                           std::span<const RecordAnalysis> analyses, size_t parameters,
                                           const HeldOutLeverage* leverage) {
  Unexplained u;
  if (!HeldOutFigures(matches, parameters, leverage, &u) || u.p_value >= kUnexplainedP) return std::nullopt;
  const double inflation = MeanInflation(matches, parameters);
  const double per_record_p = PerRecordTestSize(matches.size());
  for (size_t i = 0; i < matches.size(); ++i) {
    const RecordMatch& m = matches[i];
    if (m.residuals == 0 || !std::isfinite(m.chi2)) continue;
    // A held-out record's own test counts the parameters' error there; a fit record's, their mean.
    const bool own = leverage && i < leverage->record_chi2.size() && std::isfinite(leverage->record_chi2[i]);
    const double judged = own ? leverage->record_chi2[i] : m.chi2 / inflation;
    if (ChiSquareUpperTail(judged, m.residuals) >= per_record_p) continue;
    u.places.push_back(PlaceOf(m, i < analyses.size() ? &analyses[i] : nullptr));
  }
  std::sort(u.places.begin(), u.places.end(),
            [](const auto& a, const auto& b) { return a.chi2_per_residual > b.chi2_per_residual; });
  if (u.places.size() > kMaxPlaces) u.places.resize(kMaxPlaces);
  u.description = Describe(u);
  return u;
}

std::string WorseThanTheBase(const std::vector<RecordMatch>& base, const std::vector<RecordMatch>& model) {
  const double z = NormalUpperQuantile(PerRecordTestSize(model.size()));
  const double allowed = kWorseThanTheBaseVariance * z * z;
  const RecordMatch* worst = nullptr;
  double worst_rise = allowed, before = 0.0;
  for (size_t i = 0; i < model.size() && i < base.size(); ++i) {
    const RecordMatch& m = model[i];
    if (m.residuals == 0 || base[i].residuals == 0 || !std::isfinite(m.chi2) || !std::isfinite(base[i].chi2)) continue;
    if (m.chi2 - base[i].chi2 > worst_rise) worst = &m, worst_rise = m.chi2 - base[i].chi2, before = base[i].chi2;
  }
  if (!worst) return "";
  std::ostringstream out;
  out << "misses " << worst->name << " (" << FormatFigure(worst->frequency_hz) << " Hz, "
      << FormatFigure(worst->amplitude_v) << " V) by a chi-square " << FormatFigure(worst_rise) << " above the base "
      << "model's (" << FormatFigure(before) << " -> " << FormatFigure(worst->chi2) << "), beyond the "
      << FormatFigure(allowed) << " noise allows a model that explains what the base misses: it stands in for part "
      << "of what no library effect explains, and is not named";
  return out.str();
}

std::optional<Unexplained> FindRingAboveHarmonics(std::span<const Recording> records,
                                                  std::span<const RecordAnalysis> analyses,
                                                  const std::vector<RecordMatch>& matches, const ActuatorModel& model,
                                                  ResponseKind kind, int orders, size_t parameters) {
  std::vector<Unexplained::Place> places(analyses.size());
  ParallelFor(analyses.size(), [&](size_t i) {
    const RecordAnalysis& a = analyses[i];
    const auto record = std::find_if(records.begin(), records.end(), [&](const Recording& r) { return r.name == a.name; });
    if (a.spikes.empty() || i >= matches.size() || record == records.end()) return;
    places[i] = PlaceOf(matches[i], &a);
    try {
      FindRinging(*record, a, model, kind, orders, &places[i]);
    } catch (const std::exception&) {
      // no ringing figures for this record
    }
  });
  const size_t impacting = static_cast<size_t>(std::count_if(analyses.begin(), analyses.end(),
                                                             [](const RecordAnalysis& a) { return !a.spikes.empty(); }));
  std::erase_if(places, [](const Unexplained::Place& p) { return !std::isfinite(p.ring_frequency_hz); });
  std::sort(places.begin(), places.end(), [](const auto& a, const auto& b) { return a.ring_to_noise > b.ring_to_noise; });
  Unexplained u;
  if (!HeldOutFigures(matches, parameters, nullptr, &u)) u.misfit_to_noise = kUndefined;
  const size_t rings = places.size();
  u.places = std::move(places);
  if (u.places.size() > kMaxPlaces) u.places.resize(kMaxPlaces);
  // A mode's ring, confirmed as the description confirms it: two of the strongest rings, in records of
  // different drive frequencies, at one frequency in Hz.
  if (DescribeRinging(u, kind, kRingPlaces).empty()) return std::nullopt;
  std::ostringstream out;
  if (u.p_value >= kUnexplainedP)
    out << "the model matches the fitted harmonics of the held-out records within noise (chi-square "
        << FormatFigure(u.heldout_chi2, 4) << " against " << FormatFigure(u.expected_chi2, 4)
        << " from noise and the fitted parameters' own error), but ";
  out << "above harmonic " << orders << " the residual rings after the impacts in " << rings << " of the "
      << impacting << " records with impacts";
  u.description = out.str();
  return u;
}

}  // namespace strokelab::internal
