// The broadband diagnosis's page and folder (broadband_report.h): the sections the stepped report has
// (diagnose_report_sections.cc), the held-out parts' verdict, and the figures of a time-series fit.
#include "strokelab/report/broadband_report.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "diagnose_report_internal.h"

namespace strokelab::report {
namespace {

using namespace diagnose_internal;

constexpr int kHalfWidthPx = 560;  // two pictures side by side fit a 1200 px wide window
constexpr const char* kNoiseColor = "#7F7F7F";

bool HasAfter(const BroadbandDiagnosis& d) { return d.chosen >= 0 && d.after.size() == d.before.size(); }

std::string Header(const BroadbandDiagnosis& d) {
  const BroadbandCampaignFit& b = d.base;
  std::string out = "<h1>strokelab diagnosis (broadband records)</h1>\n";
  out += "<p class=\"meta\">" +
         Esc(Format("Base model: %s; response: %s%s; %zu records fitted by their time series, 1/%d of each held out "
                    "of every fit (the first or the last part: one that shows some of the record's impacts where one "
                    "can); "
                    "diagnosis took %s s.",
                    ToString(b.model_kind), ToString(b.response), b.absolute_scale ? "" : " (scale only nominal)",
                    d.before.size(), d.heldout_every, Num(d.seconds, 3).c_str())) +
         "</p>\n";
  for (const std::string& w : d.warnings) out += "<p class=\"meta\">" + Esc("Warning: " + w) + "</p>\n";
  return out;
}

// Where an unexplained misfit lives: the held-out parts beyond noise.
std::string UnexplainedSection(const BroadbandDiagnosis& d) {
  if (!d.unexplained) return "";
  const BroadbandUnexplained& u = *d.unexplained;
  std::string out = "<h2>What is left unexplained</h2>\n<p>" +
                    Esc(Format("Chi-square on the %s parts %s against %s from noise alone on average and at most %s "
                               "(its 1e-3 upper tail): the misfit's RMS is %s times the noise's.",
                               u.parts.c_str(), Num(u.chi2, 5).c_str(), Num(u.dof, 5).c_str(), Num(u.threshold_chi2, 5).c_str(),
                               Num(u.misfit_to_noise, 3).c_str())) +
                    "</p>\n";
  if (u.places.empty()) return out + "<p class=\"skipped\">No single held-out part stands out on its own.</p>\n";
  std::string rows;
  for (const BroadbandUnexplained::Place& p : u.places) {
    rows += "<tr>" + Td(p.record) + NumTd(p.chi2_per_sample, 3) + NumTd(p.peak_frequency_hz, 4) +
            NumTd(100 * p.near_contact_share, 2) + NumTd(100 * p.contact_time_share, 2) + "</tr>\n";
  }
  return out + Table({"record (" + u.parts + " part)", "chi2 per sample", "residual's spectral peak [Hz]",
                      "excess within 2 ms of contacts (the model's or the record's impacts) [%]",
                      "time within 2 ms of those [%]"},
                     rows);
}

// Each record's chi-square per sample on its fit and its held-out part, base and diagnosed model,
// against the drive's rms: where the model misses, and how much the added physics buys, per level.
Figure PartsFigure(const BroadbandDiagnosis& d) {
  Figure fig{"parts", "Misfit per record against noise", {}, {}, ""};
  if (d.before.empty()) {
    fig.caption = "No record was diagnosed.";
    return fig;
  }
  std::vector<size_t> order(d.before.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](size_t a, size_t b) { return d.before[a].drive_rms_v < d.before[b].drive_rms_v; });
  const bool after = HasAfter(d);
  for (const bool heldout : {false, true}) {
    plot::Series base = Line("base model", kBaseColor, true), chosen = Line("diagnosed model", kChosenColor);
    base.markers = chosen.markers = true;
    plot::Series noise = Line("noise alone", kNoiseColor, true);
    noise.line_width = 1.0;
    for (size_t i : order) {
      const double x = d.before[i].drive_rms_v;
      base.x.push_back(x);
      base.y.push_back(heldout ? d.before[i].heldout_chi2_per_sample : d.before[i].chi2_per_sample);
      if (after) {
        chosen.x.push_back(x);
        chosen.y.push_back(heldout ? d.after[i].heldout_chi2_per_sample : d.after[i].chi2_per_sample);
      }
      noise.x.push_back(x);
      noise.y.push_back(1.0);
    }
    std::vector<plot::Series> series = {noise, base};
    if (after) series.push_back(chosen);
    plot::Axes axes = MakeAxes(heldout ? "Held-out parts (no fit saw them)" : "Fit parts", "drive [V rms]",
                               "chi-square per sample", kHalfWidthPx, 380);
    const auto [lo, hi] = Extent(series, false, true);  // the noise line at 1 among them
    axes.log_y = hi / lo > 20.0;  // a record far beyond noise would flatten the others on a linear axis
    PadRange(series, false, axes.log_y, 0.08, 0.25, &axes.y_min, &axes.y_max);
    PadRange(series, true, false, 0.08, 0.08, &axes.x_min, &axes.x_max);
    fig.svgs.push_back(plot::LinePlot(series, axes));
  }
  fig.caption = "The residual's sum of squares over the record's noise level, per sample: 1 is noise alone (its "
                "spread over a part of n samples is about sqrt(12 / n)). Left the parts every fit saw, right the "
                "held-out parts, which the chosen model had to predict." +
                std::string(after ? "" : " Nothing was named, so only the base model is drawn.");
  return fig;
}

std::string RecordsSection(const BroadbandDiagnosis& d) {
  const bool after = HasAfter(d);
  std::string rows;
  for (size_t i = 0; i < d.before.size(); ++i) {
    const BroadbandRecordMatch& b = d.before[i];
    const BroadbandRecordMatch* a = after ? &d.after[i] : nullptr;
    rows += "<tr>" + Td(b.name) + NumTd(b.drive_rms_v) + NumTd(b.noise_rms) + NumTd(b.nrmse) +
            NumTd(a ? a->nrmse : NAN) + NumTd(b.chi2_per_sample) + NumTd(a ? a->chi2_per_sample : NAN) +
            NumTd(b.heldout_chi2_per_sample) + NumTd(a ? a->heldout_chi2_per_sample : NAN) + "</tr>\n";
  }
  return "<h2>Records</h2>\n" +
         Table({"record", "drive [V rms]", "noise rms", "nrmse base", "nrmse chosen", "chi2/sample base",
                "chi2/sample chosen", "held-out chi2/sample base", "held-out chi2/sample chosen"},
               rows) +
         "<p class=\"meta\">Tables: <a href=\"records.csv\">records.csv</a>, <a href=\"candidates.csv\">candidates.csv</a>, "
         "<a href=\"candidate_parameters.csv\">candidate_parameters.csv</a>; the diagnosed model: "
         "<a href=\"model.json\">model.json</a>.</p>\n";
}

void WriteRecords(const BroadbandDiagnosis& d, const std::filesystem::path& path) {
  std::vector<std::vector<std::string>> rows = {
      {"name", "drive_rms_v", "noise_rms", "nrmse_before", "chi2_per_sample_before", "heldout_nrmse_before",
       "heldout_chi2_per_sample_before", "nrmse_after", "chi2_per_sample_after", "heldout_nrmse_after",
       "heldout_chi2_per_sample_after"}};
  for (size_t i = 0; i < d.before.size(); ++i) {
    const BroadbandRecordMatch& b = d.before[i];
    const BroadbandRecordMatch& a = i < d.after.size() ? d.after[i] : BroadbandRecordMatch{};
    const bool have_after = i < d.after.size();
    auto cell = [&](double value) { return have_after ? Cell(value) : std::string(); };
    rows.push_back({b.name, Cell(b.drive_rms_v), Cell(b.noise_rms), Cell(b.nrmse), Cell(b.chi2_per_sample),
                    Cell(b.heldout_nrmse), Cell(b.heldout_chi2_per_sample), cell(a.nrmse), cell(a.chi2_per_sample),
                    cell(a.heldout_nrmse), cell(a.heldout_chi2_per_sample)});
  }
  WriteRows(path, rows);
}

}  // namespace

std::string BroadbandDiagnosisHtml(const BroadbandDiagnosis& d, const DiagnosisMaps* maps) {
  const Outcome outcome = OutcomeOf(d);
  return PageStart("strokelab diagnosis (broadband)") + Header(d) + VerdictSection(outcome) + UnexplainedSection(d) +
         FitTable(outcome) + ParametersTable(outcome) + MapsSection(d.model_note, d.missing_physics, maps) +
         CandidatesTable(outcome) + "<h2>Evidence</h2>\n" +
         EvidenceTable(d.evidence) + FiguresSection({PartsFigure(d), CurvesFigure(d.curves)}) +
         RecordsSection(d) + "</body>\n</html>\n";
}

const std::vector<std::string>& BroadbandDiagnosisReportFiles() {
  static const std::vector<std::string> files = {"index.html",          "records.csv",        "candidates.csv",
                                                 "candidate_parameters.csv", "threshold_shift.csv", "jump_intervals.csv",
                                                 "model.json"};
  return files;
}

void WriteBroadbandDiagnosisReport(const BroadbandDiagnosis& d, const std::filesystem::path& dir,
                                   const DiagnosisMaps* maps) {
  CreateReportDirectory(dir);
  WriteText(dir / "index.html", BroadbandDiagnosisHtml(d, maps));
  WriteRecords(d, dir / "records.csv");
  WriteSharedFiles(d.candidates, d.chosen, maps, d.model, dir);
}

}  // namespace strokelab::report
