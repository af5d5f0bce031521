// The saturation maps of the base and the diagnosed model (diagnosis_maps.h): the grid from the
// campaign's records, the two sweeps under the diagnosis's time budget, the threshold shifts.
#include "strokelab/report/diagnosis_maps.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <functional>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "format.h"
#include "strokelab/base/cancel.h"
#include "strokelab/base/errors.h"
#include "strokelab/identify/broadband_campaign.h"
#include "strokelab/model/model_json.h"
#include "strokelab/signal/signal.h"

namespace strokelab::report {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// Sets `stop` at `deadline` unless the owner finishes first (a row or column of a smooth model can
// take seconds, so waiting for the sweep's progress calls could overrun the budget by that much), or
// as soon as the caller's own cancel flag (base/cancel.h: a cancelled job) is raised.
class Deadline {
 public:
  Deadline(Clock::time_point deadline, std::atomic<bool>* stop)
      : thread_([this, deadline, stop, outer = CurrentCancelFlag()] {
          std::unique_lock<std::mutex> lock(mutex_);
          while (!done_) {
            const Clock::time_point next = std::min(deadline, Clock::now() + std::chrono::milliseconds(50));
            if (done_cv_.wait_until(lock, next, [this] { return done_; })) break;
            if (Clock::now() >= deadline || (outer != nullptr && outer->load())) {
              stop->store(true);
              break;
            }
          }
        }) {}
  ~Deadline() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_ = true;
    }
    done_cv_.notify_all();
    thread_.join();
  }
  Deadline(const Deadline&) = delete;
  Deadline& operator=(const Deadline&) = delete;

 private:
  std::mutex mutex_;
  std::condition_variable done_cv_;
  bool done_ = false;
  std::thread thread_;  // last: starts once the members it waits on exist
};

// One model's map, or nothing with the reason in `note`.
// `points` (may be empty) hears the sweep's progress (sweep.h), from its threads one at a time.
std::optional<SweepResult> SweepOneModel(const ActuatorModel& model, const DiagnosisMaps& maps,
                                         Clock::time_point deadline, double max_seconds, std::string* note,
                                         const std::function<void(const SweepProgress&)>& points) {
  SweepSpec spec;
  spec.model = model;
  spec.frequency_hz = maps.frequency_hz;
  spec.amplitude_v = maps.amplitude_v;
  spec.threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  spec.thresholds = true;
  spec.skip_failed_units = true;  // a row or column that fails leaves a hole, not an empty page
  if (const std::optional<FieldError> error = spec.IsValid()) {
    *note = "not swept: " + error->field + ": " + error->message;
    return std::nullopt;
  }
  const std::string budget = Format("the diagnosis's time limit (max_seconds %g s)", max_seconds);
  if (Clock::now() >= deadline) {
    *note = "not swept: " + budget + " was spent before the map began";
    return std::nullopt;
  }
  const Clock::time_point start = Clock::now();
  std::atomic<bool> stop{false};
  try {
    const Deadline watch(deadline, &stop);
    return RunSweep(spec, points, &stop);
  } catch (const Cancelled&) {
    if (CancelRequested()) throw;  // the caller's flag, not the deadline
    *note = Format("cut off after %.3g s: ", SecondsSince(start)) + budget + " was spent";
  } catch (const std::exception& e) {
    *note = std::string("the sweep failed: ") + e.what();
  }
  return std::nullopt;
}

// Both models' maps over [f_lo, f_hi] x [v_lo, v_hi] (DiagnosisMaps), in what is left of the diagnosis's
// time budget after `spent_s`, reported as the last two of `stages` progress stages.
DiagnosisMaps SweepBothModels(const ActuatorModel& base, const ActuatorModel& diagnosed, double f_lo, double f_hi,
                              double v_lo, double v_hi, double spent_s, int stages, const DiagnoseOptions& options) {
  const Clock::time_point start = Clock::now();
  auto progress = [&](int stage, const std::string& name) {
    if (options.progress) options.progress({stage, stages, name, {}});
  };
  auto points_of = [&](int stage, const std::string& name) -> std::function<void(const SweepProgress&)> {
    if (!options.progress) return {};
    return [&options, stage, stages, name](const SweepProgress& p) {
      options.progress({stage, stages, name,
                        std::to_string(p.done) + " of " + std::to_string(p.total) + " grid points and columns"});
    };
  };
  DiagnosisMaps maps;
  if (options.map_frequency_points == 0 || options.map_amplitude_points == 0) {
    maps.note = "not computed (map_frequency_points or map_amplitude_points is 0)";
    return maps;
  }
  if (!(f_lo > 0 && f_hi > f_lo && v_lo > 0 && v_hi > v_lo)) {
    maps.note = "not computed: the campaign's records do not span a range of both frequency and amplitude";
    return maps;
  }
  maps.frequency_hz = {f_lo, f_hi, options.map_frequency_points, true};
  maps.amplitude_v = {v_lo, v_hi, options.map_amplitude_points, false};
  maps.same_model = ModelToJson(base) == ModelToJson(diagnosed);
  const Clock::time_point deadline =
      start + std::chrono::duration_cast<Clock::duration>(
                  std::chrono::duration<double>(std::max(0.0, options.max_seconds - spent_s)));
  const std::string grid = Format("%d x %d", options.map_frequency_points, options.map_amplitude_points);
  const std::string base_name = "map of the base model (" + grid + ")";
  progress(stages - 1, base_name);
  maps.base = SweepOneModel(base, maps, deadline, options.max_seconds, &maps.base_note, points_of(stages - 1, base_name));
  if (maps.same_model) {
    maps.diagnosed = maps.base;
    maps.diagnosed_note = maps.base_note;
  } else {
    const std::string diagnosed_name = "map of the diagnosed model (" + grid + ")";
    progress(stages, diagnosed_name);
    maps.diagnosed = SweepOneModel(diagnosed, maps, deadline, options.max_seconds, &maps.diagnosed_note,
                                   points_of(stages, diagnosed_name));
  }
  maps.seconds = SecondsSince(start);
  return maps;
}

}  // namespace

DiagnosisMaps SweepDiagnosisMaps(const Diagnosis& d, const DiagnoseOptions& options) {
  double f_lo = INFINITY, f_hi = -INFINITY, v_lo = INFINITY, v_hi = -INFINITY;
  for (const RecordMatch& r : d.before) {
    if (!std::isfinite(r.frequency_hz) || !std::isfinite(r.amplitude_v)) continue;
    f_lo = std::min(f_lo, r.frequency_hz), f_hi = std::max(f_hi, r.frequency_hz);
    v_lo = std::min(v_lo, r.amplitude_v), v_hi = std::max(v_hi, r.amplitude_v);
  }
  return SweepBothModels(d.base.model, d.model, f_lo, f_hi, v_lo, v_hi, d.seconds,
                         d.progress_stages, options);
}

DiagnosisMaps SweepBroadbandDiagnosisMaps(const BroadbandDiagnosis& d, const Campaign& campaign,
                                          const DiagnoseOptions& options) {
  double f_lo = INFINITY, f_hi = -INFINITY, v_lo = INFINITY, v_hi = -INFINITY;
  for (const Recording& r : campaign.records) {
    if (!r.broadband || r.size() < 256) continue;
    for (const FrfSample& s : BroadbandFrf(r)) f_lo = std::min(f_lo, s.frequency_hz), f_hi = std::max(f_hi, s.frequency_hz);
    v_lo = std::min(v_lo, std::sqrt(2.0) * RmsAboutMean(r.voltage_v));
    for (double u : r.voltage_v) v_hi = std::max(v_hi, std::abs(u));
  }
  return SweepBothModels(d.base.result.fit.model, d.model, f_lo, f_hi, v_lo, v_hi, d.seconds,
                         d.progress_stages, options);
}

std::vector<ThresholdShift> ThresholdShifts(const SweepResult& base, const SweepResult& diagnosed) {
  std::vector<ThresholdShift> shifts;
  for (const SaturationThreshold& b : base.saturation_threshold) {
    ThresholdShift s;
    s.frequency_hz = b.frequency_hz;
    s.base_grazing_v = b.grazing_amplitude_v;
    s.base_lowest_contact_v = b.lowest_contact_amplitude_v;
    s.diagnosed_grazing_v = s.diagnosed_lowest_contact_v = NAN;
    for (const SaturationThreshold& t : diagnosed.saturation_threshold) {
      if (std::abs(t.frequency_hz - b.frequency_hz) > 1e-9 * b.frequency_hz) continue;
      s.diagnosed_grazing_v = t.grazing_amplitude_v;
      s.diagnosed_lowest_contact_v = t.lowest_contact_amplitude_v;
      break;
    }
    shifts.push_back(s);
  }
  return shifts;
}

}  // namespace strokelab::report
