// The broadband diagnosis's evaluations of a model on a campaign's parts (broadband_diagnose.h steps 2,
// 4 and 6): the model held, only the segments' starts, offsets and hum fitted.
#pragma once

#include <vector>

#include "strokelab/diagnose/broadband_diagnose.h"
#include "strokelab/identify/broadband_fit.h"

namespace strokelab::internal {

// The parts with the pointers the fits take.
struct BroadbandSplit : BroadbandParts {
  std::vector<const Recording*> fit_pointers, heldout_pointers;
  std::vector<BroadbandFitOptions::NoiseLevel> noise;  // the records', with their sizes
  explicit BroadbandSplit(BroadbandParts parts);
  BroadbandSplit(const BroadbandSplit&) = delete;  // the pointers point into this object
};

// `model` on the split's fit parts (or held-out parts, with `heldout`), with only their segments' starts,
// offsets and hum fitted, from `warm`'s (a fit of the same parts; may be null: a fresh start). `series`
// keeps the residual series (BroadbandFitOptions::keep_series).
BroadbandFitResult EvaluateOnParts(const ActuatorModel& model, const BroadbandSplit& split, bool heldout,
                                   ResponseKind kind, bool series, double max_seconds, const BroadbandFitResult* warm);

// `model` on the held-out parts from two starts, the lower chi-square kept: the motion continued from
// `fit`, a fit of the fit parts at `model` (a record's held-out part starts where its fit part ends), and
// a fresh start. The held-out chi-square is a minimum over those unknowns, and through impacts either
// start can end in a valley of its own: on a second stop's campaign (broadband study 8414, tuned on) the
// continued motion left the second stop's candidate (d_upper 0.2 % off, its fit parts in a valley of
// their own) at a held-out chi-square of 1.84e6, where the fresh start reached 7,112 (noise alone: at
// most 6,610).
BroadbandFitResult EvaluateHeldOut(const ActuatorModel& model, const BroadbandSplit& split, ResponseKind kind,
                                   bool series, double max_seconds, const BroadbandFitResult& fit);

}  // namespace strokelab::internal
