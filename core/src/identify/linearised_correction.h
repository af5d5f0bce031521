// A record's sampling correction (fit_orbit.h SamplingCorrection) as a linear function of the fit's
// parameters theta about where it was last computed: the paper fit's residuals carry its slopes.
//
// The correction is what the record's grid makes of the model's impacts, and it moves with where their
// kinks fall between two samples. Where a period is a whole number of samples, every period samples
// them at the same place, and the correction moves by tens of standard errors when a contact moves by
// one sample. Held frozen during each solve and refreshed between solves, the fit settled where the
// orbit's continuous-time harmonics alone were stationary. That is not the optimum: on a gen2 control
// seen through an accelerometer at 44.1 kHz (9706, every drive frequency a whole number of samples a
// period) the fit ended with k_s 16 standard errors below the truth and a residual variance of 1.77
// (2.06 without its hum, against 1.07 at the truth). Solves with the slopes from the frozen solves'
// end (fit_refine.cc) find the optimum of the model as the grid samples it: there 1.04, with every
// parameter within 1.1 standard errors of the truth.
#pragma once

#include <complex>
#include <functional>
#include <span>
#include <vector>

#include "strokelab/identify/fit_orbit.h"

namespace strokelab::internal {

// The fit's solves with the slopes: each from the last one's end with the slopes taken there, at most
// kSlopeSolves, while the chi-square at the corrections taken at each end falls by more than
// kSlopeChi2Tolerance (a tenth of a standard error moves it by 0.01); the end of least chi-square is
// kept. The correction is not smooth where an impact's kink crosses a sample, and such solves can
// alternate between ends about half a standard error apart (seen in the extended fit, on
// ExtendedFitTest's k3 campaign, when it took the slopes too).
inline constexpr int kSlopeSolves = 4;
inline constexpr double kSlopeChi2Tolerance = 0.01;

struct LinearisedCorrection {
  std::vector<double> theta0;
  std::vector<std::complex<double>> at;                   // [h - 1] at theta0 [response units]
  std::vector<std::vector<std::complex<double>>> slopes;  // [j][h - 1] per unit theta_j; empty: held
  // Correction h (0-based) at theta: at + slopes (theta - theta0).
  std::complex<double> At(int h, const double* theta) const;
};

// The correction at theta on the model's orbit through `anchor` (zero where that orbit is not found),
// with central-difference slopes if asked, where that orbit touches a stop (the impacts' kinks are
// what moves between samples; a smooth orbit's correction is far below the noise). A slope that cannot
// be evaluated (no orbit at a step) is zero.
LinearisedCorrection LineariseCorrection(const std::function<ActuatorModel(const double*)>& decode,
                                         std::span<const double> theta, const RecordAnalysis& record,
                                         const Anchor& anchor, ResponseKind kind, int orders, bool with_slopes);

}  // namespace strokelab::internal
