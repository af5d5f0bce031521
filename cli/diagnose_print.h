// The text report's pieces that the stepped-sine and the broadband diagnosis share (strokelab diagnose),
// and the broadband diagnosis's report.
#pragma once

#include <ostream>
#include <vector>

#include "strokelab/diagnose/broadband_diagnose.h"
#include "strokelab/diagnose/diagnose.h"

namespace strokelab::cli {

void PrintChosenParameters(const CandidateFit& chosen, std::ostream& out);
void PrintCandidates(const std::vector<CandidateFit>& candidates, std::ostream& out);
void PrintEvidence(const std::vector<Evidence>& evidence, std::ostream& out);
void PrintBroadbandDiagnosis(const BroadbandDiagnosis& d, std::ostream& out);

}  // namespace strokelab::cli
