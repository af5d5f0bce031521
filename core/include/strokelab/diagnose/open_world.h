// The open-world test of the diagnosis (diagnose.h, Unexplained): whether what a model leaves on the
// held-out records is noise, and if not, where it is. Public for its tests; DiagnoseCampaign runs it.
#pragma once

#include <optional>
#include <span>
#include <vector>

#include "strokelab/diagnose/diagnose.h"
#include "strokelab/identify/fit.h"

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

}  // namespace strokelab::internal
