// A stepped-sine record's harmonics as residuals of a Ceres problem, with their exact Jacobian from the
// variational flow's sensitivities: the extended fit's residuals (extended_fit.h), and the stepped
// records' of a joint fit with broadband records (broadband_fit.h). Ceres stays in the identify sources.
#pragma once

#include <ceres/ceres.h>

#include <complex>
#include <span>
#include <vector>

#include "strokelab/identify/extended_fit.h"
#include "strokelab/identify/fit_orbit.h"

namespace strokelab::internal {

// Solves end when the refreshed sampling corrections moved no identifiable theta by more than this
// fraction of its standard error (a change no test on the estimate could see).
inline constexpr double kSolveTolerancePerError = 0.01;

// One record's target: its measured harmonics, the orbit the next evaluations start from, and the
// sampling correction (frozen during a solve).
struct OrbitTarget {
  const RecordAnalysis* record = nullptr;
  double weight = 1.0;  // 1 / the record's harmonic standard error (its noise's: fit_orbit.h HarmonicVariance)
  Anchor anchor;        // on the current model's orbit
  std::vector<std::complex<double>> correction;
};

// Residuals (Re, Im) of w (C_h - C_model,h - correction_h), h = 1..orders, with their exact Jacobian in
// theta (the problem's one parameter block).
class OrbitCost : public ceres::CostFunction {
 public:
  OrbitCost(const ExtendedProblem* problem, const OrbitTarget* target, ResponseKind kind, int orders);
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  const ExtendedProblem* problem_;
  const OrbitTarget* target_;
  ResponseKind kind_;
  int orders_;
  std::vector<double ActuatorModel::*> fields_;
  // The last theta and anchor whose orbit was solved, and that orbit's start (Ceres never evaluates
  // one residual block from two threads at once; the anchors move between iterations).
  mutable std::vector<double> last_theta_;
  mutable Anchor last_anchor_;
  mutable State last_start_;
};

// Each target's sampling correction at `model`, on the model's orbit through the record's anchor
// (zero where that orbit is not found), side by side.
void RefreshCorrections(const ActuatorModel& model, std::span<OrbitTarget> targets, ResponseKind kind, int orders);

}  // namespace strokelab::internal
