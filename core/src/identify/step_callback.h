// A Ceres iteration callback that runs an action after each successful step: the fit and the
// extended fit move their records' anchors to the new iterate's orbits there, so that the next
// evaluations start next to them (and stay on each record's branch). And the solver options both
// refinements share.
#pragma once

#include <ceres/ceres.h>

#include <algorithm>
#include <functional>
#include <thread>
#include <utility>

#include "strokelab/base/cancel.h"

namespace strokelab::internal {

class AfterSuccessfulStep : public ceres::IterationCallback {
 public:
  explicit AfterSuccessfulStep(std::function<void()> action) : action_(std::move(action)) {}

  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override {
    if (summary.step_is_successful) action_();
    return ceres::SOLVER_CONTINUE;
  }

 private:
  std::function<void()> action_;
};

// Ends a solve between iterations once the calling thread's cancel flag is raised (cancel.h): Ceres'
// own threads see no flag, so the solve is stopped here rather than inside an evaluation. Callers
// learn of it at their next poll (a ParallelFor, the engines, the task's end).
class AbortWhenCancelled : public ceres::IterationCallback {
 public:
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    return CancelRequested() ? ceres::SOLVER_ABORT : ceres::SOLVER_CONTINUE;
  }
};

// Dense least squares on all cores, silent, with `callback` after each iteration and the state
// updated every iteration (the callback reads it). Stopping tests (Ceres): |d cost| / cost < 1e-7,
// |d theta| < 1e-9 (|theta| + 1e-9); theta ~ 1, so 1e-9 is a relative change of 1e-9 in each parameter.
// 1e-7 of the cost: where the model fits, cost ~ M / 2 (M residuals of unit variance), so a step that
// lowers chi-square by less than 1e-7 M (5e-5 for 500 residuals) moves no parameter by more than
// ~0.01 of its standard error. A tighter tolerance only chases the cost's own numerical noise (the
// flow's error control leaves ~1e-8 of it), step after rejected step.
inline ceres::Solver::Options RefinementSolverOptions(int max_iterations, ceres::IterationCallback* callback) {
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.max_num_iterations = max_iterations;
  solver.num_threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  solver.logging_type = ceres::SILENT;
  solver.function_tolerance = 1e-7;
  solver.parameter_tolerance = 1e-9;
  solver.gradient_tolerance = 1e-12;
  solver.update_state_every_iteration = true;
  static AbortWhenCancelled abort_when_cancelled;  // stateless: one for every solve
  solver.callbacks.push_back(&abort_when_cancelled);  // first: a cancelled solve runs no other callback
  solver.callbacks.push_back(callback);
  return solver;
}

}  // namespace strokelab::internal
