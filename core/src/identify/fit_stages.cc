// Steps 2 and 3 of the fit (fit.h): paper Eq. 3 on the records clear of the stop, and the contact's
// staged estimates (k_s from contact times, |d| bracketed by the records' amplitudes).
#include <algorithm>
#include <cmath>
#include <complex>
#include <cstddef>
#include <numeric>
#include <span>
#include <string>
#include <vector>

#include "fit_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/identify/fit.h"
#include "strokelab/identify/frf_fit.h"
#include "strokelab/signal/signal.h"

namespace strokelab {
namespace fit_internal {
namespace {

constexpr size_t kMinClearRecords = 3;   // paper Eq. 3 has 3 parameters
constexpr double kBracketMargin = 1.05;  // |d| start just above the largest clear amplitude

}  // namespace
}  // namespace fit_internal

// ---- Step 2 ----------------------------------------------------------------------------------------

std::complex<double> EquivalentForceFrf(std::complex<double> frf, ResponseKind kind, double frequency_hz,
                                        double mass_kg) {
  using fit_internal::Complex, fit_internal::kTwoPi;
  const double w = kTwoPi * frequency_hz;
  switch (kind) {
    case ResponseKind::kForce:
      return frf;
    case ResponseKind::kAcceleration:
      return mass_kg * frf;
    case ResponseKind::kVelocity:
      return mass_kg * Complex(0.0, w) * frf;
    case ResponseKind::kDisplacement:
      return -mass_kg * w * w * frf;
  }
  return frf;
}

LinearStage FitClearRecords(std::span<const RecordAnalysis> analyses, ResponseKind kind, const FitOptions& options) {
  using fit_internal::Format, fit_internal::kMinClearRecords;
  Validate(options);
  LinearStage stage;
  // The distortion limit: the options' when enough records are clear, else the least that admits
  // kMinClearRecords of the spike-free records.
  std::vector<double> spike_free_distortions;
  for (const RecordAnalysis& a : analyses)
    if (a.spikes.empty()) spike_free_distortions.push_back(a.distortion);
  const size_t spiky = analyses.size() - spike_free_distortions.size();
  if (spike_free_distortions.size() < kMinClearRecords) {
    throw InputError("records", std::to_string(spike_free_distortions.size()) + " of " +
                                    std::to_string(analyses.size()) + " records are free of impact spikes (" +
                                    std::to_string(spiky) +
                                    " show them): the linear fit (paper Eq. 3) needs at least 3 records clear of the "
                                    "stop");
  }
  std::sort(spike_free_distortions.begin(), spike_free_distortions.end());
  stage.distortion_limit = std::max(options.max_clear_distortion, spike_free_distortions[kMinClearRecords - 1]);
  std::vector<FrfSample> samples;
  for (size_t i = 0; i < analyses.size(); ++i) {
    const RecordAnalysis& a = analyses[i];
    if (!a.spikes.empty() || a.distortion > stage.distortion_limit) continue;
    stage.records.push_back(i);
    samples.push_back({a.drive.frequency_hz, EquivalentForceFrf(a.frf, kind, a.drive.frequency_hz, options.mass_kg)});
  }
  FrfFitOptions frf_options;
  frf_options.mass_kg = options.mass_kg;
  stage.summary = FitLinearFrf(samples, frf_options);
  return stage;
}

// ---- Step 3 ----------------------------------------------------------------------------------------

ContactEstimate EstimateContact(std::span<const RecordAnalysis> analyses, ResponseKind kind,
                                const FrfFitSummary& linear, const FitOptions& options) {
  using fit_internal::Complex, fit_internal::kBracketMargin, fit_internal::kNaN, fit_internal::kTwoPi;
  (void)kind;
  ContactEstimate e;
  const double m = options.mass_kg, k = linear.stiffness_n_per_m, c = linear.damping_n_s_per_m;
  const double g = linear.gain_n_per_v;
  std::vector<double> times, stiffness;
  double polarity = 0.0;
  // Which records bound |d|: those with impact spikes hit the stop, clear records do not. A record
  // distorted but without spikes bounds neither side: a hardening suspension distorts clear of the
  // stop, and a displacement channel's impacts can be lost in its twice-differentiated noise (a gen2
  // campaign at 20 kHz showed spikes at 0.5 V only, and its 0.35 V records, distorted by the stop,
  // put |d| at 2 mm against 0.95). When no record shows spikes at all, clear against not clear.
  const bool any_spikes =
      std::any_of(analyses.begin(), analyses.end(), [](const RecordAnalysis& a) { return !a.spikes.empty(); });
  auto hits_stop = [&](const RecordAnalysis& a) { return any_spikes ? !a.spikes.empty() : !a.clear; };
  double largest_clear = kNaN, smallest_contacting = kNaN;
  std::vector<double> contacting_amplitudes;
  for (size_t i = 0; i < analyses.size(); ++i) {
    const RecordAnalysis& a = analyses[i];
    const double w = kTwoPi * a.drive.frequency_hz;
    const double amplitude = std::abs(g) * a.drive.amplitude_v / std::abs(Complex(k - m * w * w, c * w));
    if (hits_stop(a)) {
      contacting_amplitudes.push_back(amplitude);
    } else if (a.clear && !(amplitude <= largest_clear)) {
      largest_clear = amplitude;
    }
    if (a.clear) continue;
    e.records.push_back(i);
    for (const Spike& s : a.spikes) {
      try {
        stiffness.push_back(ContactStiffnessDamped(m, s.ContactTimeS(), k, c));
        times.push_back(s.ContactTimeS());
        polarity += s.peak_height > 0 ? 1.0 : -1.0;
      } catch (const InputError&) {
        // a spike too wide for any stop stiffness: not an impact of this model
      }
    }
  }
  // The smallest contacting amplitude above the clear ones: below it the record may sit on the
  // contacting branch of a bistable response, which bounds nothing.
  for (double amplitude : contacting_amplitudes)
    if ((std::isnan(largest_clear) || amplitude > largest_clear) && !(amplitude >= smallest_contacting))
      smallest_contacting = amplitude;
  e.largest_clear_amplitude_m = largest_clear;
  e.smallest_contacting_amplitude_m = smallest_contacting;
  e.spikes = stiffness.size();
  const ContactTimeStatistics stats = ContactTimeStats(times);
  e.contact_time_s = stats.mean_s;
  e.contact_time_rsd = stats.rsd;
  if (stiffness.empty()) {
    e.stiffness_n_per_m = e.stiffness_spread_n_per_m = kNaN;
  } else {
    e.stiffness_n_per_m =
        std::accumulate(stiffness.begin(), stiffness.end(), 0.0) / static_cast<double>(stiffness.size());
    double ss = 0.0;
    for (double s : stiffness) ss += (s - e.stiffness_n_per_m) * (s - e.stiffness_n_per_m);
    e.stiffness_spread_n_per_m =
        stiffness.size() > 1 ? std::sqrt(ss / static_cast<double>(stiffness.size() - 1)) : kNaN;
  }
  // A lower stop pushes the mass up: positive spikes of m_p x'' (negative when the gain, i.e. the
  // sensor's polarity, is negative).
  e.lower_stop = polarity * (g < 0 ? -1.0 : 1.0) >= 0.0;
  if (e.records.empty()) {
    e.stop_distance_m = kNaN;
  } else if (std::isnan(largest_clear)) {
    e.stop_distance_m = smallest_contacting;
  } else if (std::isnan(smallest_contacting)) {
    e.stop_distance_m = kBracketMargin * largest_clear;
  } else {
    e.stop_distance_m = std::sqrt(largest_clear * smallest_contacting);  // the bracket's geometric middle
  }
  return e;
}

}  // namespace strokelab
