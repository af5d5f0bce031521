// The diagnosed model is usable (issue 12, point 4). End to end on small synthetic campaigns
// (`strokelab synth`): `strokelab diagnose --out DIR` writes DIR/model.json, equal to the JSON
// result's "model", which `strokelab sweep --model`, `strokelab simulate --model` and a sweep job's
// "model" take as it is; the report shows the saturation maps of both models and the threshold
// shift. A piecewise-linear effect (amplifier clipping, ~12 s) runs with the test command; a smooth
// one (cubic stiffness, simulated with --method cvode) is labelled slow. And SweepDiagnosisMaps
// (report/diagnosis_maps.h) on hand-made diagnoses: its grid, one sweep for an unchanged model,
// the time budget, maps turned off.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "report_test_util.h"
#include "run_cli.h"
#include "strokelab/jobs/job_spec.h"
#include "strokelab/model/model_json.h"
#include "strokelab/report/diagnosis_maps.h"

namespace strokelab {
namespace {

namespace fs = std::filesystem;
using ::strokelab::testing::FreshDir;
using ::strokelab::testing::Lines;
using ::strokelab::testing::ReadFile;
using ::strokelab::testing::RunCli;
using ::testing::HasSubstr;

struct DiagnosedCampaign {
  fs::path out;               // diagnose --out
  nlohmann::json result;      // DIR/diagnosis.json: the JSON result
  nlohmann::json model_file;  // DIR/model.json
  std::string stdout_text;
};

// `strokelab synth --out DIR/campaign SYNTH_ARGS` (12 records: 5-11 Hz x 0.1-0.5 V, noise), then
// `strokelab diagnose --data DIR/campaign --out DIR/diagnosis --no-pairs DIAGNOSE_ARGS`.
DiagnosedCampaign SynthAndDiagnose(const std::string& name, const std::string& synth_args,
                                   const std::string& diagnose_args) {
  const fs::path dir = FreshDir(name);
  const auto synth = RunCli("synth --out " + (dir / "campaign").string() +
                            " --frequencies-hz 5,7,9,11 --amplitudes-v 0.1,0.3,0.5 --settle-s 5 --noise-rms 5e-4"
                            " --seed 12 " + synth_args);
  EXPECT_EQ(synth.exit_code, 0) << synth.stderr_text;
  DiagnosedCampaign d;
  d.out = dir / "diagnosis";
  const auto diagnose = RunCli("diagnose --data " + (dir / "campaign").string() + " --out " + d.out.string() +
                               " --no-pairs " + diagnose_args);
  EXPECT_EQ(diagnose.exit_code, 0) << diagnose.stderr_text;
  d.stdout_text = diagnose.stdout_text;
  if (fs::is_regular_file(d.out / "diagnosis.json")) d.result = nlohmann::json::parse(ReadFile(d.out / "diagnosis.json"));
  if (fs::is_regular_file(d.out / "model.json")) d.model_file = nlohmann::json::parse(ReadFile(d.out / "model.json"));
  return d;
}

// The model file is what the result carries, and every consumer of models takes it as it is: sweep
// --model (a small grid), simulate --model (cvode, which runs any model), a sweep job's "model".
void ExpectTheModelFileIsUsable(const DiagnosedCampaign& d, const std::string& sweep_grid) {
  ASSERT_TRUE(fs::is_regular_file(d.out / "model.json"));
  EXPECT_EQ(d.model_file, d.result.at("model"));
  EXPECT_THAT(d.stdout_text, HasSubstr("model file: " + (d.out / "model.json").string()));
  const std::string file = (d.out / "model.json").string();

  const auto sweep = RunCli("sweep --model " + file + " " + sweep_grid + " --threads 2 --json");
  ASSERT_EQ(sweep.exit_code, 0) << sweep.stderr_text;
  const nlohmann::json swept = nlohmann::json::parse(sweep.stdout_text);
  EXPECT_EQ(swept["model"], d.model_file);
  EXPECT_FALSE(swept["points"].empty());

  const auto simulate =
      RunCli("simulate --model " + file + " --method cvode --frequency-hz 8 --amplitude-v 0.45 --duration-s 0.5 --json");
  ASSERT_EQ(simulate.exit_code, 0) << simulate.stderr_text;
  EXPECT_EQ(nlohmann::json::parse(simulate.stdout_text)["model"], d.model_file);

  const nlohmann::json job = {{"kind", "sweep"},
                              {"model", d.model_file},
                              {"grid", {{"frequency_hz", {{"from", 6}, {"to", 9}, {"points", 3}}},
                                        {"amplitude_v", {{"from", 0.2}, {"to", 0.5}, {"points", 2}}}}}};
  EXPECT_EQ(ModelToJson(jobs::SweepSpecFromJob(job).model), d.model_file);
}

// The report: both maps, the threshold table with a row per map frequency, its CSV.
void ExpectBothMapsAndTheShift(const DiagnosedCampaign& d, const std::string& effect, size_t map_frequencies) {
  const std::string html = ReadFile(d.out / "index.html");
  EXPECT_THAT(html, HasSubstr("<h2 id=\"maps\">What the missing physics changes for the control loop</h2>"));
  EXPECT_THAT(html, HasSubstr("Base model: stroke saturation, up-sweep branch"));
  EXPECT_THAT(html, HasSubstr("Diagnosed model (+ " + effect + "): stroke saturation, up-sweep branch"));
  EXPECT_THAT(html, HasSubstr("<table class=\"threshold-shift\">"));
  EXPECT_THAT(html, HasSubstr("The grazing threshold (drive amplitude at which the stroke first reaches the stop) "
                              "moves by "));
  const size_t maps = html.find("id=\"maps\"");
  EXPECT_THAT(html.substr(maps, html.find("<h2", maps) - maps), ::testing::Not(HasSubstr("class=\"skipped\"")));
  EXPECT_EQ(Lines(ReadFile(d.out / "threshold_shift.csv")).size(), 1 + map_frequencies);
  EXPECT_THAT(d.stdout_text, HasSubstr("saturation maps: "));
}

TEST(DiagnosedModelCliTest, ClippingModelFileIsWhatSweepSimulateAndJobsTake) {
  const DiagnosedCampaign d = SynthAndDiagnose("diagnosed_clipping", "--set amplifier_limit_v=0.4",
                                               "--map-frequency-points 12 --map-amplitude-points 4");
  ASSERT_FALSE(d.result.is_null());
  ASSERT_EQ(d.result["missing_physics"].size(), 1u) << d.result["conclusion"];
  ASSERT_EQ(d.result["missing_physics"][0]["effect"], "amplifier_saturation");
  ASSERT_TRUE(d.result.contains("model")) << "the JSON result carries no model";
  EXPECT_NEAR(d.result["model"]["amplifier_limit_v"].get<double>(), 0.4, 0.02);
  EXPECT_THAT(d.result["model_note"].get<std::string>(), HasSubstr("extended by amplifier_saturation"));
  // The fitted parameters in their own shape, as before, beside the model.
  EXPECT_TRUE(d.result["missing_physics"][0]["all_parameters"].contains("amplifier_limit_v"));
  ExpectTheModelFileIsUsable(d, "--frequency-hz 6:9 --frequency-points 3 --amplitude-v 0.2:0.5 --amplitude-points 2");
  ExpectBothMapsAndTheShift(d, "amplifier_saturation", 12);
}

// Slow (label "slow", tests/cli/CMakeLists.txt; ~20 s here, more under load): a smooth suspension's
// candidates and map.
TEST(DiagnosedModelSlowTest, CubicStiffnessModelFileIsWhatSweepSimulateAndJobsTake) {
  const DiagnosedCampaign d =
      SynthAndDiagnose("diagnosed_cubic", "--set k3=3e7", "--map-frequency-points 6 --map-amplitude-points 3");
  ASSERT_FALSE(d.result.is_null());
  ASSERT_GE(d.result["missing_physics"].size(), 1u) << d.result["conclusion"];
  ASSERT_EQ(d.result["missing_physics"][0]["effect"], "cubic_stiffness");
  ASSERT_TRUE(d.result.contains("model")) << "the JSON result carries no model";
  // A hardening suspension, whatever the fit's accuracy on 9 fit records (tests/diagnose checks that).
  EXPECT_GT(d.result["model"]["cubic_stiffness_n_per_m3"].get<double>(), 0.0);
  ExpectTheModelFileIsUsable(d, "--frequency-hz 7:9 --frequency-points 2 --amplitude-v 0.3:0.5 --amplitude-points 2");
  ExpectBothMapsAndTheShift(d, "cubic_stiffness", 6);
}

// ---- SweepDiagnosisMaps on hand-made diagnoses -------------------------------------------------

// Records at 6 .. 13 Hz x 0.1 .. 0.5 V; the diagnosed model adds contact damping (piecewise
// linear: the exact engine's fast maps).
Diagnosis HandMadeDiagnosis() {
  Diagnosis d;
  d.base.model = PaperModel();
  d.model = PaperModel();
  d.model.contact_damping_n_s_per_m = 40;
  for (double f : {13.0, 6.0, 9.0})
    for (double v : {0.3, 0.1, 0.5}) {
      RecordMatch r;
      r.frequency_hz = f;
      r.amplitude_v = v;
      d.before.push_back(r);
    }
  d.seconds = 1;
  return d;
}

DiagnoseOptions MapOptions(int frequencies, int amplitudes) {
  DiagnoseOptions o;
  o.map_frequency_points = frequencies;
  o.map_amplitude_points = amplitudes;
  return o;
}

TEST(SweepDiagnosisMapsTest, SweepsBothModelsOverTheCampaignsRange) {
  const report::DiagnosisMaps maps = report::SweepDiagnosisMaps(HandMadeDiagnosis(), MapOptions(5, 3));
  EXPECT_EQ(maps.note, "");
  EXPECT_FALSE(maps.same_model);
  EXPECT_EQ(maps.frequency_hz.from, 6.0);
  EXPECT_EQ(maps.frequency_hz.to, 13.0);
  EXPECT_TRUE(maps.frequency_hz.geometric);
  EXPECT_EQ(maps.amplitude_v.from, 0.1);
  EXPECT_EQ(maps.amplitude_v.to, 0.5);
  ASSERT_TRUE(maps.base && maps.diagnosed) << maps.base_note << " / " << maps.diagnosed_note;
  EXPECT_EQ(maps.base->frequency_hz.size(), 5u);
  EXPECT_EQ(maps.diagnosed->amplitude_v.size(), 3u);
  EXPECT_TRUE(maps.base->failures.empty());
  const std::vector<report::ThresholdShift> shifts = report::ThresholdShifts(*maps.base, *maps.diagnosed);
  ASSERT_EQ(shifts.size(), 5u);
  // The base's thresholds are the sweep's, the paper model's own (contact damping acts only in
  // contact, so grazing, where contact begins, does not move).
  const SaturationThreshold paper = SweepColumn(PaperModel(), shifts[2].frequency_hz);
  EXPECT_EQ(shifts[2].base_grazing_v, paper.grazing_amplitude_v);
  EXPECT_NEAR(shifts[2].GrazingShiftV(), 0.0, 1e-6);
}

TEST(SweepDiagnosisMapsTest, AnUnchangedModelIsSweptOnce) {
  Diagnosis d = HandMadeDiagnosis();
  d.model = d.base.model;
  const report::DiagnosisMaps maps = report::SweepDiagnosisMaps(d, MapOptions(3, 2));
  EXPECT_TRUE(maps.same_model);
  ASSERT_TRUE(maps.base && maps.diagnosed);
  EXPECT_EQ(maps.diagnosed->points.size(), maps.base->points.size());
}

TEST(SweepDiagnosisMapsTest, NoMapsWhenTurnedOffTheRangeIsAPointOrTheBudgetIsSpent) {
  EXPECT_THAT(report::SweepDiagnosisMaps(HandMadeDiagnosis(), MapOptions(0, 12)).note,
              HasSubstr("not computed (map_frequency_points or map_amplitude_points is 0)"));
  Diagnosis one_level = HandMadeDiagnosis();
  for (RecordMatch& r : one_level.before) r.amplitude_v = 0.3;
  const report::DiagnosisMaps flat = report::SweepDiagnosisMaps(one_level, MapOptions(5, 3));
  EXPECT_THAT(flat.note, HasSubstr("do not span a range"));
  EXPECT_FALSE(flat.base);
  // The diagnosis used its whole budget: the maps do not start.
  Diagnosis late = HandMadeDiagnosis();
  DiagnoseOptions options = MapOptions(5, 3);
  late.seconds = options.max_seconds + 1;
  const report::DiagnosisMaps none = report::SweepDiagnosisMaps(late, options);
  EXPECT_EQ(none.note, "");
  EXPECT_FALSE(none.base);
  EXPECT_FALSE(none.diagnosed);
  EXPECT_EQ(none.base_note, "not swept: the diagnosis's time limit (max_seconds 600 s) was spent before the map began");
}

}  // namespace
}  // namespace strokelab
