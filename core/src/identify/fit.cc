// The fit pipeline of fit.h: the paper's procedure (section 4) made robust. Its steps are in
// fit_drive.cc and fit_record.cc (1), fit_stages.cc (2, 3) and fit_refine.cc (4); fit_internal.h
// lists the files.
#include "strokelab/identify/fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "fit_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/parallel_for.h"
#include "strokelab/identify/fit_orbit.h"
#include "strokelab/model/model.h"

namespace strokelab {
namespace fit_internal {
namespace {

constexpr double kTable2ContactStiffness = 1.3e6;  // k_s [N/m], start when no spike gives a contact time

}  // namespace
}  // namespace fit_internal

std::vector<RecordAnalysis> AnalyseCampaign(const Campaign& campaign, const FitOptions& options,
                                            std::vector<std::string>* warnings) {
  using fit_internal::Format;
  Validate(options);
  if (campaign.records.empty()) throw InputError("records", "the campaign holds no records");
  std::vector<const Recording*> stepped;
  for (const Recording& record : campaign.records) {
    if (!record.broadband) {
      stepped.push_back(&record);
    } else if (warnings != nullptr) {
      warnings->push_back("record " + record.name + " is broadband: not used (stepped-sine records only)");
    }
  }
  if (stepped.empty())
    throw InputError("records",
                     "the campaign holds no stepped-sine record (broadband campaigns are fitted and diagnosed by "
                     "their time series: `strokelab fit`, `strokelab diagnose` and the service's fit and diagnose "
                     "jobs)");
  // Records are independent: analysed side by side, the first error (in campaign order) re-thrown.
  std::vector<RecordAnalysis> analyses(stepped.size());
  ParallelFor(stepped.size(), [&](size_t i) { analyses[i] = AnalyseRecord(*stepped[i], campaign.response, options); });
  for (const RecordAnalysis& a : analyses) {
    const double drift = a.drive.frequency_hz / a.nominal_frequency_hz - 1.0;
    if (std::abs(drift) > 1e-3 && warnings != nullptr)
      warnings->push_back("record " + a.name + ": the drive is at " + Format(a.drive.frequency_hz) +
                          " Hz, the manifest says " + Format(a.nominal_frequency_hz) + " Hz");
  }
  return analyses;
}

FitResult FitCampaign(const Campaign& campaign, const FitOptions& options) {
  const auto clock_start = std::chrono::steady_clock::now();
  std::vector<std::string> warnings;
  const std::vector<RecordAnalysis> analyses = AnalyseCampaign(campaign, options, &warnings);
  FitResult result = FitAnalysed(analyses, campaign.response, campaign.absolute_scale, options);
  result.warnings.insert(result.warnings.begin(), warnings.begin(), warnings.end());
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return result;
}

namespace {

// Where refined records that touch the stop sample every drive period alike (fit_orbit.h), that the
// standard errors understate, and at which drive frequencies; nothing where none does. Measured with
// tests/core/paper_fit_zscore_study.py (51.2 kHz, 40 campaigns a run): the z-scores' RMS with records at
// 5 and 8 Hz (10,240 and 6,400 samples a period) 1.40 (`synth`, seeds 4081-4120), 1.29 (`synth`,
// 4121-4160) and 1.16 (the second generator, tools/gen2, 4121-4160); 1.04 with those two moved to 5.0371
// and 8.0917 Hz (4081-4120), and with every frequency off a whole number of samples 0.98, 1.08 and 1.08.
std::optional<std::string> AlikePeriodsWarning(std::span<const RecordAnalysis> analyses, const FitResult& result) {
  std::vector<double> frequencies_hz;
  double sample_rate_hz = 0.0;
  for (size_t i = 0; i < analyses.size(); ++i) {
    const RecordFit& fit = result.records[i];
    const bool touches = fit.model_contacts_per_period > 0.0;
    if (!fit.used_refinement || !touches || !internal::SamplesEveryPeriodAlike(analyses[i])) continue;
    frequencies_hz.push_back(analyses[i].drive.frequency_hz);
    sample_rate_hz = analyses[i].sample_rate_hz;
  }
  if (frequencies_hz.empty()) return std::nullopt;
  std::sort(frequencies_hz.begin(), frequencies_hz.end());
  std::string list, last;  // each frequency once, as written
  for (double f : frequencies_hz) {
    const std::string written = fit_internal::Format(f);
    if (written != last) list += (list.empty() ? "" : ", ") + written;
    last = written;
  }
  return "records at " + list + " Hz touch the stop with a drive period of a whole number of samples at " +
         fit_internal::Format(sample_rate_hz) +
         " Hz: every period samples the impacts at the same place, and the standard errors understate (on"
         " campaigns of two independent generators the z-scores' RMS was 1.16-1.40 with such records, 0.98-1.08"
         " without); drive frequencies whose period is no whole number of samples avoid it";
}

}  // namespace

FitResult FitAnalysed(std::span<const RecordAnalysis> analyses, ResponseKind response, bool absolute_scale,
                      const FitOptions& options) {
  using fit_internal::Format, fit_internal::Identifiability, fit_internal::kTable2ContactStiffness;
  Validate(options);
  const auto clock_start = std::chrono::steady_clock::now();
  if (analyses.empty()) throw InputError("records", "no stepped-sine record to fit");
  FitResult result;
  result.model_kind = options.model;
  result.response = response;
  result.absolute_scale = absolute_scale;
  result.mass_kg = options.mass_kg;
  // Step 2.
  result.linear = FitClearRecords(analyses, response, options);
  const FrfFitSummary& linear = result.linear.summary;
  if (result.linear.distortion_limit > options.max_clear_distortion)
    result.warnings.push_back("fewer than 3 records are clear of the stop (no spike, harmonic distortion below " +
                              Format(100 * options.max_clear_distortion) + " %): paper Eq. 3 on the " +
                              std::to_string(result.linear.records.size()) +
                              " spike-free records with distortion up to " +
                              Format(100 * result.linear.distortion_limit) + " %, a start for the refinement");
  if (!linear.converged) {
    if (!(linear.stiffness_n_per_m > 0) || !(linear.damping_n_s_per_m > 0) || linear.gain_n_per_v == 0)
      throw NumericalError("the linear fit (paper Eq. 3) of the clear records failed: " + linear.report);
    result.warnings.push_back("the linear fit (paper Eq. 3) did not converge: " + linear.report);
  }

  ActuatorModel start = PaperModel();
  start.mass_kg = options.mass_kg;
  start.stiffness_n_per_m = linear.stiffness_n_per_m;
  start.damping_n_s_per_m = linear.damping_n_s_per_m;
  start.gain_n_per_v = linear.gain_n_per_v;
  start.lower_stop_m = ActuatorModel::kNoLowerStop;
  start.contact_damping_n_s_per_m = 0.0;

  // Step 3.
  result.contact = EstimateContact(analyses, response, linear, options);
  const ContactEstimate& contact = result.contact;
  std::vector<size_t> used;
  if (options.model == FitModelKind::kLinear) {
    used = result.linear.records;
    if (!contact.records.empty())
      result.warnings.push_back(std::to_string(contact.records.size()) +
                                " records are not clear of the stop: the linear model leaves them out of the fit");
  } else if (contact.records.empty()) {
    used = result.linear.records;
    result.warnings.push_back("no record reaches the stop: d and k_s are not identifiable (|d| > " +
                              Format(contact.largest_clear_amplitude_m) + " m, the largest displacement amplitude)");
  } else {
    for (size_t i = 0; i < analyses.size(); ++i) used.push_back(i);
    if (contact.lower_stop)
      start.lower_stop_m = -contact.stop_distance_m;
    else
      start.upper_stop_m = contact.stop_distance_m;
    if (contact.spikes > 0) {
      start.contact_stiffness = contact.stiffness_n_per_m;
    } else {
      start.contact_stiffness = kTable2ContactStiffness;
      result.warnings.push_back("no impact spike gave a contact time: k_s starts from paper Table 2 (" +
                                Format(kTable2ContactStiffness) + " N/m)");
    }
    if (!contact.lower_stop) result.warnings.push_back("impact spikes are negative: the stop is on the upper side");
    const double distance = fit_internal::StopDistanceStart(analyses, response, start, contact, options.harmonic_orders);
    result.contact.stop_distance_m = distance;
    if (contact.lower_stop)
      start.lower_stop_m = -distance;
    else
      start.upper_stop_m = distance;
  }
  // Step 4.
  result.staged = start;
  RefineParameters(analyses, response, start, used, options, &result);
  for (size_t i : result.linear.records) result.records[i].used_linear = true;
  for (size_t i : contact.records) result.records[i].used_contact = result.records[i].spikes > 0;
  const bool stop = result.model.HasLowerStop() || result.model.HasUpperStop();
  result.identifiability = Identifiability(options.model, response, absolute_scale, stop);
  if (!result.refinement.converged)
    result.warnings.push_back("the refinement did not converge: " + result.refinement.report);
  if (const std::optional<std::string> alike = AlikePeriodsWarning(analyses, result)) result.warnings.push_back(*alike);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return result;
}

const FitParameter* FitResult::Find(std::string_view name) const {
  for (const FitParameter& p : parameters)
    if (p.name == name) return &p;
  return nullptr;
}

}  // namespace strokelab
