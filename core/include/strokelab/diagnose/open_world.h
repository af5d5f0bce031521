// The open-world test of the diagnosis (diagnose.h, Unexplained): whether what a model leaves on the
// held-out records is noise, and if not, where it is. Public for its tests; DiagnoseCampaign runs it.
#pragma once

#include <optional>
#include <span>
#include <string>
#include <vector>

#include "strokelab/diagnose/diagnose.h"
#include "strokelab/identify/fit.h"
#include "strokelab/model/model.h"

namespace strokelab::internal {

// kUnexplainedP is the test's size if the noise model held exactly (chi-square, by Wilson and
// Hilferty's approximation); its real rate on control campaigns (correct model, noise, hum, offsets,
// perturbed parameters) is measured by tests/diagnose/control_study.py and must stay below 1 in 20.
inline constexpr double kUnexplainedP = 1e-3;

// `matches`: a model on every record (RecordMatch::heldout marks the held-out ones); `analyses` the
// same records in the same order (their impacts); `parameters` the number the model fitted. Empty
// when the held-out chi-square is within noise at kUnexplainedP.
std::optional<Unexplained> FindUnexplained(const std::vector<RecordMatch>& matches,
                                           std::span<const RecordAnalysis> analyses, size_t parameters);

// The force `model` lacks over (x, v) (MissingForceSurface), from every record's measured and model
// harmonics in `matches` (response channel `kind`); missing_force.cc.
MissingForceSurface EstimateMissingForce(const ActuatorModel& model, const std::vector<RecordMatch>& matches,
                                         ResponseKind kind);
// The ringing of `record`'s residual after its impacts (Unexplained::Place's ring_* figures): the
// record less `model`'s steady state on the record's own grid, less its offset, mains hum and drive
// harmonics 1..orders, averaged over the drive periods; after the impacts, the strongest frequency
// above harmonic `orders` and the decay of its amplitude, cycle pair by cycle pair (ringing.cc).
void FindRinging(const Recording& record, const RecordAnalysis& analysis, const ActuatorModel& model, ResponseKind kind,
                 int orders, Unexplained::Place* place);

// The first `places` places' ringing in words for Unexplained::description: "; in rec rings at about
// N Hz ..." for the worst ringing record confirmed by another of a different drive frequency, or "".
std::string DescribeRinging(const Unexplained& unexplained, ResponseKind kind, size_t places);
// The places whose ringing the diagnosis looks for and describes (the worst first).
inline constexpr size_t kRingPlaces = 3;

// The open-world test above the fitted harmonics: they say nothing of what rings after the impacts at
// a frequency above harmonic `orders`. Every record with impacts is looked at (FindRinging, at
// `model`); where two of the kRingPlaces strongest rings are one mode's (DescribeRinging's
// confirmation: records of different drive frequencies, one frequency in Hz), the misfit is
// unexplained: places are the ringing records, strongest ring first, with the held-out figures of
// `matches` (a model of `parameters` fitted parameters), which the description calls within noise
// where they pass. Else empty.
std::optional<Unexplained> FindRingAboveHarmonics(std::span<const Recording> records,
                                                  std::span<const RecordAnalysis> analyses,
                                                  const std::vector<RecordMatch>& matches, const ActuatorModel& model,
                                                  ResponseKind kind, int orders, size_t parameters);

// The surface in words for Unexplained::description: "; ..." (its closest single term), or its note.
std::string DescribeMissingForce(const MissingForceSurface& surface);

}  // namespace strokelab::internal
