// Helpers shared by the files of the diagnosis report (diagnose_report*.cc); not a public API.
#pragma once

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "format.h"
#include "strokelab/diagnose/broadband_diagnose.h"
#include "strokelab/diagnose/diagnose.h"
#include "strokelab/plot/svg_plot.h"
#include "strokelab/report/diagnosis_maps.h"

namespace strokelab::report::diagnose_internal {

using ::strokelab::report::Format;

// "%.<digits>g" (whole numbers below 1e6 written out), or "-" for a non-finite value.
std::string Num(double value, int digits = 4);

// "1301.5 ± 8.3", "(2.35 ± 0.12)e+06": the standard error to two digits, the value to the same
// decimal place; the value alone when the standard error is 0 or unknown; "-" when not finite.
std::string ValueSe(double value, double standard_error);

// The effect's JSON id. Kept here rather than taken from EffectLibrary() so that the report does not
// need the diagnosis code, only its types.
const char* EffectId(Effect effect);
std::string EffectIds(const std::vector<Effect>& effects);  // "a + b", "-" when empty


// The records' amplitudes grouped into levels (a stepped-sine campaign drives a few amplitudes at
// many frequencies): the level of each record, and each level's mean amplitude [V], ascending.
struct AmplitudeLevels {
  std::vector<size_t> level_of;    // per record
  std::vector<double> amplitude_v;  // per level
};
AmplitudeLevels GroupAmplitudes(const std::vector<RecordMatch>& records);

// HTML pieces of the page (diagnose_report.cc): text escaped for HTML, a table cell (with a class),
// a number's cell ("num": right-aligned), a table with its header row (and a class).
std::string Esc(const std::string& text);
std::string Td(const std::string& text, const char* css_class = nullptr);
std::string NumTd(double value, int digits = 4);
std::string YesNo(bool value);  // a "yes" or "no" cell
std::string Table(const std::vector<std::string>& headers, const std::string& rows, const char* css_class = nullptr);

// One figure of the page: its SVG (or SVGs), or the sentence that replaces it.
struct Figure {
  std::string id;  // HTML anchor: "harmonics", "frf", "residual", "resonance", "contact", "ratios", "missing_force"
  std::string heading;  // plain text
  std::vector<std::string> svgs;  // empty: skipped
  // Key shared by the SVGs: (CSS of a round swatch, text). Drawn by the page, as an SVG legend
  // would cover the data of a small scatter plot.
  std::vector<std::pair<std::string, std::string>> key;
  std::string caption;  // plain text: how to read it, or why it is missing
};
std::vector<Figure> DiagnosisFigures(const Diagnosis& diagnosis);

// What the stepped-sine and the broadband diagnosis pages show alike, as both results hold it.
struct Outcome {
  const std::vector<CandidateFit>* candidates = nullptr;
  int chosen = -1;  // index into candidates (-1: nothing named)
  std::vector<Effect> missing_physics;
  bool unexplained = false;
  FitFigures before, after;
  std::string conclusion;
  const std::vector<FitParameter>* base_parameters = nullptr;
  const CandidateFit* Chosen() const;  // null when nothing is named
};
Outcome OutcomeOf(const Diagnosis& d);
Outcome OutcomeOf(const BroadbandDiagnosis& d);

// The shared sections (diagnose_report_sections.cc): the page's head with its style, up to <body>;
// the verdict (the conclusion printed once); the fit before and after; the parameters of the base
// and the chosen model; the candidates with their decisions; the evidence table (or a sentence when
// there is none); the figures, each with its key and caption or the sentence that replaces it.
std::string PageStart(const std::string& title);
std::string VerdictSection(const Outcome& d);
std::string FitTable(const Outcome& d);
std::string ParametersTable(const Outcome& d);
std::string CandidatesTable(const Outcome& d);
std::string EvidenceTable(const std::vector<Evidence>& evidence);
std::string FiguresSection(const std::vector<Figure>& figures);

// The maps section of the page: the base and the diagnosed model's saturation maps side by side, the
// threshold shift per frequency and the jump intervals (diagnose_report_maps.cc). `maps` may be null
// (not computed: said on the page).
// `model_note` and `missing` are the diagnosis's (Diagnosis::model_note, missing_physics).
std::string MapsSection(const std::string& model_note, const std::vector<Effect>& missing, const DiagnosisMaps* maps);

// The report folder's files (diagnose_report_files.cc): a number's CSV cell ("%.10g", empty when not
// finite: the CsvTable convention); rows written as CSV (fields quoted where needed); the candidates,
// one row each, and their effect parameters, one row per parameter; a text file; the folder itself.
// Each throws std::runtime_error when it cannot write.
std::string Cell(double value);
void WriteRows(const std::filesystem::path& path, const std::vector<std::vector<std::string>>& rows);
void WriteCandidates(const std::vector<CandidateFit>& candidates, int chosen, const std::filesystem::path& path);
void WriteCandidateParameters(const std::vector<CandidateFit>& candidates, const std::filesystem::path& path);
void WriteText(const std::filesystem::path& path, const std::string& text);
void CreateReportDirectory(const std::filesystem::path& dir);
// The files both reports' folders hold, into `dir`: candidates.csv and candidate_parameters.csv,
// threshold_shift.csv and jump_intervals.csv of both models' maps (headers only when either is missing),
// and the diagnosed model as model.json.
void WriteSharedFiles(const std::vector<CandidateFit>& candidates, int chosen, const DiagnosisMaps* maps,
                      const ActuatorModel& model, const std::filesystem::path& dir);

// The named effects' characteristics with their bands (diagnose_report_curves.cc).
Figure CurvesFigure(const std::vector<EffectCurve>& curves);

// The figures against drive amplitude, per Signatures::Level (diagnose_report_levels.cc).
Figure ResonanceFigure(const Diagnosis& diagnosis);
Figure ContactFigure(const Diagnosis& diagnosis, const char* unit);
Figure RatiosFigure(const Diagnosis& diagnosis);

// ---- plot helpers (diagnose_report_plots.cc) ----

inline constexpr const char* kMeasuredColor = "#000000";
inline constexpr const char* kBaseColor = "#D55E00";
inline constexpr const char* kChosenColor = "#0072B2";

plot::Series Line(std::string label, std::string color, bool dashed = false);
plot::Series Dots(std::string label, std::string color, double line_width = 1.5);  // markers only
plot::Axes MakeAxes(std::string title, std::string x_label, std::string y_label, int width_px, int height_px);
// The data's extent on one axis (x or y; positive values only on a log axis): {lo, hi}, lo > hi if none.
std::pair<double, double> Extent(const std::vector<plot::Series>& series, bool x_axis, bool log);
// Axis limits `lo_pad` below and `hi_pad` above the data, in fractions of its span (of decades on a
// log axis), so that no point sits on the frame and the legend (top right) has room above the data.
// Leaves the limits alone (from the data) when there is none.
void PadRange(const std::vector<plot::Series>& series, bool x_axis, bool log, double lo_pad, double hi_pad,
              double* min, double* max);

}  // namespace strokelab::report::diagnose_internal
