// Job specs at the edge: ValidateJob on generated malformed documents (each with the exact JSON
// pointer and a fragment of the message), valid documents, the conversion to core types, and the
// engine a simulate job runs.
#include "strokelab/jobs/job_spec.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <string>
#include <tuple>
#include <vector>

#include "strokelab/model/model_json.h"
#include "strokelab/jobs/jobs.h"
#include "strokelab/jobs/json_schema.h"
#include "strokelab/report/sweep_tables.h"
#include "strokelab/signal/signal.h"
#include "test_util.h"

namespace strokelab::jobs {
namespace {

using nlohmann::json;
using ::testing::HasSubstr;

// Every parameter under its JSON name (ModelToJson), plus preset and contact_law: a model object
// that exercises every model key of the schema.
json FullModel() {
  json model = ModelToJson(PaperModel());
  model["preset"] = "paper";
  return model;
}

json BaseSweep() {
  return {{"kind", "sweep"},
          {"name", "paper actuator, geometric grid"},
          {"model", FullModel()},
          {"grid",
           {{"frequency_hz", {{"from", 5}, {"to", 50}, {"points", 46}, {"spacing", "geometric"}}},
            {"amplitude_v", {{"from", 0.1}, {"to", 0.6}, {"points", 6}}}}},
          {"thresholds", true}};
}

json BaseEq1Sweep() {
  return {{"kind", "sweep"},
          {"model", "paper"},
          {"grid", {{"frequency_hz", {{"points", 117}, {"spacing", "eq1"}}}, {"amplitude_v", {{"from", 0.1}, {"to", 0.6}, {"points", 6}}}}}};
}

json BaseSimulate() {
  return {{"kind", "simulate"},  {"name", "one record"},     {"model", "paper"},   {"frequency_hz", 8},
          {"amplitude_v", 0.4},  {"duration_s", 2},          {"sample_rate_hz", 51200}, {"method", "exact"}};
}

struct MalformedCase {
  std::string description;
  json document;
  std::string pointer;   // expected InputError::field()
  std::string fragment;  // expected in InputError::bare_message()
};

std::ostream& operator<<(std::ostream& out, const MalformedCase& c) {
  return out << c.description << ": " << c.document.dump();
}

json With(json document, const std::string& pointer, const json& value) {
  document[json::json_pointer(pointer)] = value;
  return document;
}

json Without(json document, const std::string& pointer) {
  const json::json_pointer p(pointer);
  document.at(p.parent_pointer()).erase(p.back());
  return document;
}

// Leaves (non-object values) of a document, as JSON pointers.
void Leaves(const json& value, const std::string& pointer, std::vector<std::string>* out) {
  if (!value.is_object()) {
    out->push_back(pointer);
    return;
  }
  for (const auto& [key, child] : value.items()) Leaves(child, pointer + "/" + key, out);
}

// What the schema says when the leaf at `pointer` holds a value of the wrong type.
std::string TypeMessage(const std::string& pointer) {
  const std::string field = pointer.substr(pointer.rfind('/') + 1);
  if (field == "kind") return "must be one of: sweep, simulate, fit, diagnose";
  if (field == "name") return "must be a string";
  if (field == "thresholds") return "must be a boolean";
  if (field == "points") return "must be an integer";
  if (field == "spacing") return "must be one of: linear, geometric, eq1";
  if (field == "method") return "must be one of: auto, exact, cvode, ode3";
  if (field == "preset") return "must be one of: paper, linear";
  if (field == "contact_law") return "must be one of: linear, hertzian";
  if (field == "model") return "must be a string or an object";
  if (field == "d" || field == "lower_stop_m" || field == "d_upper" || field == "upper_stop_m" ||
      field == "amplifier_limit_v")
    return "must be a number or null";
  return "must be a number";
}

bool NullAllowed(const std::string& pointer) { return TypeMessage(pointer) == "must be a number or null"; }

std::vector<MalformedCase> MalformedCases() {
  std::vector<MalformedCase> cases;
  const auto add = [&](std::string description, json document, std::string pointer, std::string fragment) {
    cases.push_back({std::move(description), std::move(document), std::move(pointer), std::move(fragment)});
  };
  const std::vector<std::pair<std::string, json>> bases = {
      {"sweep", BaseSweep()}, {"eq1", BaseEq1Sweep()}, {"simulate", BaseSimulate()}};

  // 1. Each required field missing: the pointer is the field's would-be path.
  for (const std::string p : {"/kind", "/model", "/grid", "/grid/frequency_hz", "/grid/amplitude_v",
                               "/grid/frequency_hz/from", "/grid/frequency_hz/to", "/grid/frequency_hz/points",
                               "/grid/amplitude_v/from", "/grid/amplitude_v/to", "/grid/amplitude_v/points"})
    add("sweep without " + p, Without(BaseSweep(), p), p, "is required");
  add("eq1 without points", Without(BaseEq1Sweep(), "/grid/frequency_hz/points"), "/grid/frequency_hz/points",
      "is required");
  for (const std::string p : {"/model", "/frequency_hz", "/amplitude_v"})
    add("simulate without " + p, Without(BaseSimulate(), p), p, "is required");
  // A linear axis needs both ends; spacing absent means linear.
  add("linear axis without to", Without(With(BaseSweep(), "/grid/frequency_hz/spacing", "linear"), "/grid/frequency_hz/to"),
      "/grid/frequency_hz/to", "is required");
  add("default-spacing axis without from",
      Without(Without(BaseSweep(), "/grid/frequency_hz/spacing"), "/grid/frequency_hz/from"), "/grid/frequency_hz/from",
      "is required");

  // 2. Each leaf with a value of the wrong type, and null where null is not allowed.
  for (const auto& [name, base] : bases) {
    std::vector<std::string> leaves;
    Leaves(base, "", &leaves);
    for (const std::string& leaf : leaves) {
      const json& original = base.at(json::json_pointer(leaf));
      const json wrong_scalar = original.is_string() ? json(1) : json("1");
      for (const json& wrong : {wrong_scalar, json::array({1}), json::object()}) {
        if (leaf == "/model" && wrong.is_object()) continue;  // {} is a valid model: the paper's
        add(name + ": " + leaf + " = " + wrong.dump(), With(base, leaf, wrong), leaf, TypeMessage(leaf));
      }
      if (!NullAllowed(leaf))
        add(name + ": " + leaf + " = null", With(base, leaf, nullptr), leaf, TypeMessage(leaf));
    }
  }
  add("the document is an array", json::array({BaseSweep()}), "", "must be an object");
  add("the document is a string", "sweep", "", "must be an object");
  for (const std::string p : {"/grid", "/grid/frequency_hz", "/grid/amplitude_v"}) {
    add(p + " = []", With(BaseSweep(), p, json::array()), p, "must be an object");
    add(p + " = null", With(BaseSweep(), p, nullptr), p, "must be an object");
  }
  add("model = null", With(BaseSweep(), "/model", nullptr), "/model", "must be a string or an object");
  add("points = 2.5", With(BaseSweep(), "/grid/amplitude_v/points", 2.5), "/grid/amplitude_v/points",
      "must be an integer");

  // 3. Numbers out of range.
  const std::vector<std::tuple<std::string, json, std::string>> ranges = {
      {"/grid/frequency_hz/from", 0.0009, "must be >= 0.001"},
      {"/grid/frequency_hz/from", -5, "must be >= 0.001"},
      {"/grid/frequency_hz/to", 10000.5, "must be <= 10000"},
      {"/grid/frequency_hz/points", 0, "must be >= 1"},
      {"/grid/frequency_hz/points", 2001, "must be <= 2000"},
      {"/grid/amplitude_v/from", 1e-7, "must be >= 1e-06"},
      {"/grid/amplitude_v/from", 0, "must be >= 1e-06"},
      {"/grid/amplitude_v/to", 1001, "must be <= 1000"},
      {"/grid/amplitude_v/points", -1, "must be >= 1"},
      {"/grid/amplitude_v/points", 100000, "must be <= 2000"},
      {"/name", std::string(201, 'x'), "must be at most 200 characters long"},
  };
  for (const auto& [pointer, value, fragment] : ranges)
    add("sweep: " + pointer + " = " + value.dump().substr(0, 20), With(BaseSweep(), pointer, value), pointer, fragment);
  const std::vector<std::tuple<std::string, json, std::string>> simulate_ranges = {
      {"/frequency_hz", 0, "must be >= 0.001"},
      {"/frequency_hz", 20000, "must be <= 10000"},
      {"/amplitude_v", -0.4, "must be >= 1e-06"},
      {"/amplitude_v", 5000, "must be <= 1000"},
      {"/duration_s", 0, "must be > 0"},
      {"/duration_s", 61, "must be <= 60"},
      {"/sample_rate_hz", 0, "must be > 0"},
      {"/sample_rate_hz", 1000001, "must be <= 1000000"},
  };
  for (const auto& [pointer, value, fragment] : simulate_ranges)
    add("simulate: " + pointer + " = " + value.dump(), With(BaseSimulate(), pointer, value), pointer, fragment);
  add("eq1: from below range", With(BaseEq1Sweep(), "/grid/frequency_hz/from", 1e-4), "/grid/frequency_hz/from",
      "must be >= 0.001");

  // 4. An unknown field at each level of each kind.
  for (const auto& [name, base] : bases) {
    std::vector<std::string> objects = {""};
    for (const std::string p : {"/grid", "/grid/frequency_hz", "/grid/amplitude_v", "/model"})
      if (base.contains(json::json_pointer(p)) && base.at(json::json_pointer(p)).is_object()) objects.push_back(p);
    for (const std::string& p : objects)
      add(name + ": unknown field under '" + p + "'", With(base, p + "/bogus", 1), p + "/bogus", "unknown field (allowed: ");
  }
  add("typo amplitude for amplitude_v", Without(With(BaseSweep(), "/grid/amplitude", json::object()), "/grid/amplitude_v"),
      "/grid/amplitude", "unknown field (allowed: amplitude_v, frequency_hz)");
  add("spacing on the amplitude axis", With(BaseSweep(), "/grid/amplitude_v/spacing", "geometric"),
      "/grid/amplitude_v/spacing", "unknown field (allowed: from, points, to)");
  add("threads is not a job field", With(BaseSweep(), "/threads", 4), "/threads", "unknown field (allowed: ");
  add("phase_rad is not a simulate field", With(BaseSimulate(), "/phase_rad", 0.5), "/phase_rad",
      "unknown field (allowed: ");
  add("grid on a simulate job", With(BaseSimulate(), "/grid", BaseSweep()["grid"]), "/grid", "unknown field (allowed: ");
  add("method on a sweep job", With(BaseSweep(), "/method", "exact"), "/method", "unknown field (allowed: ");

  // 5. Bad enum values.
  add("kind fitting (unknown)", With(BaseSweep(), "/kind", "fitting"), "/kind",
      "must be one of: sweep, simulate, fit, diagnose");
  add("kind Sweep (case)", With(BaseSweep(), "/kind", "Sweep"), "/kind", "must be one of: sweep, simulate");
  add("spacing log", With(BaseSweep(), "/grid/frequency_hz/spacing", "log"), "/grid/frequency_hz/spacing",
      "must be one of: linear, geometric, eq1");
  add("method rk4", With(BaseSimulate(), "/method", "rk4"), "/method", "must be one of: auto, exact, cvode, ode3");
  add("preset name papr", With(BaseSweep(), "/model", "papr"), "/model", "must be one of: paper, linear");
  add("preset key papr", With(BaseSweep(), "/model/preset", "papr"), "/model/preset", "must be one of: paper, linear");
  add("contact law hertz", With(BaseSweep(), "/model/contact_law", "hertz"), "/model/contact_law",
      "must be one of: linear, hertzian");

  // 6. Model keys that do not exist.
  for (const std::string key : {"K3", "mass", "k4", "lower_stop", "stop_m", "Preset"})
    add("model key " + key, With(With(BaseSimulate(), "/model", json::object()), "/model/" + key, 1.0), "/model/" + key,
        "unknown field (allowed: amplifier_limit_v, b1, b2, back_emf_damping_n_s_per_m, c2, c_emf, c_p, c_s, coil_time_constant_s, contact_damping_n_s_per_m, contact_law");

  // 7. Semantic checks after the schema.
  add("frequency to < from", With(BaseSweep(), "/grid/frequency_hz/to", 4), "/grid/frequency_hz/to", "must be >= from (5)");
  add("amplitude to < from", With(BaseSweep(), "/grid/amplitude_v/to", 0.05), "/grid/amplitude_v/to",
      "must be >= from (0.1)");
  add("amplitude to == from with 6 points", With(BaseSweep(), "/grid/amplitude_v/to", 0.1), "/grid/amplitude_v/to",
      "must be > from when points > 1");
  add("eq1 with to", With(BaseEq1Sweep(), "/grid/frequency_hz/to", 50), "/grid/frequency_hz/to",
      "must be left out with spacing eq1");
  add("eq1 past 10 kHz", With(BaseEq1Sweep(), "/grid/frequency_hz/points", 2000), "/grid/frequency_hz/points",
      "must be <= 10000 Hz (at most 384 points from 5 Hz)");
  add("eq1 past 10 kHz from 9 kHz", With(With(BaseEq1Sweep(), "/grid/frequency_hz/from", 9000), "/grid/frequency_hz/points", 7),
      "/grid/frequency_hz/points", "at most 6 points from 9000 Hz");
  add("negative mass (short key)", With(BaseSweep(), "/model", {{"m_p", -1}}), "/model/m_p", "must be > 0");
  add("negative mass (JSON name)", With(BaseSweep(), "/model/mass_kg", -0.1), "/model/mass_kg", "must be > 0");
  add("stop above rest", With(BaseSimulate(), "/model", {{"d", 1e-3}}), "/model/d", "at or below the rest position");
  add("upper stop below lower", With(BaseSimulate(), "/model", {{"d", -1e-3}, {"d_upper", -2e-3}}), "/model/d_upper",
      "at or above the rest position");
  add("zero stop stiffness", With(BaseSimulate(), "/model", {{"k_s", 0}}), "/model/k_s", "must be > 0");
  add("null mass", With(BaseSimulate(), "/model", {{"m_p", nullptr}}), "/model/m_p", "must be a number");
  add("mass given twice", With(BaseSimulate(), "/model", {{"m_p", 0.03}, {"mass_kg", 0.03}}), "/model/mass_kg",
      "gives the same parameter as m_p");
  add("exact with cubic stiffness", With(BaseSimulate(), "/model", {{"k3", 4e7}}), "/method",
      "the exact engine needs a piecewise-linear model; this one has k3 (cubic stiffness) (use auto, the default, "
      "or cvode)");
  add("exact with Hertzian contact", With(BaseSimulate(), "/model", {{"contact_law", "hertzian"}, {"k_s", 4e9}}),
      "/method", "this one has Hertzian contact (use auto");
  add("record under 2 samples", With(With(BaseSimulate(), "/duration_s", 1e-5), "/sample_rate_hz", 100), "/duration_s",
      "at least 2 samples");

  // 8. Jobs over the size caps: the limit is named.
  add("grid 2000 x 2000", With(With(BaseSweep(), "/grid/frequency_hz/points", 2000), "/grid/amplitude_v/points", 2000),
      "/grid", "2000 x 2000 = 4000000 exceeds the limit of 200000 grid points per job");
  add("grid 1000 x 201", With(With(BaseSweep(), "/grid/frequency_hz/points", 1000), "/grid/amplitude_v/points", 201),
      "/grid", "exceeds the limit of 200000 grid points");
  add("record 60 s at 1 MHz", With(With(BaseSimulate(), "/duration_s", 60), "/sample_rate_hz", 1e6), "/duration_s",
      "= 60000000 samples exceeds the limit of 10000000 samples per record");
  return cases;
}

class MalformedJobTest : public ::testing::TestWithParam<MalformedCase> {};

TEST_P(MalformedJobTest, NamesTheFieldAndTheRule) {
  const MalformedCase& c = GetParam();
  try {
    ValidateJob(c.document);
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), c.pointer);
    EXPECT_THAT(e.bare_message(), HasSubstr(c.fragment));
    // The root's pointer is "" (the whole document): then what() is the bare message.
    EXPECT_EQ(std::string(e.what()), c.pointer.empty() ? e.bare_message() : c.pointer + ": " + e.bare_message());
  }
}

std::string CaseName(const ::testing::TestParamInfo<MalformedCase>& info) {
  std::string name = std::to_string(info.index) + "_";
  for (char ch : info.param.description) name += std::isalnum(static_cast<unsigned char>(ch)) ? ch : '_';
  return name.substr(0, 80);
}

INSTANTIATE_TEST_SUITE_P(Generated, MalformedJobTest, ::testing::ValuesIn(MalformedCases()), CaseName);

TEST(MalformedJobTableTest, CoversEnoughCases) {
  const std::vector<MalformedCase> cases = MalformedCases();
  EXPECT_GE(cases.size(), 60u);
  std::printf("%zu malformed job documents\n", cases.size());
}

TEST(MalformedJobTableTest, SchemaErrorsComeFromTheSchemaAlone) {
  // Cases the schema catches report the same pointer through ValidateAgainstSchema as through
  // ValidateJob; the rest are valid for the schema and caught by the code after it.
  int schema_cases = 0, code_cases = 0;
  for (const MalformedCase& c : MalformedCases()) {
    SCOPED_TRACE(c.description);
    const auto violation = ValidateAgainstSchema(BuiltInSchema("job"), c.document);
    if (violation) {
      ++schema_cases;
      EXPECT_EQ(violation->pointer, c.pointer);
      EXPECT_THAT(violation->message, HasSubstr(c.fragment));
    } else {
      ++code_cases;
    }
  }
  EXPECT_GE(code_cases, 15);
  EXPECT_GE(schema_cases, 100);
}

TEST(JobLimitTest, OversizeJobsThrowJobLimitError) {
  EXPECT_THROW(ValidateJob(With(With(BaseSweep(), "/grid/frequency_hz/points", 2000), "/grid/amplitude_v/points", 101)),
               JobLimitError);
  EXPECT_THROW(ValidateJob(With(With(BaseSimulate(), "/duration_s", 20), "/sample_rate_hz", 1e6)), JobLimitError);
  EXPECT_NO_THROW(CheckGridSize(2000, 100));
  EXPECT_NO_THROW(CheckGridSize(447, 447));
  EXPECT_THROW(CheckGridSize(200001, 1), JobLimitError);
  try {
    CheckGridSize(1000, 201);
    FAIL();
  } catch (const JobLimitError& e) {
    EXPECT_EQ(e.field(), "/grid");
    EXPECT_EQ(e.bare_message(), "frequency points x amplitude points = 1000 x 201 = 201000 exceeds the limit of 200000 "
                                "grid points per job");
  }
  // Exactly at the caps: accepted.
  EXPECT_NO_THROW(ValidateJob(With(With(BaseSweep(), "/grid/frequency_hz/points", 2000), "/grid/amplitude_v/points", 100)));
  EXPECT_NO_THROW(ValidateJob(With(With(BaseSimulate(), "/duration_s", 10), "/sample_rate_hz", 1e6)));
}

TEST(ValidJobTest, ValidDocumentsPass) {
  const std::vector<json> valid = {
      BaseSweep(),
      BaseEq1Sweep(),
      BaseSimulate(),
      // The issue's example.
      json::parse(R"({"kind": "sweep", "model": "paper", "grid": {"frequency_hz": {"from": 5, "to": 50, "points": 117},
                      "amplitude_v": {"from": 0.1, "to": 0.6, "points": 6}}})"),
      // Short keys, nulls for absent stops and limit, a preset under the object, Hertzian contact with cvode.
      json::parse(R"({"kind": "simulate", "model": {"preset": "linear", "k3": 4e7, "d": null, "d_upper": null,
                      "amplifier_limit_v": null}, "frequency_hz": 13, "amplitude_v": 0.5, "method": "cvode"})"),
      json::parse(R"({"kind": "simulate", "model": {"upper_stop_m": 2e-3, "contact_law": "hertzian",
                      "contact_stiffness": 4e9}, "frequency_hz": 8, "amplitude_v": 0.5, "method": "ode3",
                      "duration_s": 60, "sample_rate_hz": 100000})"),
      // Minimal simulate: duration, rate and method take their defaults (10 s, 51.2 kHz, auto).
      json::parse(R"({"kind": "simulate", "model": "linear", "frequency_hz": 0.001, "amplitude_v": 1000})"),
      // The default method, auto, takes a model the exact engine cannot (it runs cvode), and auto by name.
      Without(With(BaseSimulate(), "/model", {{"contact_law", "hertzian"}, {"k_s", 4e9}}), "/method"),
      With(With(BaseSimulate(), "/model", {{"k3", 4e7}}), "/method", "auto"),
      // One point per axis, to == from; whole numbers written as floats; thresholds off; a name at the cap.
      {{"kind", "sweep"},
       {"model", "linear"},
       {"name", std::string(200, 'n')},
       {"thresholds", false},
       {"grid", {{"frequency_hz", {{"from", 10.0}, {"to", 10.0}, {"points", 1.0}}}, {"amplitude_v", {{"from", 1e-6}, {"to", 1e-6}, {"points", 1}}}}}},
      // eq1 from another start, and up to the 10 kHz edge: 5 Hz x 1.02^383 = 9837 Hz.
      With(BaseEq1Sweep(), "/grid/frequency_hz/points", 384),
      With(With(BaseEq1Sweep(), "/grid/frequency_hz/from", 20), "/grid/frequency_hz/points", 10),
  };
  for (const json& job : valid) {
    SCOPED_TRACE(job.dump());
    EXPECT_NO_THROW(ValidateJob(job));
    EXPECT_EQ(ValidateAgainstSchema(BuiltInSchema("job"), job), std::nullopt);
  }
}

TEST(SweepSpecFromJobTest, ConvertsGridModelAndThresholds) {
  const SweepSpec spec = SweepSpecFromJob(BaseSweep());
  EXPECT_EQ(spec.frequency_hz.from, 5.0);
  EXPECT_EQ(spec.frequency_hz.to, 50.0);
  EXPECT_EQ(spec.frequency_hz.points, 46);
  EXPECT_TRUE(spec.frequency_hz.geometric);
  EXPECT_EQ(spec.amplitude_v.from, 0.1);
  EXPECT_EQ(spec.amplitude_v.to, 0.6);
  EXPECT_EQ(spec.amplitude_v.points, 6);
  EXPECT_FALSE(spec.amplitude_v.geometric);
  EXPECT_TRUE(spec.thresholds);
  EXPECT_EQ(spec.threads, 1);
  EXPECT_EQ(ModelToJson(spec.model), ModelToJson(PaperModel()));

  // Spacing absent: linear; thresholds false; a model object over the linear preset.
  json job = With(Without(BaseSweep(), "/grid/frequency_hz/spacing"), "/thresholds", false);
  job["model"] = {{"preset", "linear"}, {"k3", 4e7}, {"m_p", 0.05}};
  const SweepSpec linear = SweepSpecFromJob(job);
  EXPECT_FALSE(linear.frequency_hz.geometric);
  EXPECT_FALSE(linear.thresholds);
  EXPECT_EQ(linear.model.cubic_stiffness_n_per_m3, 4e7);
  EXPECT_EQ(linear.model.mass_kg, 0.05);
  EXPECT_FALSE(linear.model.HasLowerStop());
}

// A linear axis between decimal end points has the decimals in between as its values, not their
// rounded neighbours: 0.1 .. 0.6 V in 26 points is 0.1, 0.12, ..., 0.3 (not 0.30000000000000004, as
// 0.1 + 0.2 is), so that they print and are queried as the axis defines them.
TEST(SweepSpecFromJobTest, LinearAxisValuesAreTheDecimalsTheAxisDefines) {
  json job = BaseSweep();
  job["grid"]["amplitude_v"] = {{"from", 0.1}, {"to", 0.6}, {"points", 26}};
  const std::vector<double> values = SweepSpecFromJob(job).amplitude_v.Values();
  ASSERT_EQ(values.size(), 26u);
  for (int i = 0; i < 26; ++i) {
    char decimal[16];
    std::snprintf(decimal, sizeof decimal, "%.2f", 0.1 + 0.02 * i);
    EXPECT_EQ(values[i], std::stod(decimal)) << i;
    EXPECT_LE(json(values[i]).dump().size(), 4u) << json(values[i]).dump();
  }
  // Values that are no short decimal keep the nearest double: 0.5 .. 1.5 in 4 points.
  job["grid"]["amplitude_v"] = {{"from", 0.5}, {"to", 1.5}, {"points", 4}};
  EXPECT_EQ(SweepSpecFromJob(job).amplitude_v.Values()[1], 0.5 + 1.0 / 3.0);
}

// A job as it runs: presets and defaults spelled out (the service shows it as "resolved").
TEST(ResolvedJobTest, SpellsOutModelGridMethodAndOptions) {
  const json sweep = ResolvedJob(BaseEq1Sweep());
  EXPECT_EQ(sweep["model"], ModelToJson(PaperModel()));
  EXPECT_EQ(sweep["grid"]["frequency_hz"]["spacing"], "geometric");
  EXPECT_EQ(sweep["grid"]["frequency_hz"]["values"].size(), 117u);
  EXPECT_EQ(sweep["grid"]["amplitude_v"]["values"].dump(), "[0.1,0.2,0.3,0.4,0.5,0.6]");
  EXPECT_EQ(sweep["thresholds"], true);
  EXPECT_EQ(sweep["kind"], "sweep");

  const json simulate = ResolvedJob(Without(Without(BaseSimulate(), "/method"), "/duration_s"));
  EXPECT_EQ(simulate["duration_s"], 10.0);
  EXPECT_EQ(simulate["method"], "exact (auto: the model is piecewise linear)");
  EXPECT_EQ(simulate["model"]["mass_kg"], 0.032);

  const json fit = ResolvedJob({{"kind", "fit"}, {"campaign", {{"id", "0123456789abcdef"}}}});
  EXPECT_EQ(fit["model"], "paper");
  EXPECT_EQ(fit["options"].size(), FitOptionFields().size());
  const json diagnose = ResolvedJob({{"kind", "diagnose"}, {"campaign", {{"id", "0123456789abcdef"}}},
                                     {"options", {{"max_seconds", 30}}}});
  EXPECT_EQ(diagnose["options"]["max_seconds"], 30.0);
  EXPECT_EQ(diagnose["options"].size(), FitOptionFields().size() + DiagnoseOptionFields().size());
  EXPECT_THROW(ResolvedJob(With(BaseSimulate(), "/method", "rk4")), InputError);
}

TEST(SweepSpecFromJobTest, Eq1IsThePapersGrid) {
  // paper Eq. 1: w(n) = 10 pi 1.02^(n-1) rad/s; "from" defaults to 5 Hz.
  const SweepSpec spec = SweepSpecFromJob(BaseEq1Sweep());
  EXPECT_EQ(spec.frequency_hz.from, 5.0);
  EXPECT_EQ(spec.frequency_hz.points, 117);
  EXPECT_TRUE(spec.frequency_hz.geometric);
  EXPECT_REL_NEAR(spec.frequency_hz.to, 5.0 * std::pow(1.02, 116), 1e-15);
  const std::vector<double> grid = spec.frequency_hz.Values();
  const std::vector<double> paper = PaperFrequencyGridHz(117);
  ASSERT_EQ(grid.size(), paper.size());
  constexpr double kGridTolerance = 1e-13;  // relative: pow of a ratio vs repeated products
  for (size_t i = 0; i < grid.size(); ++i) EXPECT_REL_NEAR(grid[i], paper[i], kGridTolerance) << "n = " << i + 1;

  const SweepSpec shifted = SweepSpecFromJob(With(With(BaseEq1Sweep(), "/grid/frequency_hz/from", 20), "/grid/frequency_hz/points", 10));
  EXPECT_EQ(shifted.frequency_hz.from, 20.0);
  EXPECT_REL_NEAR(shifted.frequency_hz.Values()[9], 20.0 * std::pow(1.02, 9), 1e-14);
}

TEST(SweepSpecFromJobTest, RejectsOtherKindsAndInvalidJobs) {
  try {
    SweepSpecFromJob(BaseSimulate());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "/kind");
    EXPECT_EQ(e.bare_message(), "must be sweep");
  }
  try {
    SweepSpecFromJob(With(BaseSweep(), "/grid/amplitude_v/to", 0.01));
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "/grid/amplitude_v/to: must be >= from (0.1)");
  }
  EXPECT_THROW(SweepSpecFromJob(json::parse("{}")), InputError);
}

TEST(SweepSpecFromJobTest, NullStopsAndLimitMeanAbsent) {
  json job = BaseSweep();
  job["model"] = {{"d", nullptr}, {"upper_stop_m", nullptr}, {"amplifier_limit_v", nullptr}};
  const SweepSpec spec = SweepSpecFromJob(job);
  EXPECT_FALSE(spec.model.HasLowerStop());
  EXPECT_FALSE(spec.model.HasUpperStop());
  EXPECT_FALSE(spec.model.HasAmplifierLimit());
  job["model"] = {{"amplifier_limit_v", 0.3}, {"d_upper", 2e-3}};
  const SweepSpec limited = SweepSpecFromJob(job);
  EXPECT_EQ(limited.model.amplifier_limit_v, 0.3);
  EXPECT_EQ(limited.model.upper_stop_m, 2e-3);
}

// A sweep's tasks return their rows as flat records (task.h) that stand for the objects RowToJson
// writes, value for value, in the order SweepRow and SweepColumn give them.
TEST(SweepTaskTest, RecordsStandForTheRowsRowToJsonWrites) {
  const json job = {{"kind", "sweep"}, {"model", "paper"},
                    {"grid", {{"frequency_hz", {{"from", 10}, {"to", 30}, {"points", 41}}},
                              {"amplitude_v", {{"from", 0.5}, {"to", 0.5}, {"points", 1}}}}}};
  const std::vector<TaskSpec> tasks = PlanTasks(job);
  ASSERT_GE(tasks.size(), 2u);  // the row, then the thresholds of its 41 columns in chunks
  const ActuatorModel model = ModelFromJson("paper");
  const std::vector<double> frequencies = tasks[0].spec.at("frequencies_hz").get<std::vector<double>>();
  const SweepRowResult row = SweepRow(model, 0.5, frequencies);
  std::vector<json> expected;
  for (const SweepPoint& p : row.points) expected.push_back(report::RowToJson(p));
  for (const JumpInterval& j : row.jumps) expected.push_back(report::RowToJson(j));
  ASSERT_FALSE(row.jumps.empty()) << "the row should cross the jump interval";
  const TaskResult result = RunTask(tasks[0].spec);
  EXPECT_TRUE(result.rows.empty());
  ASSERT_EQ(result.records.size(), 2u);
  EXPECT_EQ(result.records[0].table, "points");
  EXPECT_EQ(result.records[1].table, "jumps");
  const std::vector<ResultRow> all = result.AllRows();
  ASSERT_EQ(all.size(), expected.size());
  EXPECT_EQ(result.RowCount(), expected.size());
  for (size_t i = 0; i < all.size(); ++i) EXPECT_EQ(all[i].values.dump(), expected[i].dump()) << i;

  const std::vector<double> chunk = tasks[1].spec.at("frequencies_hz").get<std::vector<double>>();
  const TaskResult thresholds = RunTask(tasks[1].spec);
  ASSERT_EQ(thresholds.records.size(), 1u);
  ASSERT_EQ(thresholds.records[0].size(), chunk.size());
  const size_t last = chunk.size() - 1;
  EXPECT_EQ(thresholds.records[0].RowAt(last).dump(), report::RowToJson(SweepColumn(model, chunk[last])).dump());
}

// A simulate job without a method runs the engine its model allows, and its record says which and
// why; a named method is written as named.
TEST(SimulateJobTest, TheDefaultMethodFollowsTheModel) {
  const auto method_of = [](const json& job) {
    const std::vector<TaskSpec> tasks = PlanTasks(job);
    EXPECT_EQ(tasks.size(), 1u);
    const std::vector<ResultRow> rows = RunTask(tasks.at(0).spec).AllRows();
    EXPECT_EQ(rows.size(), 1u);
    return rows.at(0).values.at("method").get<std::string>();
  };
  const json simulate = With(With(BaseSimulate(), "/duration_s", 1), "/sample_rate_hz", 8192);
  const json cubic = With(simulate, "/model", {{"k3", 4e7}});
  EXPECT_EQ(method_of(Without(cubic, "/method")),
            "cvode (auto: the model has k3 (cubic stiffness), which the exact engine cannot take)");
  EXPECT_EQ(method_of(Without(simulate, "/method")), "exact (auto: the model is piecewise linear)");
  EXPECT_EQ(method_of(With(cubic, "/method", "ode3")), "ode3");
  EXPECT_EQ(method_of(simulate), "exact");
}

// Each job option lands in its field (FitOptionFields, DiagnoseOptionFields); absent ones keep the
// defaults.
TEST(FitOptionsFromJobTest, ReadsEachOptionIntoItsField) {
  const json fit = {{"kind", "fit"},
                    {"campaign", {{"path", "campaign-a"}}},
                    {"model", "linear"},
                    {"options",
                     {{"harmonics", 7},
                      {"mass_kg", 0.05},
                      {"fit_contact_damping", true},
                      {"mains_hz", 60},
                      {"max_distortion", 0.2},
                      {"max_iterations", 9},
                      {"refine", false},
                      {"max_refinement_seconds", 30}}}};
  const FitOptions options = FitOptionsFromJob(fit);
  EXPECT_EQ(options.model, FitModelKind::kLinear);
  EXPECT_EQ(options.harmonic_orders, 7);
  EXPECT_EQ(options.mass_kg, 0.05);
  EXPECT_TRUE(options.fit_contact_damping);
  EXPECT_EQ(options.mains_frequency_hz, 60.0);
  EXPECT_EQ(options.max_clear_distortion, 0.2);
  EXPECT_EQ(options.max_iterations, 9);
  EXPECT_FALSE(options.refine);
  EXPECT_EQ(options.max_refinement_seconds, 30.0);

  const json diagnose = {{"kind", "diagnose"},
                         {"campaign", {{"id", "0123456789abcdef"}}},
                         {"options",
                          {{"harmonics", 6},
                           {"heldout_every", 3},
                           {"min_heldout_gain", 5},
                           {"pairs", false},
                           {"max_passes", 4},
                           {"max_seconds", 60},
                           {"map_frequency_points", 0},
                           {"map_amplitude_points", 5}}}};
  const DiagnoseOptions d = DiagnoseOptionsFromJob(diagnose);
  EXPECT_EQ(d.fit.harmonic_orders, 6);
  EXPECT_EQ(d.fit.mass_kg, FitOptions{}.mass_kg);
  EXPECT_EQ(d.heldout_every, 3);
  EXPECT_EQ(d.min_heldout_gain, 5.0);
  EXPECT_FALSE(d.pairs);
  EXPECT_EQ(d.max_passes, 4);
  EXPECT_EQ(d.max_seconds, 60.0);
  EXPECT_EQ(d.map_frequency_points, 0);
  EXPECT_EQ(d.map_amplitude_points, 5);
  EXPECT_EQ(DiagnoseOptionsFromJob({{"kind", "diagnose"}, {"campaign", {{"id", "0123456789abcdef"}}}}).max_passes,
            DiagnoseOptions{}.max_passes);
}

}  // namespace
}  // namespace strokelab::jobs
