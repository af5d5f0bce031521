// `strokelab regress` end to end on temporary copies: a baseline perturbed beyond its tolerance is
// a regression (exit code 1) naming the field and the row, within it a pass; tolerances in the job
// file; a missing baseline says how to create it; --update writes NEW then UPDATED baselines; a
// changed job and rows gone or added are regressions; bad input is exit code 2 naming the file.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "cli/run_cli.h"
#include "read_json.h"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::strokelab::testing::CliResult;
using ::strokelab::testing::RunCli;
using ::testing::HasSubstr;
using ::testing::Not;

const fs::path kRegress = STROKELAB_REGRESS_DIR;

// A fresh directory per test.
fs::path TempDir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir = fs::path(::testing::TempDir()) / "strokelab_regress" / info->name();
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

using ::strokelab::testing::ReadJson;

void WriteText(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path) << text;
}

void WriteJson(const fs::path& path, const json& value) { WriteText(path, value.dump(2)); }

CliResult Regress(const std::string& args) { return RunCli("regress " + args); }

// A simulate job that runs in milliseconds.
json SmallSimulate() {
  return {{"kind", "simulate"}, {"model", "paper"}, {"frequency_hz", 8},       {"amplitude_v", 0.5},
          {"duration_s", 1},    {"sample_rate_hz", 8192}, {"method", "exact"}};
}

// The checked-in 8 Hz baseline, copied with its first-harmonic force scaled by (1 + relative).
fs::path PerturbedBaseline(const fs::path& dir, double relative) {
  json baseline = ReadJson(kRegress / "baselines" / "simulate_8hz_exact.json");
  json& force = baseline["tables"]["records"][0]["first_harmonic_force_n"];
  force = force.get<double>() * (1 + relative);
  WriteJson(dir / "baselines" / "simulate_8hz_exact.json", baseline);
  return dir / "baselines";
}

TEST(RegressCliTest, CheckedInBaselinesPass) {
  const CliResult r = Regress((kRegress / "jobs" / "simulate_8hz_exact.json").string() + " --baseline " +
                              (kRegress / "baselines").string());
  EXPECT_EQ(r.exit_code, 0) << r.stdout_text << r.stderr_text;
  EXPECT_THAT(r.stdout_text, HasSubstr("simulate_8hz_exact.json  PASS"));
  EXPECT_THAT(r.stdout_text, HasSubstr("1 passed"));
}

TEST(RegressCliTest, CatchesAValueBeyondItsTolerance) {
  const fs::path dir = TempDir();
  const fs::path job = kRegress / "jobs" / "simulate_8hz_exact.json";
  const CliResult r = Regress(job.string() + " --baseline " + PerturbedBaseline(dir, 1e-6).string());
  EXPECT_EQ(r.exit_code, 1) << r.stdout_text << r.stderr_text;
  EXPECT_THAT(r.stdout_text, HasSubstr("simulate_8hz_exact.json  FAIL"));
  EXPECT_THAT(r.stdout_text, HasSubstr("records[f=8 Hz, V=0.5 V].first_harmonic_force_n: "));
  EXPECT_THAT(r.stdout_text, HasSubstr("relative deviation 1e-06 beyond tolerance relative 1e-09, absolute 1e-12"));
  EXPECT_THAT(r.stdout_text, HasSubstr("if the change is intended: strokelab regress " + job.string() + " --baseline"));
  EXPECT_THAT(r.stdout_text, HasSubstr("1 failed"));
  EXPECT_TRUE(r.stderr_text.empty()) << r.stderr_text;
}

TEST(RegressCliTest, PassesWithinTheToleranceAndShowsTheWorstValue) {
  const fs::path dir = TempDir();
  const CliResult r = Regress((kRegress / "jobs" / "simulate_8hz_exact.json").string() + " --baseline " +
                              PerturbedBaseline(dir, 2e-10).string());
  EXPECT_EQ(r.exit_code, 0) << r.stdout_text << r.stderr_text;
  EXPECT_THAT(r.stdout_text, HasSubstr("PASS"));
  EXPECT_THAT(r.stdout_text, HasSubstr("2.0e-10 rel (20% of tol) at records[f=8 Hz, V=0.5 V].first_harmonic_force_n"));
}

TEST(RegressCliTest, ToleranceInTheJobFile) {
  const fs::path dir = TempDir();
  json job = ReadJson(kRegress / "jobs" / "simulate_8hz_exact.json");
  job["tolerances"] = {{"first_harmonic_force_n", {{"relative", 1e-5}}}};
  WriteJson(dir / "jobs" / "simulate_8hz_exact.json", job);
  const CliResult r =
      Regress((dir / "jobs" / "simulate_8hz_exact.json").string() + " --baseline " + PerturbedBaseline(dir, 1e-6).string());
  EXPECT_EQ(r.exit_code, 0) << r.stdout_text << r.stderr_text;
  EXPECT_THAT(r.stdout_text, HasSubstr("1.0e-06 rel (10% of tol)"));
}

TEST(RegressCliTest, MissingBaselineSaysHowToCreateIt) {
  const fs::path dir = TempDir();
  WriteJson(dir / "small.json", SmallSimulate());
  const CliResult r = Regress((dir / "small.json").string() + " --baseline " + (dir / "none").string());
  EXPECT_EQ(r.exit_code, 1) << r.stdout_text << r.stderr_text;
  EXPECT_THAT(r.stdout_text, HasSubstr("small.json  FAIL"));
  EXPECT_THAT(r.stdout_text, HasSubstr("no baseline " + (dir / "none" / "small.json").string()));
  EXPECT_THAT(r.stdout_text, HasSubstr("create it with: strokelab regress " + (dir / "small.json").string() +
                                       " --baseline " + (dir / "none").string() + " --update"));
  EXPECT_FALSE(fs::exists(dir / "none"));
}

TEST(RegressCliTest, UpdateWritesNewThenUpdatedBaselines) {
  const fs::path dir = TempDir();
  const std::string job = (dir / "small.json").string(), base = (dir / "base").string();
  WriteJson(job, SmallSimulate());
  CliResult r = Regress(job + " --baseline " + base + " --update");
  EXPECT_EQ(r.exit_code, 0) << r.stdout_text << r.stderr_text;
  EXPECT_THAT(r.stdout_text, HasSubstr("small.json  NEW"));
  EXPECT_THAT(r.stdout_text, HasSubstr("wrote " + base + "/small.json (1 row)"));
  const json baseline = ReadJson(dir / "base" / "small.json");
  EXPECT_EQ(baseline["job"], SmallSimulate());
  EXPECT_EQ(baseline["tables"]["records"].size(), 1u);
  EXPECT_TRUE(baseline["code_version"].is_string());

  r = Regress(job + " --baseline " + base);
  EXPECT_EQ(r.exit_code, 0) << r.stdout_text;
  EXPECT_THAT(r.stdout_text, HasSubstr("small.json  PASS"));

  // A changed job is a regression until its baseline is rewritten; a new name is not a change.
  json changed = SmallSimulate();
  changed["name"] = "renamed";
  WriteJson(job, changed);
  EXPECT_EQ(Regress(job + " --baseline " + base).exit_code, 0);
  changed["amplitude_v"] = 0.45;
  WriteJson(job, changed);
  r = Regress(job + " --baseline " + base);
  EXPECT_EQ(r.exit_code, 1) << r.stdout_text;
  EXPECT_THAT(r.stdout_text, HasSubstr("the job differs from the baseline's \"job\""));
  EXPECT_THAT(r.stdout_text, HasSubstr("records[f=8 Hz, V=0.5 V]: missing row"));
  EXPECT_THAT(r.stdout_text, HasSubstr("records[f=8 Hz, V=0.45 V]: extra row"));

  r = Regress(job + " --baseline " + base + " --update");
  EXPECT_EQ(r.exit_code, 0) << r.stdout_text;
  EXPECT_THAT(r.stdout_text, HasSubstr("small.json  UPDATED"));
  EXPECT_THAT(r.stdout_text, HasSubstr("changes from the old baseline beyond tolerance (3):"));
  EXPECT_EQ(Regress(job + " --baseline " + base).exit_code, 0);
}

TEST(RegressCliTest, RowsGoneOrAddedInASweep) {
  const fs::path dir = TempDir();
  const json sweep = {{"kind", "sweep"},
                      {"model", "paper"},
                      {"thresholds", false},
                      {"grid", {{"frequency_hz", {{"from", 10}, {"to", 14}, {"points", 5}}},
                                {"amplitude_v", {{"from", 0.5}, {"to", 0.5}, {"points", 1}}}}}};
  const std::string job = (dir / "sweep.json").string(), base = (dir / "base").string();
  WriteJson(job, sweep);
  ASSERT_EQ(Regress(job + " --baseline " + base + " --update").exit_code, 0);
  json baseline = ReadJson(dir / "base" / "sweep.json");
  json& points = baseline["tables"]["points"];
  ASSERT_GE(points.size(), 5u);
  const json removed = points[2];
  points.erase(2);
  points[0]["frequency_hz"] = 9.5;  // a row the results do not have
  WriteJson(dir / "base" / "sweep.json", baseline);
  const CliResult r = Regress(job + " --baseline " + base);
  EXPECT_EQ(r.exit_code, 1) << r.stdout_text;
  EXPECT_THAT(r.stdout_text, HasSubstr("points[f=9.5 Hz, V=0.5 V, " + points[0]["branch"].get<std::string>() +
                                       "]: missing row"));
  EXPECT_THAT(r.stdout_text, HasSubstr("points[f=" + std::to_string(removed["frequency_hz"].get<int>()) +
                                       " Hz, V=0.5 V, " + removed["branch"].get<std::string>() + "]: extra row"));
}

// One line on stderr naming the file (and the field), exit code 2, nothing run or printed.
void ExpectBadInput(const std::string& args, const std::string& expected) {
  const CliResult r = Regress(args);
  EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.stdout_text << r.stderr_text;
  EXPECT_THAT(r.stderr_text, HasSubstr(expected)) << args;
  EXPECT_EQ(std::count(r.stderr_text.begin(), r.stderr_text.end(), '\n'), 1) << r.stderr_text;
  EXPECT_TRUE(r.stdout_text.empty()) << r.stdout_text;
}

TEST(RegressCliTest, BadInputIsExitCodeTwo) {
  const fs::path dir = TempDir();
  const std::string good = (dir / "good.json").string(), base = " --baseline " + (dir / "base").string();
  WriteJson(good, SmallSimulate());
  WriteText(dir / "broken.json", "{\"kind\": \"simulate\",\n");
  json bad = SmallSimulate();
  bad["duration_s"] = -1;
  WriteJson(dir / "bad.json", bad);
  json unknown = SmallSimulate();
  unknown["colour"] = "red";
  WriteJson(dir / "unknown.json", unknown);
  json tolerance = SmallSimulate();
  tolerance["tolerances"] = {{"h_re_n_per_v", {{"relative", -1}}}};
  WriteJson(dir / "tolerance.json", tolerance);
  WriteJson(dir / "array.json", json::array());

  ExpectBadInput((dir / "broken.json").string() + base, "strokelab: error: " + (dir / "broken.json").string() +
                                                            ": not valid JSON: parse error at line 2");
  // Every file is checked before any runs: a bad second file stops the first too.
  ExpectBadInput(good + " " + (dir / "bad.json").string() + base, (dir / "bad.json").string() + ": /duration_s: ");
  ExpectBadInput((dir / "unknown.json").string() + base, (dir / "unknown.json").string() + ": /colour: ");
  ExpectBadInput((dir / "tolerance.json").string() + base,
                 (dir / "tolerance.json").string() + ": /tolerances/h_re_n_per_v/relative: must be a number >= 0");
  ExpectBadInput((dir / "array.json").string() + base, "array.json: a job file must hold one JSON object");
  ExpectBadInput((dir / "missing.json").string() + base, "missing.json: cannot read the file");
  ExpectBadInput(good, "--baseline: required");
  ExpectBadInput("--baseline " + (dir / "base").string(), "give one or more job files");
  ExpectBadInput(good + " --baseline " + good, "--baseline: '" + good + "' is not a directory");
  fs::create_directories(dir / "other");
  fs::copy_file(good, dir / "other" / "good.json");
  ExpectBadInput(good + " " + (dir / "other" / "good.json").string() + base, "has the same file name as " + good);
  // An unreadable baseline is bad input too (with --update it is replaced).
  WriteText(dir / "base" / "good.json", "not json");
  ExpectBadInput(good + base, (dir / "base" / "good.json").string() + ": not valid JSON");
  const CliResult r = Regress(good + base + " --update");
  EXPECT_EQ(r.exit_code, 0) << r.stdout_text << r.stderr_text;
  EXPECT_THAT(r.stdout_text, HasSubstr("good.json  UPDATED"));
  EXPECT_THAT(r.stdout_text, HasSubstr("the old baseline was not readable"));
}

}  // namespace
