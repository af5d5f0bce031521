// The diagnosis report (HTML page, CSV tables, model file) on hand-made diagnoses and sweep results,
// so that the page is checked without fitting or sweeping anything: a named effect, "nothing
// missing", an empty diagnosis, and the maps of the base and the diagnosed model.
#include "strokelab/report/diagnose_report.h"
#include "strokelab/diagnose/effect_curves.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <complex>
#include <filesystem>
#include <functional>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "report_test_util.h"
#include "strokelab/model/model_json.h"
#include "strokelab/report/diagnosis_data.h"
#include "strokelab/report/diagnosis_maps.h"

namespace strokelab::report {
namespace {

using ::strokelab::testing::FreshDir;
using ::strokelab::testing::Lines;
using ::strokelab::testing::MapsOf;
using ::strokelab::testing::Parameter;
using ::strokelab::testing::ReadFile;

using ::testing::HasSubstr;
using ::testing::Not;

constexpr const char* kOddName = "rec<&>7";
constexpr int kHarmonics = 5;

// A resonance near 32 Hz whose harmonics fall as 1/h^2; `error` is the model's relative error.
std::vector<std::complex<double>> Harmonics(double f_hz, double v, double error) {
  const double r = f_hz / 32.0;
  const std::complex<double> first = v / std::complex<double>(1 - r * r, 0.1 * r);
  std::vector<std::complex<double>> c;
  for (int h = 1; h <= kHarmonics; ++h) c.push_back(first * (1 + error * h) * std::polar(1.0 / (h * h), 0.3 * h));
  return c;
}

RecordMatch Match(const std::string& name, double f_hz, double v, bool heldout, double error) {
  RecordMatch m;
  m.name = name;
  m.frequency_hz = f_hz;
  m.amplitude_v = v;
  m.heldout = heldout;
  m.clear = v < 0.5;
  m.measured = Harmonics(f_hz, v, 0.0);
  m.model = Harmonics(f_hz, v, error);
  m.nrmse = std::abs(error) * 1.7;
  m.chi2 = 1e4 * error * error * v;
  return m;
}

FitFigures Figures(double nrmse, double heldout_nrmse, double chi2, double heldout_chi2, double rv) {
  return {nrmse, heldout_nrmse, chi2, heldout_chi2, rv};
}

// A fitted, converged single-effect candidate.
CandidateFit Candidate(Effect effect, std::string label, const FitFigures& figures, double heldout_gain,
                       double fit_gain, std::vector<FitParameter> effect_parameters) {
  CandidateFit c;
  c.effects = {effect};
  c.label = std::move(label);
  c.fitted = c.converged = true;
  c.effect_parameters = std::move(effect_parameters);
  c.figures = figures;
  c.heldout_gain = heldout_gain;
  c.fit_gain = fit_gain;
  return c;
}

// 5 frequencies x 3 amplitudes, every 4th held out; the base model misses more at large amplitude
// (a hardening suspension), the chosen cubic stiffness much less.
Diagnosis Named() {
  Diagnosis d;
  d.base.response = ResponseKind::kForce;
  d.base.model.stiffness_n_per_m = 1300;  // sqrt(k_p / m_p) / 2 pi = 32.1 Hz
  d.base.parameters = {Parameter("k_p", "N/m", 1301.5, 8.3), Parameter("c_p", "N s/m", 1.31, 0.02),
                       Parameter("m_p", "kg", 0.032, 0)};
  d.base.parameters[2].fixed = true;
  size_t index = 0;
  for (double v : {0.1, 0.3, 1.0}) {
    for (double f : {20.0, 26.0, 32.0, 38.0, 50.0}) {
      const bool heldout = index % 4 == 3;
      const std::string name = index == 7 ? kOddName : "rec" + std::to_string(index);
      d.before.push_back(Match(name, f, v, heldout, 0.05 * v));
      d.after.push_back(Match(name, f, v, heldout, 0.004 * v));
      if (heldout) d.heldout.push_back(index);
      ++index;
    }
  }
  d.fit_before = Figures(0.08125, 0.0931, 1520, 610, 9.5);
  d.fit_after = Figures(0.01234, 0.0152, 160, 55, 1.02);

  CandidateFit cubic = Candidate(Effect::kCubicStiffness, "cubic_stiffness", d.fit_after, 540.5, 1350,
                                 {Parameter("k3", "N/m^3", 2.3456e6, 1.2e5)});
  cubic.parameters = d.base.parameters;
  cubic.parameters.push_back(cubic.effect_parameters[0]);
  cubic.passes = 3;
  cubic.seconds = 12.5;
  cubic.model = d.base.model;
  cubic.model.cubic_stiffness_n_per_m3 = 2.3456e6;
  cubic.covariance.assign(16, 0.0);  // k_p, c_p, m_p (fixed), k3
  for (size_t i = 0; i < 4; ++i) cubic.covariance[i * 4 + i] = std::pow(cubic.parameters[i].standard_error, 2);
  d.curves = EffectCurves(cubic, d.base.model, {-1e-3, 1e-3, 0.1, 0.0, 1.0, 5.0, 20.0, "test ranges"});
  const CandidateFit quadratic = Candidate(Effect::kQuadraticStiffness, "quadratic_stiffness",
                                           Figures(0.0801, 0.0925, 1490, 600, 9.3), 1.25, 3.5,
                                           {Parameter("k2", "N/m^2", 150, 400)});
  CandidateFit skipped = Candidate(Effect::kDryFriction, "dry_friction", Figures(NAN, NAN, NAN, NAN, NAN), NAN, NAN, {});
  skipped.fitted = skipped.converged = false;
  skipped.note = "skipped: <1 s of the budget left";
  d.candidates = {cubic, quadratic, skipped};
  d.chosen = 0;
  d.missing_physics = {Effect::kCubicStiffness};
  d.conclusion = "The suspension hardens: k3 explains the resonance shift & the odd harmonics.";
  d.seconds = 42;
  d.model = d.base.model;
  d.model.cubic_stiffness_n_per_m3 = 2.3456e6;
  d.model_note = "the base model extended by cubic_stiffness";

  Signatures& s = d.signatures;
  s.evidence.push_back({"resonance_shift", "The resonance rises by 4.1 Hz from 0.1 V to 1 V.", 4.1, 0.5, 8.2,
                        {Effect::kCubicStiffness}});
  s.evidence.push_back({"harmonic_balance", "Even harmonics not measurable.", NAN, 0, 0,
                        {Effect::kQuadraticStiffness, Effect::kCubicStiffness}});
  s.hotspots.push_back({kOddName, 32.0, 0.3, 3, 0.125, -0.2, 45.5});
  s.hotspots.push_back({"rec14", 50.0, 1.0, 1, -0.08, 0.1, 30.25});
  s.contact_window_s = 2e-3;
  s.residual_rms_near_contacts = 0.05;
  s.residual_rms_elsewhere = 0.0125;
  s.levels = {{0.1, 5, 31.2, 0.3, 0.002, 0.003, NAN},
              {0.3, 5, 32.5, 0.4, 0.004, 0.02, 1.2e-3},
              {1.0, 0, 35.3, 0.5, NAN, NAN, 0.9e-3}};
  return d;
}

// The same campaign with nothing chosen, no contacts and no resonance per level.
Diagnosis NothingMissing() {
  Diagnosis d = Named();
  d.after = d.before;
  d.fit_after = d.fit_before;
  d.chosen = -1;
  d.missing_physics.clear();
  d.curves.clear();
  d.candidates.erase(d.candidates.begin());
  d.conclusion = "Nothing missing.";
  d.model = d.base.model;
  d.model_note = "nothing missing: the base fit's model";
  d.signatures.residual_rms_near_contacts = d.signatures.residual_rms_elsewhere = NAN;
  for (Signatures::Level& level : d.signatures.levels) {
    level.mean_contact_time_s = NAN;
    level.resonance_hz = NAN;
  }
  return d;
}

// Nothing named, and the misfit unexplained with its missing-force surface (2 x 3 bins, one empty).
Diagnosis UnexplainedMisfit() {
  Diagnosis d = NothingMissing();
  d.conclusion = "unexplained: the model misses something no library effect explains";
  Unexplained u;
  u.heldout_chi2 = 4.4e4, u.heldout_residuals = 120, u.expected_chi2 = 118, u.threshold_chi2 = 171, u.p_value = 0;
  u.misfit_to_noise = 19.4;
  u.harmonic_chi2_per_residual = {3.0, NAN, 2.0};
  u.description = "misses by 19.4 x noise";
  MissingForceSurface& s = u.missing_force;
  s.x_m = {-1e-3, 1e-3};
  s.v_m_per_s = {-0.05, 0.0, 0.05};
  s.force_n = {0.01, NAN, -0.01, 0.012, 0.0, -0.012};
  s.standard_error_n = {0.001, NAN, 0.001, 0.002, 0.001, 0.002};
  s.samples = {5, 1, 7, 4, 9, 3};
  s.rms_n = 0.0063, s.term = "x^2 v", s.term_unit = "N s/m^3", s.term_coefficient = -2.01e5;
  s.term_r2 = 0.2, s.linear_r2 = 0.017;
  d.unexplained = u;
  return d;
}

size_t Count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t i = text.find(what); i != std::string::npos; i = text.find(what, i + 1)) ++n;
  return n;
}

// Empty when every element is closed in order (void and self-closed elements aside), every '<'
// opens a tag and every '&' an entity; else what is wrong and where.
std::string CheckMarkup(const std::string& html) {
  static const std::set<std::string> kVoid = {"meta", "br", "hr", "img", "input", "link", "col", "wbr"};
  std::vector<std::string> open;
  for (size_t i = html.find('<'); i != std::string::npos; i = html.find('<', i + 1)) {
    const size_t end = html.find('>', i);
    if (end == std::string::npos) return "unterminated tag at " + std::to_string(i);
    if (html[i + 1] == '!') continue;  // <!DOCTYPE>
    const bool closing = html[i + 1] == '/';
    size_t name_end = i + 1 + closing;
    while (name_end < end && (std::isalnum(static_cast<unsigned char>(html[name_end])) || html[name_end] == '-'))
      ++name_end;
    const std::string name = html.substr(i + 1 + closing, name_end - i - 1 - closing);
    if (name.empty()) return "stray '<' at " + std::to_string(i) + ": " + html.substr(i, 20);
    if (closing) {
      if (open.empty() || open.back() != name) {
        return "</" + name + "> at " + std::to_string(i) + " closes <" + (open.empty() ? "" : open.back()) + ">";
      }
      open.pop_back();
    } else if (html[end - 1] != '/' && !kVoid.count(name)) {
      open.push_back(name);
    }
  }
  if (!open.empty()) return "<" + open.back() + "> never closed";
  static const std::regex kBadAmpersand("&(?!(amp|lt|gt|quot|#[0-9]+);)");
  std::smatch m;
  if (std::regex_search(html, m, kBadAmpersand)) return "bare '&' at " + std::to_string(m.position(0));
  return "";
}

TEST(DiagnoseReportTest, NamedEffectPageHasConclusionNumbersAndFigures) {
  const std::filesystem::path dir = FreshDir("diagnose_named");
  WriteDiagnosisReport(Named(), dir / "nested");  // creates missing folders
  for (const std::string& name : DiagnosisReportFiles()) {
    ASSERT_TRUE(std::filesystem::is_regular_file(dir / "nested" / name)) << name;
  }
  const std::string html = ReadFile(dir / "nested/index.html");
  EXPECT_EQ(CheckMarkup(html), "");
  for (const char* expected : {
           // The conclusion, with the parameter's standard error (and relative: 1.2e5 / 2.3456e6).
           "Missing physics: <strong>cubic_stiffness</strong>",
           "k3 = (2.35 \u00b1 0.12)e+06 N/m^3 (5.1 %)",
           "explains the resonance shift &amp; the odd harmonics",
           // fit_before -> fit_after, improvement 1 - 0.01234 / 0.08125 and 1 - 0.0152 / 0.0931.
           "nrmse 0.08125 \u2192 0.01234 (84.8 % better)",
           "held-out nrmse 0.0931 \u2192 0.0152 (83.7 % better)",
           "<td class=\"num\">1301.5 \u00b1 8.3</td>",
           // Candidates: the chosen row highlighted; the skipped one's NaNs as "-", its note escaped.
           "<tr class=\"chosen\"><td>cubic_stiffness (chosen)</td>",
           "<td class=\"num\">540.5</td>",
           "<td>dry_friction</td><td>no</td><td>no</td><td class=\"num\">-</td>",
           "skipped: &lt;1 s of the budget left",
           // Evidence (NaN value: "-") and hotspots (12.5 %, -0.2 rad); the record name escaped.
           "<td class=\"num\">4.10 \u00b1 0.50</td><td class=\"num\">8.2</td>",
           "<td>quadratic_stiffness + cubic_stiffness</td>",
           "<td>rec&lt;&amp;&gt;7</td><td class=\"num\">32</td>",
           "<td class=\"num\">12.5</td><td class=\"num\">-0.2</td>",  // phase in rad, as everywhere
           "phase error [rad]", "arg C_h [rad]",
           // The residual near contacts in the contact figure's caption.
           "0.05 N within +-2 ms of the contacts, 0.0125 N elsewhere (ratio 4)",
       }) {
    EXPECT_THAT(html, HasSubstr(expected));
  }
  EXPECT_EQ(Count(html, "<tr class=\"chosen\">"), 1u);
  EXPECT_THAT(html, Not(HasSubstr(kOddName)));
  for (const char* bad : {">nan", ">inf", "-nan", "nan<", "[deg]"}) EXPECT_THAT(html, Not(HasSubstr(bad))) << bad;
  // One SVG per plot: 3 worst records x (magnitude, phase), FRF, K(x), 2 residual maps, resonance,
  // contact times, harmonic ratios.
  EXPECT_EQ(Count(html, "<svg"), 13u);
  for (const char* id : {"harmonics", "frf", "curves", "residual", "resonance", "contact", "ratios"})
    EXPECT_THAT(html, HasSubstr(std::string("<section id=\"") + id + "\">")) << id;
  // The one sentence in place of data: no maps were given.
  EXPECT_EQ(Count(html, "class=\"skipped\""), 1u);
  EXPECT_THAT(html, HasSubstr("<p class=\"skipped\">Saturation maps not computed.</p>"));
  // Self-contained: no script, nothing loaded from elsewhere.
  for (const char* external : {"<script", "src=", "href=\"http", "url(http"})
    EXPECT_THAT(html, Not(HasSubstr(external))) << external;
}

TEST(DiagnoseReportTest, NamedEffectTables) {
  const std::filesystem::path dir = FreshDir("diagnose_named_tables");
  WriteDiagnosisReport(Named(), dir);
  const auto records = Lines(ReadFile(dir / "records.csv"));
  ASSERT_EQ(records.size(), 16u);
  EXPECT_EQ(records[0],
            "name,frequency_hz,amplitude_v,heldout,clear,nrmse_before,chi2_before,model_period_before,"
            "contacts_per_period_before,nrmse_after,chi2_after,model_period_after,contacts_per_period_after");
  EXPECT_THAT(records[8], ::testing::StartsWith("rec<&>7,32,0.3,1,1,0.0255,"));
  const auto candidates = Lines(ReadFile(dir / "candidates.csv"));
  ASSERT_EQ(candidates.size(), 4u);
  // One value per cell: the effect parameters are a table of their own, one row per parameter.
  EXPECT_EQ(candidates[0],
            "label,chosen,fitted,converged,heldout_gain,fit_gain,nrmse,heldout_nrmse,chi2,heldout_chi2,"
            "residual_variance,passes,wall_time_s,decision,note");
  EXPECT_THAT(candidates[1], ::testing::StartsWith("cubic_stiffness,1,1,1,540.5,1350,0.01234,0.0152,160,55,1.02,3,12.5,"));
  EXPECT_EQ(candidates[3], "dry_friction,0,0,0,,,,,,,,0,0,,skipped: <1 s of the budget left");
  const auto parameters = Lines(ReadFile(dir / "candidate_parameters.csv"));
  ASSERT_EQ(parameters.size(), 3u);
  EXPECT_EQ(parameters[0], "candidate,parameter,value,standard_error,unit");
  EXPECT_EQ(parameters[1], "cubic_stiffness,k3,2345600,120000,N/m^3");
  EXPECT_EQ(parameters[2], "quadratic_stiffness,k2,150,400,N/m^2");
  const auto levels = Lines(ReadFile(dir / "levels.csv"));
  ASSERT_EQ(levels.size(), 4u);
  EXPECT_EQ(levels[1], "0.1,5,31.2,0.3,0.002,0.003,");
  EXPECT_EQ(levels[3], "1,0,35.3,0.5,,,0.0009");
}

// One section of the page, from its <section id="..."> to its end.
std::string PageSection(const std::string& html, const std::string& id) {
  const size_t begin = html.find("<section id=\"" + id + "\">");
  if (begin == std::string::npos) return "";
  return html.substr(begin, html.find("</section>", begin) - begin);
}

// The x coordinates of the first dashed polyline of an SVG (the base model's line).
std::vector<double> DashedLineXs(const std::string& svg) {
  static const std::regex kDashed("<polyline points=\"([^\"]*)\"[^>]*stroke-dasharray");
  std::smatch m;
  std::vector<double> xs;
  if (!std::regex_search(svg, m, kDashed)) return xs;
  std::istringstream points(m[1].str());
  std::string pair;
  while (points >> pair) xs.push_back(std::stod(pair.substr(0, pair.find(','))));
  return xs;
}

// With one amplitude level clear of the stop the resonance figure is one dot: the base model's
// resonance is still a line across the axis (it had no length), and the caption says why there is
// no trend to read.
TEST(DiagnoseReportTest, ResonanceOfOneLevelKeepsTheModelLineAndSaysSo) {
  Diagnosis d = Named();
  d.signatures.levels[1].resonance_hz = d.signatures.levels[2].resonance_hz = NAN;
  const std::string section = PageSection(DiagnosisHtml(d), "resonance");
  ASSERT_THAT(section, HasSubstr("<svg"));
  const std::vector<double> xs = DashedLineXs(section);
  ASSERT_EQ(xs.size(), 2u) << section;
  EXPECT_GT(xs[1] - xs[0], 100.0) << "the base model's line has (almost) no length";
  EXPECT_THAT(section, HasSubstr("Only one amplitude level (0.1 V) has 3 or more records clear of the stop"));
}

// The per-level FRF: levels coloured by amplitude with a colour bar, and a legend of the line
// styles only, above the data (a legend entry per level covered the points).
TEST(DiagnoseReportTest, FrfPerLevelHasAColourBarAndALegendClearOfThePoints) {
  const std::string section = PageSection(DiagnosisHtml(Named()), "frf");
  EXPECT_THAT(section, HasSubstr("<g class=\"colorbar\">"));
  EXPECT_THAT(section, HasSubstr("drive amplitude [V]"));
  const size_t legend = section.find("<g class=\"legend\">");
  ASSERT_NE(legend, std::string::npos);
  const std::string legend_svg = section.substr(legend, section.find("</g>", legend) - legend);
  EXPECT_THAT(legend_svg, Not(HasSubstr(" V<"))) << "a legend entry per level";
  EXPECT_THAT(legend_svg, HasSubstr("dots: measured"));
}

TEST(DiagnoseReportTest, NothingMissingSaysSoAndSkipsPlotsWithoutData) {
  const std::filesystem::path dir = FreshDir("diagnose_nothing");
  WriteDiagnosisReport(NothingMissing(), dir);
  const std::string html = ReadFile(dir / "index.html");
  EXPECT_EQ(CheckMarkup(html), "");
  EXPECT_THAT(html, HasSubstr("<strong>Nothing missing</strong>"));
  EXPECT_THAT(html, Not(HasSubstr("Missing physics")));
  EXPECT_THAT(html, HasSubstr("nrmse 0.08125 \u2192 0.08125 (0.0 % better)"));
  EXPECT_EQ(Count(html, "<tr class=\"chosen\">"), 0u);
  EXPECT_THAT(html, HasSubstr("No contact times: no amplitude level has impact spikes. No contacts: no time-domain "
                              "residual near contacts."));
  EXPECT_THAT(html, HasSubstr("No amplitude level has 3 or more records clear of the stop"));
  EXPECT_THAT(html, HasSubstr("Nothing was added to the model, so there is no second map."));
  // 3 worst records x 2, FRF, one residual map, harmonic ratios.
  EXPECT_EQ(Count(html, "<svg"), 9u);
  EXPECT_EQ(Count(html, "class=\"skipped\""), 4u);  // and the curves and the maps, not given
  EXPECT_THAT(html, HasSubstr("Nothing was named, so there is no characteristic to draw."));
}

TEST(DiagnoseReportTest, AnUnexplainedMisfitShowsTheMissingForceSurface) {
  const std::filesystem::path dir = FreshDir("diagnose_unexplained");
  WriteDiagnosisReport(UnexplainedMisfit(), dir);
  const std::string html = ReadFile(dir / "index.html");
  EXPECT_EQ(CheckMarkup(html), "");
  const size_t figure = html.find("<section id=\"missing_force\">");
  ASSERT_NE(figure, std::string::npos);
  const std::string section = html.substr(figure, html.find("</section>", figure) - figure);
  EXPECT_THAT(section, HasSubstr("<svg"));
  EXPECT_THAT(section, HasSubstr("x^2 v, -201000 N s/m^3"));
  // Without a surface (a coil's pole), the figure says why.
  Diagnosis coil = UnexplainedMisfit();
  coil.unexplained->missing_force = MissingForceSurface{};
  coil.unexplained->missing_force.note = "the model's coil force is a state of its own";
  WriteDiagnosisReport(coil, dir);
  EXPECT_THAT(ReadFile(dir / "index.html"), HasSubstr("No surface: the model's coil force is a state of its own."));
  // Nothing unexplained: no such figure.
  WriteDiagnosisReport(NothingMissing(), dir);
  EXPECT_THAT(ReadFile(dir / "index.html"), Not(HasSubstr("id=\"missing_force\"")));
}

TEST(DiagnoseReportTest, EmptyDiagnosisSkipsEveryFigure) {
  const std::filesystem::path dir = FreshDir("diagnose_empty");
  WriteDiagnosisReport(Diagnosis{}, dir);
  const std::string html = ReadFile(dir / "index.html");
  EXPECT_EQ(CheckMarkup(html), "");
  EXPECT_THAT(html, HasSubstr("Nothing missing"));
  EXPECT_EQ(Count(html, "<svg"), 0u);
  EXPECT_THAT(html, HasSubstr("No candidate was tried."));
  EXPECT_EQ(Lines(ReadFile(dir / "records.csv")).size(), 1u);
  EXPECT_EQ(Lines(ReadFile(dir / "levels.csv")).size(), 1u);
}

// ---- The maps of the base and the diagnosed model ---------------------------------------------

// The colour bar of the n-th SVG of the page.
std::string ColourBarOf(const std::string& html, size_t n) {
  size_t at = 0;
  for (size_t i = 0; i <= n; ++i) at = html.find("<svg", at + 1);
  const size_t bar = html.find("<g class=\"colorbar\">", at);
  return html.substr(bar, html.find("</g>", bar) - bar);
}

TEST(DiagnoseReportMapsTest, BothMapsOnOneScaleWithTheThresholdShift) {
  const std::filesystem::path dir = FreshDir("diagnose_maps");
  const Diagnosis d = Named();
  const DiagnosisMaps maps = MapsOf();
  WriteDiagnosisReport(d, dir, &maps);
  const std::string html = ReadFile(dir / "index.html");
  EXPECT_EQ(CheckMarkup(html), "");
  EXPECT_EQ(Count(html, "class=\"skipped\""), 0u);
  EXPECT_EQ(Count(html, "<svg"), 15u);  // the 13 figures and two maps
  for (const char* expected : {
           "<h2 id=\"maps\">What the missing physics changes for the control loop</h2>",
           "Diagnosed model: the base model extended by cubic_stiffness.",
           "Base model: stroke saturation, up-sweep branch",
           "Diagnosed model (+ cubic_stiffness): stroke saturation, up-sweep branch",
           "3 frequencies 5 – 20 Hz (geometric) x 2 amplitudes 0.1 – 0.3 V",
           // 5 Hz: grazing 0.3 -> 0.27 V (-10 %), lowest contacting 0.28 -> 0.25 V (-10.71 %).
           "<table class=\"threshold-shift\">",
           "<tr><td class=\"num\">5</td><td class=\"num\">0.3</td><td class=\"num\">0.27</td>"
           "<td class=\"num\">-0.0300</td><td class=\"num\">-10.00</td><td class=\"num\">0.28</td>"
           "<td class=\"num\">0.25</td><td class=\"num\">-0.0300</td><td class=\"num\">-10.71</td></tr>",
           // 20 Hz: only the diagnosed model reaches the stop.
           "<tr><td class=\"num\">20</td><td class=\"num\">-</td><td class=\"num\">0.4</td>"
           "<td class=\"num\">-</td><td class=\"num\">-</td>",
           "moves by -0.0300 V at most, at 5 Hz (0.3 → 0.27 V, -10.00 %); by -2.50 % on average over the 2 "
           "frequencies where both models reach the stop. At 1 frequency only the diagnosed model reaches the stop.",
           "<table class=\"jump-intervals\">",
           "<tr><td class=\"num\">0.3</td><td>10 – 14 Hz (fold – grazing)</td><td>none</td></tr>",
       }) {
    EXPECT_THAT(html, HasSubstr(expected));
  }
  // One colour scale (spike factor 1 .. 6 over both maps): the two colour bars are the same.
  const size_t maps_at = html.find("id=\"maps\""), first_map = Count(html.substr(0, maps_at), "<svg");
  EXPECT_EQ(ColourBarOf(html, first_map), ColourBarOf(html, first_map + 1));

  const auto shifts = Lines(ReadFile(dir / "threshold_shift.csv"));
  ASSERT_EQ(shifts.size(), 4u);
  EXPECT_EQ(shifts[0],
            "frequency_hz,grazing_base_v,grazing_diagnosed_v,grazing_shift_v,grazing_shift_percent,"
            "lowest_contact_base_v,lowest_contact_diagnosed_v,lowest_contact_shift_v,lowest_contact_shift_percent");
  EXPECT_THAT(shifts[1], ::testing::StartsWith("5,0.3,0.27,-0.0299999"));  // 0.27 - 0.3 in doubles
  EXPECT_THAT(shifts[1], ::testing::HasSubstr(",-9.99999"));
  EXPECT_EQ(shifts[3], "20,,0.4,,,,0.38,,");
  const auto jumps = Lines(ReadFile(dir / "jump_intervals.csv"));
  ASSERT_EQ(jumps.size(), 2u);
  EXPECT_EQ(jumps[1], "base,0.3,10,14,fold,grazing");
  // The model file is the diagnosed model as model files are written.
  const nlohmann::json model = nlohmann::json::parse(ReadFile(dir / "model.json"));
  EXPECT_EQ(model, ModelToJson(d.model));
  EXPECT_EQ(model["cubic_stiffness_n_per_m3"], 2.3456e6);
}

TEST(DiagnoseReportMapsTest, ThresholdShiftsMatchFrequenciesAndSayWhereOneIsMissing) {
  const DiagnosisMaps maps = MapsOf();
  SweepResult other = *maps.diagnosed;
  other.saturation_threshold.erase(other.saturation_threshold.begin() + 1);  // no 10 Hz column
  const std::vector<ThresholdShift> shifts = ThresholdShifts(*maps.base, other);
  ASSERT_EQ(shifts.size(), 3u);
  EXPECT_EQ(shifts[0].diagnosed_grazing_v, 0.27);
  EXPECT_TRUE(std::isnan(shifts[1].diagnosed_grazing_v));
  EXPECT_EQ(shifts[2].diagnosed_grazing_v, 0.4);
  EXPECT_NEAR(shifts[0].GrazingShiftPercent(), -10.0, 1e-12);
  EXPECT_EQ(ThresholdShiftSummary(shifts),
            "The grazing threshold (drive amplitude at which the stroke first reaches the stop) moves by -0.0300 V "
            "at most, at 5 Hz (0.3 → 0.27 V, -10.00 %); by -10.00 % on average over the 1 frequency where both "
            "models reach the stop. At 1 frequency only the base model reaches the stop. At 1 frequency only the "
            "diagnosed model reaches the stop.");
  EXPECT_EQ(ThresholdShiftSummary({}), "Neither model reaches the stop at any frequency of the grid.");
}

TEST(DiagnoseReportMapsTest, NothingMissingShowsOneMapAndNoShift) {
  const std::filesystem::path dir = FreshDir("diagnose_maps_nothing");
  DiagnosisMaps maps = MapsOf();
  maps.diagnosed = maps.base;
  maps.same_model = true;
  WriteDiagnosisReport(NothingMissing(), dir, &maps);
  const std::string html = ReadFile(dir / "index.html");
  EXPECT_EQ(CheckMarkup(html), "");
  EXPECT_EQ(Count(html, "<svg"), 10u);  // the 9 figures and one map
  EXPECT_THAT(html, HasSubstr("Base model = diagnosed model: stroke saturation, up-sweep branch"));
  EXPECT_THAT(html, HasSubstr("Nothing missing: the diagnosed model is the base model, so the threshold does not move."));
  EXPECT_THAT(html, HasSubstr("<td class=\"num\">+0.0000</td><td class=\"num\">+0.00</td>"));
  EXPECT_THAT(html, Not(HasSubstr("moves by")));
  EXPECT_EQ(Lines(ReadFile(dir / "threshold_shift.csv")).size(), 4u);
}

TEST(DiagnoseReportMapsTest, MissingMapsAreSaidWhyAndLeaveEmptyTables) {
  const std::filesystem::path dir = FreshDir("diagnose_maps_missing");
  DiagnosisMaps failed = MapsOf();
  failed.diagnosed.reset();
  failed.diagnosed_note = "the sweep failed: <CVode> gave up";
  WriteDiagnosisReport(Named(), dir, &failed);
  std::string html = ReadFile(dir / "index.html");
  EXPECT_EQ(CheckMarkup(html), "");
  EXPECT_EQ(Count(html, "<svg"), 14u);
  EXPECT_THAT(html, HasSubstr("Diagnosed model (+ cubic_stiffness): stroke saturation, up-sweep branch: no map, the "
                              "sweep failed: &lt;CVode&gt; gave up"));
  EXPECT_THAT(html, Not(HasSubstr("threshold-shift")));
  EXPECT_EQ(Lines(ReadFile(dir / "threshold_shift.csv")).size(), 1u);
  EXPECT_EQ(Lines(ReadFile(dir / "jump_intervals.csv")).size(), 1u);
  // A map with a failed row: its jump intervals there are unknown, not absent.
  DiagnosisMaps holed = MapsOf();
  std::erase_if(holed.diagnosed->points, [](const SweepPoint& p) { return p.amplitude_v == 0.3; });
  holed.diagnosed->failures = {"row at 0.3 V: <CVode> gave up"};
  WriteDiagnosisReport(Named(), dir, &holed);
  html = ReadFile(dir / "index.html");
  EXPECT_THAT(html, HasSubstr("1 of 5 rows and columns failed numerically and are left blank: row at 0.3 V: "
                              "&lt;CVode&gt; gave up"));
  EXPECT_THAT(html, HasSubstr("<tr><td class=\"num\">0.3</td><td>10 \u2013 14 Hz (fold \u2013 grazing)</td>"
                              "<td>not known: this amplitude's row failed</td></tr>"));

  DiagnosisMaps off;
  off.note = "not computed (map_frequency_points or map_amplitude_points is 0)";
  WriteDiagnosisReport(Named(), dir, &off);
  html = ReadFile(dir / "index.html");
  EXPECT_THAT(html, HasSubstr("Saturation maps not computed (map_frequency_points or map_amplitude_points is 0)."));
  EXPECT_EQ(Count(html, "<svg"), 13u);
}

// ---- A diagnosis as data (what a remote worker sends) --------------------------------------------

// The report and result document written from the data, after a text round trip as over HTTP.
void ExpectSameReportFromData(const Diagnosis& d, const DiagnosisMaps& maps, const std::string& name) {
  const nlohmann::json sent = nlohmann::json::parse(DiagnosisDataToJson(d, maps).dump());
  const DiagnosisData got = DiagnosisDataFromJson(sent);
  EXPECT_EQ(DiagnosisToJson(got.diagnosis).dump(), DiagnosisToJson(d).dump()) << name;
  const std::filesystem::path direct = FreshDir("data_direct_" + name), rebuilt = FreshDir("data_rebuilt_" + name);
  WriteDiagnosisReport(d, direct, &maps);
  WriteDiagnosisReport(got.diagnosis, rebuilt, &got.maps);
  for (const std::string& file : DiagnosisReportFiles())
    EXPECT_EQ(ReadFile(rebuilt / file), ReadFile(direct / file)) << name << ": " << file;
}

TEST(DiagnosisDataTest, TheReportFromDataIsTheReportFromTheDiagnosis) {
  Diagnosis named = Named();  // and the members Named leaves at their defaults
  named.base.model_kind = FitModelKind::kLinear;
  named.base.absolute_scale = false;
  named.base.identifiability = "k_s not identifiable: no contacts";
  named.base.warnings = {"rec3: drive 2 % off the manifest"};
  named.before[1].power = 2.5;
  named.before[1].model_period = 2;
  named.candidates[0].model.cubic_stiffness_n_per_m3 = 2e6;
  ExpectSameReportFromData(named, MapsOf(), "named");
  DiagnosisMaps same = MapsOf();
  same.same_model = true;
  same.diagnosed.reset();
  same.base->failures = {"row at 0.3 V: no periodic orbit"};
  ExpectSameReportFromData(NothingMissing(), same, "nothing");
  ExpectSameReportFromData(UnexplainedMisfit(), same, "unexplained");
  DiagnosisMaps none;
  none.note = "no maps: map_frequency_points is 0";
  ExpectSameReportFromData(Diagnosis{}, none, "empty");
}

TEST(DiagnosisDataTest, AWorkersMarkupIsRenderedAsText) {
  Diagnosis d = Named();
  const std::string markup = "<script>alert(1)</script><img src=x onerror=alert(2)>";
  d.conclusion = d.model_note = d.candidates[1].note = d.signatures.evidence[0].summary = markup;
  d.before[0].name = d.after[0].name = markup;
  DiagnosisMaps maps = MapsOf();
  maps.base_note = markup;
  const DiagnosisData got = DiagnosisDataFromJson(DiagnosisDataToJson(d, maps));
  const std::filesystem::path dir = FreshDir("data_markup");
  WriteDiagnosisReport(got.diagnosis, dir, &got.maps);
  const std::string html = ReadFile(dir / "index.html");
  EXPECT_EQ(CheckMarkup(html), "");
  EXPECT_THAT(html, Not(HasSubstr("<script")));
  EXPECT_THAT(html, Not(HasSubstr("<img")));
  EXPECT_THAT(html, HasSubstr("&lt;script&gt;alert(1)&lt;/script&gt;"));
}

// The JSON pointer of the member that DiagnosisDataFromJson refuses in `good` spoiled by `spoil`, or
// "(accepted)".
std::string RefusedMember(const nlohmann::json& good, const std::function<void(nlohmann::json&)>& spoil) {
  nlohmann::json bad = good;
  spoil(bad);
  try {
    DiagnosisDataFromJson(bad);
  } catch (const InputError& e) {
    return e.field();
  }
  return "(accepted)";
}

// The missing-force surface a worker sends is checked as the rest: sizes bounded, numbers finite.
TEST(DiagnosisDataTest, ABadMissingForceSurfaceIsRefusedNamingTheMember) {
  const nlohmann::json good = DiagnosisDataToJson(UnexplainedMisfit(), MapsOf());
  ASSERT_NO_THROW(DiagnosisDataFromJson(good));
  const auto field_of = [&](const std::function<void(nlohmann::json&)>& spoil) { return RefusedMember(good, spoil); };
  using nlohmann::json;
  const std::string at = "/diagnosis/unexplained/missing_force";
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["unexplained"]["missing_force"]["x_m"] = std::vector<double>(65, 0.0); }),
            at + "/x_m");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["unexplained"]["missing_force"]["force_n"][1][0] = "big"; }),
            at + "/force_n/1/0");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["unexplained"]["missing_force"]["force_n"][1].push_back(1.0); }),
            at + "/force_n/1");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["unexplained"]["missing_force"]["samples"][0][0] = 1e300; }),
            at + "/samples");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["unexplained"]["places"] = json::array(); j["diagnosis"]["unexplained"]["missing_force"] = 3; }),
            at);
}

// Each damaged document is refused naming the member, as the server answers a worker's completion.
TEST(DiagnosisDataTest, BadDataIsRefusedNamingTheMember) {
  const nlohmann::json good = DiagnosisDataToJson(Named(), MapsOf());
  ASSERT_NO_THROW(DiagnosisDataFromJson(good));
  const auto field_of = [&](const std::function<void(nlohmann::json&)>& spoil) { return RefusedMember(good, spoil); };
  using nlohmann::json;
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"].erase("conclusion"); }), "/diagnosis/conclusion");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["before"][2]["nrmse"] = "small"; }), "/diagnosis/before/2/nrmse");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["before"][2]["nrmse"] = INFINITY; }), "/diagnosis/before/2/nrmse");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["candidates"][1]["effects"][0] = "magic"; }),
            "/diagnosis/candidates/1/effects/0");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["chosen"] = 3; }), "/diagnosis/chosen");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["chosen"] = -1; }), "/diagnosis/chosen");  // yet an effect is named
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["heldout"][0] = 15; }), "/diagnosis/heldout/0");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["after"].erase(0); }), "/diagnosis/after");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["before"][0]["measured"] = json(std::vector<json>(65, {1, 0})); }),
            "/diagnosis/before/0/measured");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["conclusion"] = std::string(70'000, 'x'); }), "/diagnosis/conclusion");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["model"]["mass_kg"] = -1; }).rfind("/diagnosis/model", 0), 0u);
  EXPECT_EQ(field_of([](json& j) { j["maps"]["base"]["points"][0]["peak_force_n"] = INFINITY; }),
            "/maps/base/points/0/peak_force_n");
  EXPECT_EQ(field_of([](json& j) { j["maps"]["diagnosed"]["jump"] = json::object(); }), "/maps/diagnosed/jump");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["curves"][0]["effect"] = "magic"; }), "/diagnosis/curves/0/effect");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["curves"][0]["y_se"][3] = "wide"; }), "/diagnosis/curves/0/y_se/3");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["curves"][0]["y"].erase(0); }), "/diagnosis/curves/0");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["curves"][0]["x"][0] = nullptr; }), "/diagnosis/curves/0/x/0");
  EXPECT_EQ(field_of([](json& j) { j.erase("maps"); }), "/maps");
}

}  // namespace
}  // namespace strokelab::report
