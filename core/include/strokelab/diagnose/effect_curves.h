// The named effects' characteristics with their standard errors (diagnose.h, EffectCurve), from the
// chosen candidate's fit: what DiagnoseCampaign puts in Diagnosis::curves.
#pragma once

#include <vector>

#include "strokelab/diagnose/diagnose.h"

namespace strokelab {

// Where the records reach, which the curves span: displacement [min, max] (0 included), |velocity|
// up to its largest, stop penetration up to its deepest, drive amplitude up to its largest.
struct CurveRanges {
  double min_displacement_m = 0.0, max_displacement_m = 0.0;
  double max_velocity_m_per_s = 0.0;
  double max_penetration_m = 0.0;
  double max_amplitude_v = 0.0;
  double min_frequency_hz = 0.0, max_frequency_hz = 0.0;
  std::string source;  // where the ranges come from, in words
};

// One curve per characteristic of `chosen`'s effects (K(x) once for cubic and quadratic stiffness),
// each of chosen.model with its standard error from chosen.covariance, and of `base`.
std::vector<EffectCurve> EffectCurves(const CandidateFit& chosen, const ActuatorModel& base, const CurveRanges& ranges);

}  // namespace strokelab
