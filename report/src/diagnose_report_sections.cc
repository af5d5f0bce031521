// The sections both diagnosis pages share (diagnose_report.h, broadband_report.h): the style, the
// verdict, the fit before and after, the parameters, the candidates, the evidence table, the figures.
#include <cmath>

#include "diagnose_report_internal.h"

namespace strokelab::report::diagnose_internal {
namespace {

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

}  // namespace

const CandidateFit* Outcome::Chosen() const {
  return chosen >= 0 && static_cast<size_t>(chosen) < candidates->size() ? &(*candidates)[static_cast<size_t>(chosen)]
                                                                         : nullptr;
}

Outcome OutcomeOf(const Diagnosis& d) {
  return {&d.candidates, d.chosen, d.missing_physics, d.unexplained.has_value(), d.fit_before, d.fit_after,
          d.conclusion, &d.base.parameters};
}

Outcome OutcomeOf(const BroadbandDiagnosis& d) {
  return {&d.candidates, d.chosen, d.missing_physics, d.unexplained.has_value(), d.fit_before, d.fit_after,
          d.conclusion, &d.base.result.fit.parameters};
}

std::string PageStart(const std::string& title) {
  return "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" + Esc(title) +
         "</title>\n<style>" + std::string(kStyle) + "</style>\n</head>\n<body>\n";
}

std::string VerdictSection(const Outcome& d) {
  const CandidateFit* chosen = d.Chosen();
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
  const FitFigures &b = d.before, &a = d.after;
  out += "<p>" +
         Esc(Format("nrmse %s \u2192 %s (%s better), held-out nrmse %s \u2192 %s (%s better).", Num(b.nrmse).c_str(),
                    Num(a.nrmse).c_str(), Improvement(b.nrmse, a.nrmse).c_str(), Num(b.heldout_nrmse).c_str(),
                    Num(a.heldout_nrmse).c_str(), Improvement(b.heldout_nrmse, a.heldout_nrmse).c_str())) +
         "</p>\n";
  // The conclusion, once: it carries the open-world test's description when something is unexplained.
  if (!d.conclusion.empty()) out += "<p>" + Esc(d.conclusion) + "</p>\n";
  return out + "</div>\n";
}

std::string FitTable(const Outcome& d) {
  const CandidateFit* chosen = d.Chosen();
  auto row = [](const std::string& name, const FitFigures& f) {
    return "<tr>" + Td(name) + NumTd(f.nrmse) + NumTd(f.heldout_nrmse) + NumTd(f.chi2) + NumTd(f.heldout_chi2) +
           NumTd(f.residual_variance) + "</tr>\n";
  };
  const FitFigures &b = d.before, &a = d.after;
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

std::string ParametersTable(const Outcome& d) {
  const CandidateFit* chosen = d.Chosen();
  auto estimate = [](const FitParameter* p) { return Td(p ? ValueSe(p->value, p->standard_error) : "-", "num"); };
  std::string rows;
  for (const FitParameter& p : *d.base_parameters) {
    const FitParameter* after = chosen ? FindParameter(chosen->parameters, p.name) : nullptr;
    rows += "<tr>" + Td(p.name) + Td(p.unit) + estimate(&p) + (chosen ? estimate(after) : "") +
            Td(ParameterNote(p), "note") + "</tr>\n";
  }
  if (chosen) {
    for (const FitParameter& p : chosen->parameters) {
      if (FindParameter(*d.base_parameters, p.name)) continue;
      rows += "<tr class=\"added\">" + Td(p.name) + Td(p.unit) + Td("-", "num") + estimate(&p) +
              Td(ParameterNote(p).empty() ? "added" : "added; " + ParameterNote(p), "note") + "</tr>\n";
    }
  }
  std::vector<std::string> headers = {"parameter", "unit", "base model"};
  if (chosen) headers.push_back("base + " + chosen->label);
  headers.push_back("note");
  return "<h2>Parameters (value \u00b1 standard error)</h2>\n" + Table(headers, rows);
}

std::string CandidatesTable(const Outcome& d) {
  std::string out = "<h2>Candidates</h2>\n";
  if (d.candidates->empty()) return out + "<p class=\"skipped\">No candidate was tried.</p>\n";
  std::string rows;
  for (size_t i = 0; i < d.candidates->size(); ++i) {
    const CandidateFit& c = (*d.candidates)[i];
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

std::string EvidenceTable(const std::vector<Evidence>& evidence) {
  if (evidence.empty()) return "<p class=\"skipped\">No signature was measured.</p>\n";
  std::string rows;
  for (const Evidence& e : evidence) {
    const bool known = e.standard_error > 0 && std::isfinite(e.significance);
    rows += "<tr>" + Td(e.kind) + Td(e.summary) + Td(ValueSe(e.value, e.standard_error), "num") +
            Td(known ? Num(e.significance, 3) : "-", "num") + Td(EffectIds(e.points_to)) + "</tr>\n";
  }
  return Table({"kind", "summary", "value \u00b1 SE", "significance [SE]", "points to"}, rows);
}

std::string FiguresSection(const std::vector<Figure>& figures) {
  std::string out = "<h2>Figures</h2>\n";
  for (const Figure& f : figures) {
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

}  // namespace strokelab::report::diagnose_internal
