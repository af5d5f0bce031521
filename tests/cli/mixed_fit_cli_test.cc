// `strokelab fit` on a campaign of stepped-sine and broadband records, as a rig writes one (one
// manifest, the broadband records at their own sample rate): one joint fit, reported in text and JSON.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "run_cli.h"

namespace strokelab {
namespace {

using ::strokelab::testing::CliResult;
using ::strokelab::testing::RunCli;
using ::testing::HasSubstr;
namespace fs = std::filesystem;

nlohmann::json ReadJson(const fs::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// Synthesises the two halves with `strokelab synth` and joins them in one campaign directory.
std::string MixedCampaign() {
  const fs::path dir = ::testing::TempDir() + "/mixed_fit_cli_" + std::to_string(::getpid());
  fs::remove_all(dir);
  const CliResult stepped = RunCli("synth --out " + (dir / "stepped").string() +
                                   " --frequencies-hz 5,7,9,11 --amplitudes-v 0.1,0.3,0.5 --settle-s 3 "
                                   "--noise-rms 5e-4 --seed 41");
  EXPECT_EQ(stepped.exit_code, 0) << stepped.stderr_text;
  const CliResult broadband = RunCli("synth --out " + (dir / "broadband").string() +
                                     " --excitation multisine --levels-v-rms 0.1,0.6 --sample-rate-hz 8192 "
                                     "--settle-s 2 --noise-rms 2e-4 --seed 42");
  EXPECT_EQ(broadband.exit_code, 0) << broadband.stderr_text;
  nlohmann::json manifest = ReadJson(dir / "stepped" / "manifest.json");
  const nlohmann::json other = ReadJson(dir / "broadband" / "manifest.json");
  fs::create_directories(dir / "mixed");
  for (const nlohmann::json& r : manifest["records"])
    fs::copy_file(dir / "stepped" / r["file"].get<std::string>(), dir / "mixed" / r["file"].get<std::string>());
  for (nlohmann::json r : other["records"]) {
    const std::string file = "bb_" + r["file"].get<std::string>();
    fs::copy_file(dir / "broadband" / r["file"].get<std::string>(), dir / "mixed" / file);
    r["file"] = file;
    r["sample_rate_hz"] = other["sample_rate_hz"];
    manifest["records"].push_back(r);
  }
  std::ofstream(dir / "mixed" / "manifest.json") << manifest.dump(1);
  return (dir / "mixed").string();
}

TEST(MixedFitCli, FitsBothKindsJointly) {
  const std::string campaign = MixedCampaign();
  const CliResult json = RunCli("fit --data " + campaign + " --json");
  ASSERT_EQ(json.exit_code, 0) << json.stderr_text;
  const nlohmann::json r = nlohmann::json::parse(json.stdout_text);
  EXPECT_EQ(r["kind"], "mixed");
  EXPECT_TRUE(r["converged"].get<bool>()) << r["report"];
  EXPECT_FALSE(r["rejected"].get<bool>()) << r["report"];
  EXPECT_EQ(r["records"].size(), 2u);
  EXPECT_GE(r["stepped_records"].size(), 10u);  // of 12: the refinement's
  for (const char* name : {"k_p", "c_p", "g", "d", "k_s"}) {
    EXPECT_TRUE(r["parameters"][name]["identifiable"].get<bool>()) << name;
    EXPECT_TRUE(r["stepped_start"].contains(name)) << name;
  }
  // The paper's model (synth's default): k_p within 4 of its standard errors of 124 N/m.
  EXPECT_NEAR(r["parameters"]["k_p"]["value"].get<double>(), 124.0,
              4.0 * r["parameters"]["k_p"]["standard_error"].get<double>());

  const CliResult text = RunCli("fit --data " + campaign);
  ASSERT_EQ(text.exit_code, 0) << text.stderr_text;
  EXPECT_THAT(text.stdout_text, HasSubstr("and 2 broadband records (their time series) fitted jointly"));
  EXPECT_THAT(text.stdout_text, HasSubstr("start: the stepped-sine records alone (converged"));
  EXPECT_THAT(text.stdout_text, HasSubstr("bb_rec_002.csv"));

  // Without the refinement ("stop at the staged estimates", which only the stepped fit has): the
  // stepped sines' staged fit, saying that the broadband records were left out; a campaign of
  // broadband records only is refused, naming the flag.
  const CliResult staged = RunCli("fit --data " + campaign + " --no-refine --json");
  ASSERT_EQ(staged.exit_code, 0) << staged.stderr_text;
  const nlohmann::json s = nlohmann::json::parse(staged.stdout_text);
  EXPECT_FALSE(s.contains("kind"));  // the stepped-sine fit's document
  EXPECT_FALSE(s["stages"]["refinement"]["ran"].get<bool>());
  EXPECT_THAT(s["warnings"].dump(), HasSubstr("record bb_rec_001.csv is broadband: not used"));
  const CliResult refused = RunCli("fit --data " + (fs::path(campaign).parent_path() / "broadband").string() + " --no-refine");
  EXPECT_EQ(refused.exit_code, 2);
  EXPECT_THAT(refused.stderr_text, HasSubstr("--no-refine: a campaign of broadband records only has no staged estimates"));
  fs::remove_all(fs::path(campaign).parent_path());
}

}  // namespace
}  // namespace strokelab
