// A Ceres iteration callback that runs an action after each successful step: the fit and the
// extended fit move their records' anchors to the new iterate's orbits there, so that the next
// evaluations start next to them (and stay on each record's branch).
#pragma once

#include <ceres/ceres.h>

#include <functional>
#include <utility>

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

}  // namespace strokelab::internal
