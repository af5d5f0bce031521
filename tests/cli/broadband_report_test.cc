// The broadband diagnosis's report (report/broadband_report.h) on hand-made diagnoses: a named effect
// with its figures and tables, an unexplained misfit with the parts where it lives, and the folder's
// files read back.
#include "strokelab/report/broadband_report.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <regex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "quiet_multisines.h"
#include "report_test_util.h"
#include "strokelab/data/synth.h"
#include "strokelab/model/model_json.h"
#include "strokelab/base/errors.h"
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

BroadbandRecordMatch Match(const std::string& name, double drive_v, double chi2, double heldout_chi2) {
  BroadbandRecordMatch m;
  m.name = name;
  m.drive_rms_v = drive_v;
  m.noise_rms = 1e-4;
  m.nrmse = 0.1 * std::sqrt(chi2);
  m.heldout_nrmse = 0.1 * std::sqrt(heldout_chi2);
  m.chi2_per_sample = chi2;
  m.heldout_chi2_per_sample = heldout_chi2;
  return m;
}

// k3 named: the base misses the loudest record, the diagnosed model fits all three within noise.
BroadbandDiagnosis NamedCubic() {
  BroadbandDiagnosis d;
  d.base.result.fit.parameters = {Parameter("k_p", "N/m", 122.1, 0.25), Parameter("g", "N/V", 0.2934, 2e-4)};
  d.before = {Match("rec_001.csv", 0.1, 1.01, 0.99), Match("rec_002.csv", 0.25, 1.3, 1.4),
              Match("rec_003.csv", 0.5, 9.0, 11.0)};
  d.after = {Match("rec_001.csv", 0.1, 1.0, 0.99), Match("rec_002.csv", 0.25, 1.0, 1.01),
             Match("rec_003.csv", 0.5, 1.02, 1.03)};
  d.fit_before = {0.14, 0.15, 52000, 18000, 8.4};
  d.fit_after = {0.05, 0.05, 6100, 2030, 1.0};
  CandidateFit k3;
  k3.effects = {Effect::kCubicStiffness};
  k3.label = "cubic_stiffness";
  k3.fitted = k3.converged = true;
  k3.parameters = {Parameter("k_p", "N/m", 121.0, 0.2), Parameter("k3", "N/m^3", 1.49e7, 9.5e4)};
  k3.effect_parameters = {k3.parameters[1]};
  k3.figures = d.fit_after;
  k3.heldout_gain = 15970;
  k3.decision = "named";
  CandidateFit friction;
  friction.effects = {Effect::kDryFriction};
  friction.label = "dry_friction";
  friction.fitted = true;
  friction.heldout_gain = 3.2;
  friction.decision = "rejected: held-out gain 3.2 <= 10";
  d.candidates = {k3, friction};
  d.chosen = 0;
  d.missing_physics = {Effect::kCubicStiffness};
  d.model = PaperModel();
  d.model.cubic_stiffness_n_per_m3 = 1.49e7;
  d.conclusion = "missing physics: cubic_stiffness (held-out chi-square down by 15970 residual variances)";
  Evidence far_out;
  far_out.kind = "residual_far_out";
  far_out.summary = "the residual's chi-square per sample is 9 far out against 1 elsewhere";
  far_out.value = 8.0;
  far_out.standard_error = 0.1;
  far_out.significance = 80;
  far_out.points_to = {Effect::kCubicStiffness};
  d.evidence = {far_out};
  d.seconds = 23.0;
  return d;
}

TEST(BroadbandReportTest, NamedEffectPageHasTheVerdictTablesAndBothPartsFigures) {
  const std::string html = BroadbandDiagnosisHtml(NamedCubic());
  EXPECT_THAT(html, HasSubstr("Missing physics: <strong>cubic_stiffness</strong>"));
  EXPECT_THAT(html, HasSubstr("k3 = (1.4900 \u00b1 0.0095)e+07 N/m^3 (0.64 %)"));
  EXPECT_THAT(html, HasSubstr("rejected: held-out gain 3.2 &lt;= 10"));  // the candidates' decisions
  EXPECT_THAT(html, HasSubstr("residual_far_out"));
  EXPECT_THAT(html, HasSubstr("Saturation maps not computed."));  // no maps given
  // The conclusion once; the parts figure's two panels (fit parts and held-out parts) with the noise
  // line and both models; no unexplained section.
  EXPECT_EQ(std::regex_search(html, std::regex("held-out chi-square down by 15970.*held-out chi-square down by 15970")),
            false);
  EXPECT_THAT(html, HasSubstr("Held-out parts (no fit saw them)"));
  EXPECT_THAT(html, HasSubstr(">diagnosed model<"));
  EXPECT_THAT(html, HasSubstr(">noise alone<"));
  EXPECT_THAT(html, Not(HasSubstr("What is left unexplained")));
  size_t svgs = 0;
  for (size_t at = html.find("<svg"); at != std::string::npos; at = html.find("<svg", at + 1)) ++svgs;
  EXPECT_EQ(svgs, 2u);  // the two panels; no curves (none in this diagnosis), said instead
  EXPECT_THAT(html, HasSubstr("Nothing was named, so there is no characteristic to draw."));
}

TEST(BroadbandReportTest, AnUnexplainedMisfitNamesThePartsWhereItLives) {
  BroadbandDiagnosis d = NamedCubic();
  d.candidates[0].decision = "not named: removes only part";
  d.chosen = -1;
  d.missing_physics.clear();
  d.after = d.before;
  d.fit_after = d.fit_before;
  BroadbandUnexplained u;
  u.chi2 = 18000;
  u.dof = 6100;
  u.threshold_chi2 = 6900;
  u.misfit_to_noise = std::sqrt(18000.0 / 6100.0);
  u.places = {{"rec_003.csv", 11.0, 16.0, 0.4, 0.02}};
  d.unexplained = u;
  d.conclusion = "unexplained: the model misses something no library effect explains";
  const std::string html = BroadbandDiagnosisHtml(d);
  EXPECT_THAT(html, HasSubstr("<strong>Unexplained</strong>"));
  EXPECT_THAT(html, HasSubstr("What is left unexplained"));
  EXPECT_THAT(html, HasSubstr("<td>rec_003.csv</td><td class=\"num\">11</td><td class=\"num\">16</td>"));
  EXPECT_THAT(html, HasSubstr("Nothing was named, so only the base model is drawn."));
  EXPECT_THAT(html, Not(HasSubstr(">diagnosed model<")));
}

TEST(BroadbandReportTest, TheFolderHoldsItsFilesAndTheModelReadsBack) {
  const BroadbandDiagnosis d = NamedCubic();
  const auto dir = FreshDir("broadband_report");
  WriteBroadbandDiagnosisReport(d, dir);
  for (const std::string& name : BroadbandDiagnosisReportFiles()) EXPECT_TRUE(std::filesystem::exists(dir / name)) << name;
  const std::vector<std::string> records = Lines(ReadFile(dir / "records.csv"));
  ASSERT_EQ(records.size(), 4u);
  EXPECT_EQ(records[3], "rec_003.csv,0.5,0.0001,0.3,9,0.331662479,11,0.1009950494,1.02,0.1014889157,1.03");
  EXPECT_THAT(ReadFile(dir / "candidates.csv"), HasSubstr("dry_friction,0,1,0,3.2"));
  EXPECT_THAT(ReadFile(dir / "candidate_parameters.csv"), HasSubstr("cubic_stiffness,k3,14900000,95000,N/m^3"));
  const ActuatorModel model = ModelFromJson(nlohmann::json::parse(ReadFile(dir / "model.json")));
  EXPECT_EQ(model.cubic_stiffness_n_per_m3, 1.49e7);
}

// With both models' maps, the page has the stepped report's maps section (both maps, the threshold's
// shift per frequency, the jump intervals) and the folder their tables.
TEST(BroadbandReportTest, TheMapsOfBothModelsAndTheThresholdShift) {
  const BroadbandDiagnosis d = NamedCubic();
  const DiagnosisMaps maps = MapsOf();
  const auto dir = FreshDir("broadband_report_maps");
  WriteBroadbandDiagnosisReport(d, dir, &maps);
  const std::string html = ReadFile(dir / "index.html");
  EXPECT_THAT(html, HasSubstr("<h2 id=\"maps\">What the missing physics changes for the control loop</h2>"));
  EXPECT_THAT(html, HasSubstr("Diagnosed model (+ cubic_stiffness): stroke saturation, up-sweep branch"));
  EXPECT_THAT(html, HasSubstr("<td class=\"num\">-0.0300</td><td class=\"num\">-10.00</td>"));  // 5 Hz: 0.3 -> 0.27 V
  EXPECT_THAT(html, HasSubstr("<tr><td class=\"num\">0.3</td><td>10 \u2013 14 Hz (fold \u2013 grazing)</td><td>none</td></tr>"));
  EXPECT_THAT(html, Not(HasSubstr("class=\"skipped\">Saturation maps")));
  const std::vector<std::string> shifts = Lines(ReadFile(dir / "threshold_shift.csv"));
  ASSERT_EQ(shifts.size(), 4u);  // the header and 5, 10, 20 Hz
  EXPECT_EQ(shifts[1].rfind("5,0.3,0.27,", 0), 0u) << shifts[1];
  EXPECT_THAT(ReadFile(dir / "jump_intervals.csv"), HasSubstr("base,0.3,10,14,fold,grazing"));
}

// The maps' grid from the records: their drives' band (multisines over 2-200 Hz) and sine amplitudes
// from the quietest drive's rms times sqrt 2 to the largest drive peak; the paper model swept on it
// (the diagnosed model is the base model: one sweep).
TEST(BroadbandReportTest, TheMapsGridSpansTheDrivesBandAndLevels) {
  SynthOptions o;
  o.excitation = Excitation::kMultisine;
  o.levels_v_rms = {0.1, 0.3};
  o.duration_s = 0.5;
  o.settle_s = 0.5;
  o.sample_rate_hz = 4096.0;
  const Campaign campaign = Synthesize(PaperModel(), o).campaign;
  BroadbandDiagnosis d;
  d.base.result.fit.model = PaperModel();
  d.model = PaperModel();
  DiagnoseOptions options;
  options.map_frequency_points = 4;
  options.map_amplitude_points = 3;
  const DiagnosisMaps maps = SweepBroadbandDiagnosisMaps(d, campaign, options);
  ASSERT_EQ(maps.note, "");
  EXPECT_NEAR(maps.frequency_hz.from, 2.0, 0.1);  // the multisine's lowest line (2 Hz: 1 / duration apart)
  EXPECT_NEAR(maps.frequency_hz.to, 200.0, 2.0);
  EXPECT_TRUE(maps.frequency_hz.geometric);
  EXPECT_NEAR(maps.amplitude_v.from, 0.1 * std::sqrt(2.0), 1e-3);
  double peak = 0.0;
  for (const Recording& r : campaign.records)
    for (double u : r.voltage_v) peak = std::max(peak, std::abs(u));
  EXPECT_DOUBLE_EQ(maps.amplitude_v.to, peak);
  EXPECT_GT(peak, 0.3 * std::sqrt(2.0));  // a multisine's crest factor is above a sine's
  EXPECT_TRUE(maps.same_model);
  ASSERT_TRUE(maps.base);
  EXPECT_EQ(maps.base->points.size() >= 12u, true);
  EXPECT_EQ(maps.base->saturation_threshold.size(), 4u);
}


// ---- A broadband diagnosis as data (what a remote worker sends) ----------------------------------

// The result document and the report written from the data, after a text round trip as over HTTP.
void ExpectSameReportFromData(const BroadbandDiagnosis& d, const DiagnosisMaps& maps, const std::string& name) {
  const nlohmann::json sent = nlohmann::json::parse(BroadbandDiagnosisDataToJson(d, maps).dump());
  const BroadbandDiagnosisData got = BroadbandDiagnosisDataFromJson(sent);
  EXPECT_EQ(BroadbandDiagnosisToJson(got.diagnosis, got.base_fit).dump(), BroadbandDiagnosisToJson(d).dump()) << name;
  const auto direct = FreshDir("bb_data_direct_" + name), rebuilt = FreshDir("bb_data_rebuilt_" + name);
  WriteBroadbandDiagnosisReport(d, direct, &maps);
  WriteBroadbandDiagnosisReport(got.diagnosis, rebuilt, &got.maps);
  for (const std::string& file : BroadbandDiagnosisReportFiles())
    EXPECT_EQ(ReadFile(rebuilt / file), ReadFile(direct / file)) << name << ": " << file;
}

BroadbandDiagnosis Unexplained() {
  BroadbandDiagnosis d = NamedCubic();
  d.chosen = -1;
  d.missing_physics.clear();
  d.after.clear();
  BroadbandUnexplained u;
  u.parts = "fit";
  u.chi2 = 18000;
  u.dof = 6100;
  u.threshold_chi2 = 6900;
  u.misfit_to_noise = std::sqrt(18000.0 / 6100.0);
  u.places = {{"rec_003.csv", 11.0, 16.0, 0.4, NAN}};
  u.description = "rings at about 40 Hz after every impact";
  d.unexplained = u;
  return d;
}

TEST(BroadbandDiagnosisDataTest, TheReportFromDataIsTheReportFromTheDiagnosis) {
  BroadbandDiagnosis named = NamedCubic();  // and base members NamedCubic leaves at their defaults
  named.base.model_kind = FitModelKind::kLinear;
  named.base.response = ResponseKind::kAcceleration;
  named.base.absolute_scale = false;
  named.base.result.rejected = true;
  named.base.result.fit.converged = false;
  named.base.start_record = "rec_002.csv";
  named.heldout_every = 3;
  named.heldout_dof = 2048;
  named.warnings = {"record rec_9.csv is a stepped sine: not used"};
  ExpectSameReportFromData(named, MapsOf(), "named");
  DiagnosisMaps none;
  none.note = "no maps: map_frequency_points is 0";
  ExpectSameReportFromData(Unexplained(), none, "unexplained");
  ExpectSameReportFromData(BroadbandDiagnosis{}, none, "empty");
}

// A diagnosis of real records (the paper model's quiet multisines: nothing missing) with its maps.
TEST(BroadbandDiagnosisDataTest, ADiagnosisOfRecordsComesBackWhole) {
  const Campaign campaign = ::strokelab::testing::QuietMultisines(13).campaign;
  DiagnoseOptions options;
  options.map_frequency_points = 4;
  options.map_amplitude_points = 3;
  const BroadbandDiagnosis d = DiagnoseBroadbandCampaign(campaign, options);
  ASSERT_FALSE(d.base.result.fit.parameters.empty());
  const DiagnosisMaps maps = SweepBroadbandDiagnosisMaps(d, campaign, options);
  ASSERT_TRUE(maps.base);
  ExpectSameReportFromData(d, maps, "records");
}

TEST(BroadbandDiagnosisDataTest, AWorkersMarkupIsRenderedAsText) {
  BroadbandDiagnosis d = Unexplained();
  const std::string markup = "<script>alert(1)</script><img src=x onerror=alert(2)>";
  d.conclusion = d.model_note = d.candidates[1].decision = d.evidence[0].summary = markup;
  d.before[0].name = d.unexplained->places[0].record = d.unexplained->description = markup;
  d.warnings = {markup};
  const BroadbandDiagnosisData got = BroadbandDiagnosisDataFromJson(BroadbandDiagnosisDataToJson(d, MapsOf()));
  const std::string html = BroadbandDiagnosisHtml(got.diagnosis, &got.maps);
  EXPECT_THAT(html, Not(HasSubstr("<script")));
  EXPECT_THAT(html, Not(HasSubstr("<img")));
  EXPECT_THAT(html, HasSubstr("&lt;script&gt;alert(1)&lt;/script&gt;"));
}

// Each damaged document is refused naming the member, as the server answers a worker's completion.
TEST(BroadbandDiagnosisDataTest, BadDataIsRefusedNamingTheMember) {
  const nlohmann::json good = BroadbandDiagnosisDataToJson(Unexplained(), MapsOf());
  ASSERT_NO_THROW(BroadbandDiagnosisDataFromJson(good));
  using nlohmann::json;
  const auto field_of = [&](const std::function<void(json&)>& spoil) -> std::string {
    json bad = good;
    spoil(bad);
    try {
      BroadbandDiagnosisDataFromJson(bad);
    } catch (const InputError& e) {
      return e.field();
    }
    return "(accepted)";
  };
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"].erase("conclusion"); }), "/diagnosis/conclusion");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["before"][1]["chi2_per_sample"] = "small"; }),
            "/diagnosis/before/1/chi2_per_sample");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["after"] = json::array({json::object()}); }), "/diagnosis/after/0/name");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["after"] = json::array({j["diagnosis"]["before"][0]}); }),
            "/diagnosis/after");  // not record for record
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["base"]["fit"] = "a page"; }), "/diagnosis/base/fit");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["base"]["fit"].erase("parameters"); }), "/diagnosis/base/fit/parameters");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["base"]["response"] = "smell"; }), "/diagnosis/base/response");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["base"]["converged"] = 1; }), "/diagnosis/base/converged");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["heldout_every"] = 1; }), "/diagnosis/heldout_every");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["candidates"][0]["effects"][0] = "magic"; }),
            "/diagnosis/candidates/0/effects/0");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["chosen"] = 0; }), "/diagnosis/chosen");  // yet nothing named
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["unexplained"]["parts"] = "all"; }), "/diagnosis/unexplained/parts");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["unexplained"]["places"][0]["peak_frequency_hz"] = json::array(); }),
            "/diagnosis/unexplained/places/0/peak_frequency_hz");
  EXPECT_EQ(field_of([](json& j) { j["diagnosis"]["warnings"][0] = std::string(70'000, 'x'); }), "/diagnosis/warnings/0");
  EXPECT_EQ(field_of([](json& j) { j["maps"]["base"]["points"][0]["peak_force_n"] = "big"; }).rfind("/maps/base/points/0", 0), 0u);
  EXPECT_EQ(field_of([](json& j) { j.erase("maps"); }), "/maps");
}

}  // namespace
}  // namespace strokelab::report
