// The diagnosis page (diagnose_report.h): one HTML file, its figures inline, read top-down as the
// answer (what is missing), how much it buys, the alternatives, the evidence and the pictures.
#include "strokelab/report/diagnose_report.h"

#include <cmath>
#include <numbers>

#include "diagnose_report_internal.h"
#include "strokelab/plot/svg_plot.h"

namespace strokelab::report {
namespace diagnose_internal {

std::string Esc(const std::string& text) { return plot::EscapeXml(text); }

std::string Td(const std::string& text, const char* css_class) {
  return css_class ? Format("<td class=\"%s\">", css_class) + Esc(text) + "</td>" : "<td>" + Esc(text) + "</td>";
}
std::string NumTd(double value, int digits) { return Td(Num(value, digits), "num"); }
std::string YesNo(bool value) { return Td(value ? "yes" : "no"); }

std::string Table(const std::vector<std::string>& headers, const std::string& rows, const char* css_class) {
  std::string out = css_class ? Format("<table class=\"%s\">\n<tr>", css_class) : std::string("<table>\n<tr>");
  for (const std::string& h : headers) out += "<th>" + Esc(h) + "</th>";
  return out + "</tr>\n" + rows + "</table>\n";
}

}  // namespace diagnose_internal

namespace {

using namespace diagnose_internal;

std::string Header(const Diagnosis& d) {
  size_t heldout = 0;
  for (const RecordMatch& r : d.before) heldout += r.heldout;
  std::string out = "<h1>strokelab diagnosis</h1>\n";
  out += "<p class=\"meta\">" +
         Esc(Format("Base model: %s; response: %s%s; %zu records, %zu held out of every fit; diagnosis took %s s.",
                    ToString(d.base.model_kind), ToString(d.base.response),
                    d.base.absolute_scale ? "" : " (scale only nominal)", d.before.size(), heldout,
                    Num(d.seconds, 3).c_str())) +
         "</p>\n";
  if (!d.base.identifiability.empty()) out += "<p class=\"meta\">" + Esc(d.base.identifiability) + "</p>\n";
  return out;
}

std::string EvidenceSection(const Diagnosis& d) {
  const Signatures& s = d.signatures;
  std::string out = "<h2>Evidence</h2>\n" + EvidenceTable(s.evidence);
  out += "<h3>Hotspots: where the base model misses most</h3>\n";
  if (s.hotspots.empty()) return out + "<p class=\"skipped\">No hotspot was reported.</p>\n";
  std::string rows;
  for (const Signatures::Hotspot& h : s.hotspots) {
    rows += "<tr>" + Td(h.record) + NumTd(h.frequency_hz) + NumTd(h.amplitude_v) + Td(std::to_string(h.harmonic), "num") +
            NumTd(100 * h.magnitude_error, 3) + NumTd(h.phase_error_rad, 3) + NumTd(h.chi2_per_residual, 3) +
            "</tr>\n";
  }
  return out + Table({"record", "f [Hz]", "V [V]", "harmonic", "magnitude error [%]", "phase error [rad]",
                      "chi2 per residual"},
                     rows);
}

std::string RecordsSection(const Diagnosis& d) {
  std::string rows;
  for (size_t i = 0; i < d.before.size(); ++i) {
    const RecordMatch& b = d.before[i];
    const RecordMatch* a = i < d.after.size() ? &d.after[i] : nullptr;
    rows += "<tr>" + Td(b.name) + NumTd(b.frequency_hz) + NumTd(b.amplitude_v) + YesNo(b.heldout) + YesNo(b.clear) +
            NumTd(b.nrmse) + NumTd(a ? a->nrmse : NAN) + NumTd(b.chi2) + NumTd(a ? a->chi2 : NAN) +
            Td(std::to_string(b.model_period) + (a ? " / " + std::to_string(a->model_period) : ""), "num") + "</tr>\n";
  }
  return "<h2>Records</h2>\n<details>\n<summary>" + Esc(Format("All %zu records, base and chosen model", d.before.size())) +
         "</summary>\n" +
         Table({"record", "f [Hz]", "V [V]", "held out", "clear", "nrmse base", "nrmse chosen", "chi2 base",
                "chi2 chosen", "model period base / chosen"},
               rows) +
         "</details>\n<p class=\"meta\">Tables: <a href=\"records.csv\">records.csv</a>, "
         "<a href=\"candidates.csv\">candidates.csv</a>, <a href=\"candidate_parameters.csv\">candidate_parameters.csv</a>, "
         "<a href=\"levels.csv\">levels.csv</a>; the diagnosed model: "
         "<a href=\"model.json\">model.json</a>.</p>\n";
}

}  // namespace

std::string DiagnosisHtml(const Diagnosis& d, const DiagnosisMaps* maps) {
  const Outcome outcome = OutcomeOf(d);
  return PageStart("strokelab diagnosis") + Header(d) + VerdictSection(outcome) + FitTable(outcome) +
         ParametersTable(outcome) + MapsSection(d.model_note, d.missing_physics, maps) + CandidatesTable(outcome) + EvidenceSection(d) +
         FiguresSection(DiagnosisFigures(d)) + RecordsSection(d) + "</body>\n</html>\n";
}

}  // namespace strokelab::report
