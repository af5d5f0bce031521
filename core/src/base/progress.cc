// ProgressClock and ProgressLine (progress.h).
#include "strokelab/base/progress.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace strokelab {

ProgressClock::ProgressClock() : start_(Clock::now()), stage_start_(start_) {}

ProgressReport ProgressClock::Report(const ProgressStage& stage) {
  const std::lock_guard<std::mutex> lock(mutex_);
  const Clock::time_point now = Clock::now();
  if (stage.stage > current_) {  // a new stage: the one before (if any) has finished
    if (current_ > 0) ++finished_;
    current_ = stage.stage;
    stage_start_ = now;
  }
  ProgressReport report;
  report.stage = stage;
  report.elapsed_s = std::chrono::duration<double>(now - start_).count();
  if (finished_ == 0) {
    report.eta_s = std::numeric_limits<double>::quiet_NaN();
  } else {
    // The finished stages took the time up to this stage's start.
    const double mean_s = std::chrono::duration<double>(stage_start_ - start_).count() / finished_;
    const double in_stage_s = std::chrono::duration<double>(now - stage_start_).count();
    const int after = std::max(0, stage.stages - stage.stage);
    report.eta_s = std::max(0.0, mean_s - in_stage_s) + mean_s * after;
  }
  return report;
}

namespace {

std::string Seconds(double s) {
  char text[32];
  std::snprintf(text, sizeof text, s < 10 ? "%.1f s" : "%.0f s", s);
  return text;
}

}  // namespace

std::string ProgressLine(const ProgressReport& r) {
  std::string line = "stage " + std::to_string(r.stage.stage) + " of " + std::to_string(r.stage.stages) + ": " +
                     r.stage.name;
  if (!r.stage.step.empty()) line += ", " + r.stage.step;
  line += " | " + Seconds(r.elapsed_s) + " elapsed";
  if (std::isfinite(r.eta_s)) line += ", about " + Seconds(r.eta_s) + " left (estimate)";
  return line;
}

}  // namespace strokelab
