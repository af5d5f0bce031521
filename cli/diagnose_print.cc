// The diagnosis's text report pieces (diagnose_print.h).
#include "diagnose_print.h"

#include <cstdio>
#include <string>

#include "format.h"

namespace strokelab::cli {

void PrintChosenParameters(const CandidateFit& chosen, std::ostream& out) {
  out << "\nfitted parameters of " << chosen.label
      << (chosen.converged ? "" : " (the fit did NOT converge: the standard errors understate the uncertainty)")
      << ":\n";
  for (const FitParameter& p : chosen.parameters)
    out << "  " << p.name << " = " << General(p.value, 6) << " +- " << General(p.standard_error, 3) << " " << p.unit
        << (p.note.empty() ? "" : "  (" + p.note + ")") << "\n";
}

void PrintCandidates(const std::vector<CandidateFit>& candidates, std::ostream& out) {
  out << "\ncandidates (held-out gain in residual variances; named when > the threshold):\n";
  char line[256];
  std::snprintf(line, sizeof line, "  %-42s %12s %12s %10s %10s %8s\n", "candidate", "heldout gain", "fit gain",
                "nrmse", "held out", "seconds");
  out << line;
  for (const CandidateFit& c : candidates) {
    std::snprintf(line, sizeof line, "  %-42s %12s %12s %10s %10s %8s\n", c.label.c_str(),
                  General(c.heldout_gain, 4).c_str(), General(c.fit_gain, 4).c_str(), General(c.figures.nrmse, 4).c_str(),
                  General(c.figures.heldout_nrmse, 4).c_str(), General(c.seconds, 3).c_str());
    out << line;
    if (!c.note.empty() && !c.fitted) out << "    " << c.note << "\n";
    if (!c.decision.empty()) out << "    " << c.decision << "\n";
  }
}

void PrintEvidence(const std::vector<Evidence>& evidence, std::ostream& out) {
  out << "\nevidence:\n";
  for (const Evidence& e : evidence) {
    std::string points;
    for (Effect effect : e.points_to) points += (points.empty() ? "" : ", ") + std::string(Info(effect).id);
    out << "  [" << e.kind << "] " << e.summary << (points.empty() ? "" : "  -> " + points) << "\n";
  }
}

void PrintBroadbandDiagnosis(const BroadbandDiagnosis& d, std::ostream& out) {
  out << d.conclusion << "\n";
  out << "diagnosed model: " << d.model_note << "\n";
  for (const std::string& w : d.warnings) out << "warning: " << w << "\n";
  out << "\n";
  if (d.unexplained)
    for (const BroadbandUnexplained::Place& p : d.unexplained->places)
      out << "  unexplained in " << p.record << ": chi-square per sample " << General(p.chi2_per_sample, 3)
          << ", residual peaks at " << General(p.peak_frequency_hz, 4) << " Hz\n";
  out << "normalised RMS error of the time series: before " << General(d.fit_before.nrmse, 4) << ", after "
      << General(d.fit_after.nrmse, 4) << "; held-out parts (1/" << d.heldout_every
      << " of each record, an end that shows some of its impacts where one can): before " << General(d.fit_before.heldout_nrmse, 4) << ", after "
      << General(d.fit_after.heldout_nrmse, 4) << "\n";
  out << "\nper record (chi-square per sample, 1 is noise): fit part before -> after, held-out part before -> after\n";
  for (size_t i = 0; i < d.before.size(); ++i) {
    const BroadbandRecordMatch& b = d.before[i];
    const BroadbandRecordMatch& a = i < d.after.size() ? d.after[i] : b;
    out << "  " << b.name << " (" << General(b.drive_rms_v, 3) << " V rms): " << General(b.chi2_per_sample, 4) << " -> "
        << General(a.chi2_per_sample, 4) << ", " << General(b.heldout_chi2_per_sample, 4) << " -> "
        << General(a.heldout_chi2_per_sample, 4) << "\n";
  }
  if (d.chosen >= 0) PrintChosenParameters(d.candidates[d.chosen], out);
  PrintCandidates(d.candidates, out);
  PrintEvidence(d.evidence, out);
  out << "\n" << General(d.seconds, 3) << " s\n";
}

}  // namespace strokelab::cli
