// FitWarnings and DiagnosisWarnings (campaign_warnings.h).
#include "strokelab/jobs/campaign_warnings.h"

#include <string_view>

namespace strokelab::jobs {
namespace {

// The refinement's own warning for a parameter it left on a bound: "k_s ended on its bound (a factor
// ..." (core/src/identify/fit_refine.cc); and the extended fit's note for one it held there: "held at
// a bound of its range ..." (core/src/identify/extended_fit.cc).
constexpr std::string_view kFitOnBound = " ended on its bound";
constexpr std::string_view kHeldNote = "held at a bound";
// The broadband fit's note for a parameter that ended on a bound (core/src/identify/broadband_fit.cc).
constexpr std::string_view kBroadbandOnBound = "ended on its bound";

std::string HeldAtBound(const std::string& parameter) { return parameter + " held at a bound"; }

}  // namespace

std::vector<std::string> FitWarnings(const FitResult& fit) {
  std::vector<std::string> out;
  if (fit.refinement.ran && !fit.refinement.converged) out.push_back("fit did not converge");
  for (const std::string& w : fit.warnings) {
    const size_t at = w.find(kFitOnBound);
    if (at != std::string::npos && at > 0 && w.find(' ') == at) out.push_back(HeldAtBound(w.substr(0, at)));
  }
  return out;
}

std::vector<std::string> BroadbandFitWarnings(const strokelab::internal::BroadbandFitResult& fit) {
  std::vector<std::string> out;
  if (!fit.fit.converged) out.push_back("fit did not converge");
  if (fit.rejected) out.push_back("the records reject the fit");
  for (const FitParameter& p : fit.fit.parameters)
    if (p.note == kBroadbandOnBound) out.push_back(HeldAtBound(p.name));
  return out;
}

namespace {

// Of a diagnosis's chosen candidate: its parameters held at a bound or not identifiable, and whether
// its fit did not converge.
std::vector<std::string> CandidateWarnings(const CandidateFit& c) {
  std::vector<std::string> out;
  for (const FitParameter& p : c.parameters) {
    if (p.note.rfind(kHeldNote, 0) == 0) out.push_back(HeldAtBound(p.name));
    else if (!p.identifiable && !p.fixed) out.push_back(p.name + " not identifiable");
  }
  // A candidate whose parameters are not all identifiable counts as not converged (extended_fit.h),
  // which the lines above say; its note says NOT CONVERGED when the solves themselves did not.
  if (!c.converged && (out.empty() || c.note.find("NOT CONVERGED") != std::string::npos))
    out.insert(out.begin(), "fit did not converge (" + c.label + ")");
  return out;
}

}  // namespace

std::vector<std::string> DiagnosisWarnings(const Diagnosis& d) {
  return d.chosen < 0 ? FitWarnings(d.base) : CandidateWarnings(d.candidates[d.chosen]);
}

std::vector<std::string> BroadbandDiagnosisWarnings(const BroadbandDiagnosis& d) {
  return d.chosen < 0 ? BroadbandFitWarnings(d.base.result) : CandidateWarnings(d.candidates[d.chosen]);
}

std::vector<ResultRow> WarningRows(const std::vector<std::string>& warnings) {
  std::vector<ResultRow> rows;
  for (const std::string& w : warnings) rows.push_back({"warnings", {{"warning", w}}});
  return rows;
}

}  // namespace strokelab::jobs
