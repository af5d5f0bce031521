// Evaluations of a model on a broadband campaign's parts (diagnose/broadband_evaluation.h).
#include "strokelab/diagnose/broadband_evaluation.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <utility>

#include "strokelab/engines/variational_flow.h"

namespace strokelab::internal {
namespace {

// The held-out parts' warm start at `model`: the motion continued from the fit parts. A record's held-out
// part starts where its fit part ends (or, held out first, where the record's end would continue into
// its start: a multisine's period is its record), so its segments start from the states `model` reaches
// there, flowed by the record's own voltage from the start that `fit` (a fit of the fit parts at `model`)
// found for the fit part's last segment; the offsets are the fit parts' (the hum, whose phase runs on,
// starts at zero).
BroadbandFitResult HeldOutWarmStart(const ActuatorModel& model, const BroadbandSplit& split,
                                    const BroadbandFitResult& fit) {
  const double segment_s = BroadbandFitOptions{}.segment_s;
  BroadbandFitResult warm;
  size_t fit_segments = 0;
  for (size_t r = 0; r < split.fit.size(); ++r) {
    const Recording& part = split.fit[r];
    const Recording& heldout = split.heldout[r];
    const double fs = part.sample_rate_hz;
    const std::vector<size_t> fit_firsts = SegmentFirsts(part.size(), fs, segment_s);
    fit_segments += fit_firsts.size();
    State state = fit.segment_starts.at(fit_segments - 1);
    double t_s = static_cast<double>(fit_firsts.back()) / fs;
    std::vector<double> voltage = part.voltage_v;
    voltage.insert(voltage.end(), heldout.voltage_v.begin(), heldout.voltage_v.end());
    const SampledDrive drive{fs, voltage};
    for (size_t first : SegmentFirsts(heldout.size(), fs, segment_s)) {
      const double next_s = static_cast<double>(part.size() + first) / fs;
      try {
        state = Flow(model, drive, state, t_s, next_s, {}).end;
      } catch (const std::exception&) {
        state = State{};  // the held-out fit starts this segment from rest
      }
      t_s = next_s;
      warm.segment_starts.push_back(state);
    }
    std::vector<double> nuisance(fit.nuisance.at(r).size(), 0.0);
    nuisance[0] = fit.nuisance[r][0];
    warm.nuisance.push_back(nuisance);
  }
  return warm;
}

}  // namespace

BroadbandSplit::BroadbandSplit(BroadbandParts parts) : BroadbandParts(std::move(parts)) {
  for (const Recording& r : fit) fit_pointers.push_back(&r);
  for (const Recording& r : heldout) heldout_pointers.push_back(&r);
  for (size_t r = 0; r < names.size(); ++r) noise.push_back({noise_rms[r], fit[r].size() + heldout[r].size()});
}

BroadbandFitResult EvaluateOnParts(const ActuatorModel& model, const BroadbandSplit& split, bool heldout,
                                   ResponseKind kind, bool series, double max_seconds, const BroadbandFitResult* warm) {
  ExtendedProblem held;
  held.base = model;
  BroadbandFitOptions options;
  options.keep_series = series;
  options.max_seconds = std::max(1.0, max_seconds);
  options.warm_start = warm;
  options.noise = split.noise;
  return FitBroadband(heldout ? split.heldout_pointers : split.fit_pointers, kind, held, options);
}

BroadbandFitResult EvaluateHeldOut(const ActuatorModel& model, const BroadbandSplit& split, ResponseKind kind,
                                   bool series, double max_seconds, const BroadbandFitResult& fit) {
  const BroadbandFitResult warm = HeldOutWarmStart(model, split, fit);
  BroadbandFitResult continued = EvaluateOnParts(model, split, true, kind, series, max_seconds, &warm);
  BroadbandFitResult fresh = EvaluateOnParts(model, split, true, kind, series, max_seconds, nullptr);
  const bool fresh_better = fresh.fit.chi2 < continued.fit.chi2 || !std::isfinite(continued.fit.chi2);
  return fresh_better ? std::move(fresh) : std::move(continued);
}

}  // namespace strokelab::internal
