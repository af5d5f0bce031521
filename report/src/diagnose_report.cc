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

std::string Table(const std::vector<std::string>& headers, const std::string& rows, const char* css_class) {
  std::string out = css_class ? Format("<table class=\"%s\">\n<tr>", css_class) : std::string("<table>\n<tr>");
  for (const std::string& h : headers) out += "<th>" + Esc(h) + "</th>";
  return out + "</tr>\n" + rows + "</table>\n";
}

}  // namespace diagnose_internal

namespace {

using namespace diagnose_internal;

constexpr const char* kStyle = R"(
body { font-family: Helvetica, Arial, 'DejaVu Sans', sans-serif; color: #222; max-width: 1220px;
       margin: 20px auto; padding: 0 16px; line-height: 1.4; }
h1 { font-size: 24px; margin: 0 0 4px; }
h2 { font-size: 19px; margin: 30px 0 8px; border-bottom: 1px solid #ccc; padding-bottom: 3px; }
h3 { font-size: 15px; margin: 20px 0 6px; }
.meta { color: #555; font-size: 13px; margin: 2px 0; }
.verdict { border-left: 6px solid #D55E00; background: #fdf1ea; padding: 10px 14px; margin: 14px 0; }
.verdict.nothing { border-color: #009E73; background: #ecf7f2; }
.verdict .answer { font-size: 19px; margin: 0 0 6px; }
.verdict ul { margin: 4px 0 6px; }
.verdict p { margin: 4px 0; }
table { border-collapse: collapse; font-size: 13px; margin: 6px 0 10px; }
th, td { border: 1px solid #d4d4d4; padding: 3px 7px; text-align: left; vertical-align: top; }
th { background: #f1f1f1; font-weight: 600; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
tr.chosen td { background: #fff1bf; font-weight: 600; }
tr.added td { background: #f4f8fc; }
td.note { color: #555; max-width: 380px; }
.figs { display: flex; flex-wrap: wrap; gap: 10px; }
svg { max-width: 100%; height: auto; border: 1px solid #eee; }
p.caption { font-size: 13px; color: #444; max-width: 1000px; margin: 4px 0 8px; }
p.key { font-size: 13px; margin: 4px 0; }
.swatch { display: inline-block; width: 11px; height: 11px; border-radius: 50%; margin: 0 4px 0 10px;
          vertical-align: -1px; }
p.skipped { font-style: italic; color: #666; }
details summary { cursor: pointer; font-weight: 600; margin: 6px 0; }
.maps { display: flex; flex-wrap: wrap; gap: 10px; }
.maps figure { flex: 1 1 560px; margin: 0; }
.maps figure svg { width: 100%; }
.maps figcaption { font-size: 13px; color: #444; margin: 4px 0; }
)";

std::string YesNo(bool value) { return Td(value ? "yes" : "no"); }

const CandidateFit* Chosen(const Diagnosis& d) {
  return d.chosen >= 0 && static_cast<size_t>(d.chosen) < d.candidates.size()
             ? &d.candidates[static_cast<size_t>(d.chosen)]
             : nullptr;
}

std::string ParameterText(const FitParameter& p) {
  return p.name + " = " + ValueSe(p.value, p.standard_error) + (p.unit.empty() ? "" : " " + p.unit);
}

// The relative standard error, for the verdict: how well the added parameter is determined.
std::string RelativeSe(const FitParameter& p) {
  const double relative = p.standard_error / std::abs(p.value);
  return std::isfinite(relative) && relative > 0 ? Format(" (%.2g %%)", 100 * relative) : "";
}

// 1 - after / before, in percent ("-" when undefined).
std::string Improvement(double before, double after) {
  const double relative = (before - after) / before;
  return std::isfinite(relative) ? Format("%.1f %%", 100 * relative) : "-";
}

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

std::string Verdict(const Diagnosis& d) {
  const CandidateFit* chosen = Chosen(d);
  const bool nothing = chosen == nullptr && d.missing_physics.empty();
  std::string out = nothing && !d.unexplained ? "<div class=\"verdict nothing\">\n" : "<div class=\"verdict\">\n";
  if (nothing && !d.unexplained) {
    out += "<p class=\"answer\"><strong>Nothing missing</strong>: no candidate effect improved the held-out fit "
           "enough to be named, and what the base model leaves on the held-out records is noise.</p>\n";
  } else if (nothing) {
    out += "<p class=\"answer\"><strong>Unexplained</strong>: the model misses something that no library effect "
           "explains.</p>\n";
  } else {
    const std::string name = chosen ? chosen->label : EffectIds(d.missing_physics);
    out += "<p class=\"answer\">Missing physics: <strong>" + Esc(name) + "</strong>" +
           (chosen && !chosen->converged ? " (its fit did <strong>not converge</strong>: the values may be off)" : "") +
           "</p>\n";
    if (chosen && !chosen->effect_parameters.empty()) {
      out += "<ul>\n";
      for (const FitParameter& p : chosen->effect_parameters) out += "<li>" + Esc(ParameterText(p) + RelativeSe(p)) + "</li>\n";
      out += "</ul>\n";
    }
    if (chosen) {
      out += "<p>" +
             Esc(Format("Held-out chi-square lower by %s residual variances, fit records' by %s.",
                        Num(chosen->heldout_gain).c_str(), Num(chosen->fit_gain).c_str())) +
             "</p>\n";
    }
  }
  const FitFigures &b = d.fit_before, &a = d.fit_after;
  out += "<p>" +
         Esc(Format("nrmse %s \u2192 %s (%s better), held-out nrmse %s \u2192 %s (%s better).", Num(b.nrmse).c_str(),
                    Num(a.nrmse).c_str(), Improvement(b.nrmse, a.nrmse).c_str(), Num(b.heldout_nrmse).c_str(),
                    Num(a.heldout_nrmse).c_str(), Improvement(b.heldout_nrmse, a.heldout_nrmse).c_str())) +
         "</p>\n";
  if (d.unexplained) {
    out += "<p class=\"unexplained\"><strong>Unexplained" + std::string(nothing ? "" : " beyond it") +
           "</strong>: " + Esc(d.unexplained->description) + ".</p>\n";
  }
  return out + "</div>\n";
}

std::string FitTable(const Diagnosis& d) {
  const CandidateFit* chosen = Chosen(d);
  auto row = [](const std::string& name, const FitFigures& f) {
    return "<tr>" + Td(name) + NumTd(f.nrmse) + NumTd(f.heldout_nrmse) + NumTd(f.chi2) + NumTd(f.heldout_chi2) +
           NumTd(f.residual_variance) + "</tr>\n";
  };
  const FitFigures &b = d.fit_before, &a = d.fit_after;
  std::string rows = row("base model", b) + row(chosen ? "base + " + chosen->label : "after (nothing added)", a);
  rows += "<tr>" + Td("improvement, 1 - after / before") + Td(Improvement(b.nrmse, a.nrmse), "num") +
          Td(Improvement(b.heldout_nrmse, a.heldout_nrmse), "num") + Td(Improvement(b.chi2, a.chi2), "num") +
          Td(Improvement(b.heldout_chi2, a.heldout_chi2), "num") + Td("", "num") + "</tr>\n";
  return "<h2>Fit before and after</h2>\n" +
         Table({"model", "nrmse", "held-out nrmse", "chi2 (fit records)", "held-out chi2", "residual variance"},
               rows);
}

const FitParameter* FindParameter(const std::vector<FitParameter>& list, const std::string& name) {
  for (const FitParameter& p : list) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

std::string ParameterNote(const FitParameter& p) {
  std::string note = p.fixed ? "fixed" : "";
  if (!p.identifiable) note += std::string(note.empty() ? "" : "; ") + "not identifiable";
  if (!p.note.empty()) note += (note.empty() ? "" : "; ") + p.note;
  return note;
}

std::string ParametersTable(const Diagnosis& d) {
  const CandidateFit* chosen = Chosen(d);
  auto estimate = [](const FitParameter* p) { return Td(p ? ValueSe(p->value, p->standard_error) : "-", "num"); };
  std::string rows;
  for (const FitParameter& p : d.base.parameters) {
    const FitParameter* after = chosen ? FindParameter(chosen->parameters, p.name) : nullptr;
    rows += "<tr>" + Td(p.name) + Td(p.unit) + estimate(&p) + (chosen ? estimate(after) : "") +
            Td(ParameterNote(p), "note") + "</tr>\n";
  }
  if (chosen) {
    for (const FitParameter& p : chosen->parameters) {
      if (FindParameter(d.base.parameters, p.name)) continue;
      rows += "<tr class=\"added\">" + Td(p.name) + Td(p.unit) + Td("-", "num") + estimate(&p) +
              Td(ParameterNote(p).empty() ? "added" : "added; " + ParameterNote(p), "note") + "</tr>\n";
    }
  }
  std::vector<std::string> headers = {"parameter", "unit", "base model"};
  if (chosen) headers.push_back("base + " + chosen->label);
  headers.push_back("note");
  return "<h2>Parameters (value \u00b1 standard error)</h2>\n" + Table(headers, rows);
}

std::string CandidatesTable(const Diagnosis& d) {
  std::string out = "<h2>Candidates</h2>\n";
  if (d.candidates.empty()) return out + "<p class=\"skipped\">No candidate was tried.</p>\n";
  std::string rows;
  for (size_t i = 0; i < d.candidates.size(); ++i) {
    const CandidateFit& c = d.candidates[i];
    const bool is_chosen = static_cast<int>(i) == d.chosen;
    std::string parameters;
    for (const FitParameter& p : c.effect_parameters) parameters += (parameters.empty() ? "" : "; ") + ParameterText(p);
    rows += std::string(is_chosen ? "<tr class=\"chosen\">" : "<tr>") + Td(c.label + (is_chosen ? " (chosen)" : "")) +
            YesNo(c.fitted) + YesNo(c.converged) + NumTd(c.heldout_gain) + NumTd(c.fit_gain) +
            NumTd(c.figures.heldout_nrmse) + NumTd(c.figures.nrmse) + Td(parameters.empty() ? "-" : parameters) +
            Td(std::to_string(c.passes), "num") + NumTd(c.seconds, 3) + Td(c.decision, "note") + Td(c.note, "note") +
            "</tr>\n";
  }
  out += "<p class=\"caption\">Gains: drop of the chi-square against the base model, in residual variances of the "
         "candidate (held out: the records no fit saw). Decision: named, or why not, with the numbers that decided "
         "(the rules: the README's diagnosis section).</p>\n";
  return out + Table({"candidate", "fitted", "converged", "held-out gain", "fit gain", "held-out nrmse", "nrmse",
                      "effect parameters \u00b1 SE", "passes", "time [s]", "decision", "note"},
                     rows);
}

std::string EvidenceSection(const Diagnosis& d) {
  const Signatures& s = d.signatures;
  std::string out = "<h2>Evidence</h2>\n";
  if (s.evidence.empty()) {
    out += "<p class=\"skipped\">No signature was measured.</p>\n";
  } else {
    std::string rows;
    for (const Evidence& e : s.evidence) {
      const bool known = e.standard_error > 0 && std::isfinite(e.significance);
      rows += "<tr>" + Td(e.kind) + Td(e.summary) + Td(ValueSe(e.value, e.standard_error), "num") +
              Td(known ? Num(e.significance, 3) : "-", "num") + Td(EffectIds(e.points_to)) + "</tr>\n";
    }
    out += Table({"kind", "summary", "value \u00b1 SE", "significance [SE]", "points to"}, rows);
  }
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

std::string FiguresSection(const Diagnosis& d) {
  std::string out = "<h2>Figures</h2>\n";
  for (const Figure& f : DiagnosisFigures(d)) {
    out += "<section id=\"" + Esc(f.id) + "\">\n<h3>" + Esc(f.heading) + "</h3>\n";
    if (f.svgs.empty()) {
      out += "<p class=\"skipped\">" + Esc(f.caption) + "</p>\n</section>\n";
      continue;
    }
    out += "<div class=\"figs\">\n";
    for (const std::string& svg : f.svgs) out += svg;
    out += "</div>\n";
    if (!f.key.empty()) {
      out += "<p class=\"key\">";
      for (const auto& [swatch, text] : f.key) {
        out += "<span class=\"swatch\" style=\"" + Esc(swatch) + "\"></span>" + Esc(text) + " ";
      }
      out += "</p>\n";
    }
    out += "<p class=\"caption\">" + Esc(f.caption) + "</p>\n</section>\n";
  }
  return out;
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
  return "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>strokelab diagnosis</title>\n"
         "<style>" +
         std::string(kStyle) + "</style>\n</head>\n<body>\n" + Header(d) + Verdict(d) + FitTable(d) +
         ParametersTable(d) + MapsSection(d, maps) + CandidatesTable(d) + EvidenceSection(d) + FiguresSection(d) + RecordsSection(d) +
         "</body>\n</html>\n";
}

}  // namespace strokelab::report
