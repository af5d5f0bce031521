// Progress of a long computation made of stages (the diagnosis: the records' analysis, the base fit,
// the signatures, one fit per candidate effect, the pair, the report's maps): what the computation
// reports (stage k of N, and where it is inside the stage), and the clock its caller keeps to add
// the elapsed time and an estimate of the time left.
#pragma once

#include <chrono>
#include <functional>
#include <mutex>
#include <string>

namespace strokelab {

// What a computation reports at the start of each stage and, when it can, within one.
struct ProgressStage {
  int stage = 0;     // k, 1-based
  int stages = 0;    // N as planned; revised when the computation learns its plan (a stage that turns
                     // out not to be needed is passed over: k then jumps)
  std::string name;  // "candidate cubic_stiffness"
  std::string step;  // within the stage ("solve 2 (at most 8), iteration 14"); empty at its start
};
using ProgressHook = std::function<void(const ProgressStage&)>;

struct ProgressReport {
  ProgressStage stage;
  double elapsed_s = 0.0;  // since the clock started [s]
  // An estimate of the time left [s], from the stages done so far: their mean time times the stages
  // after this one, plus what is left of the mean in this one (0 once this one has run longer).
  // NaN until a stage has finished. Stages differ in cost (the analysis takes milliseconds, a
  // candidate's fit a minute), so it is rough at first and improves as stages finish.
  double eta_s = 0.0;
};

// Adds the time to a computation's stages. Safe to call from several threads.
class ProgressClock {
 public:
  ProgressClock();  // starts now
  ProgressReport Report(const ProgressStage& stage);

 private:
  using Clock = std::chrono::steady_clock;
  std::mutex mutex_;
  Clock::time_point start_, stage_start_;
  int current_ = 0;   // the stage in progress (0: none yet)
  int finished_ = 0;  // stages that ran and finished
};

// One line: "stage 4 of 12: candidate cubic_stiffness, solve 1 (at most 8), iteration 7 | 20.1 s
// elapsed, about 40 s left (estimate)".
std::string ProgressLine(const ProgressReport& report);

}  // namespace strokelab
