// Results carry their version (regress/README.md, "Results version"): every checked-in baseline is
// the result its version recorded in the ledger, so a baseline that changes while the version does
// not fails here; and `regress --update` refuses to write one.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "cli/run_cli.h"
#include "regression.h"
#include "strokelab/jobs/version.h"
#include "read_json.h"

namespace {

namespace fs = std::filesystem;
namespace regression = strokelab::cli::regression;
using nlohmann::json;
using ::strokelab::testing::CliResult;
using ::strokelab::testing::RunCli;
using ::testing::HasSubstr;

const fs::path kBaselines = fs::path(STROKELAB_REGRESS_DIR) / "baselines";

using ::strokelab::testing::ReadJson;

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(ResultsVersion, EveryCheckedInBaselineIsTheResultItsVersionRecorded) {
  const auto ledger = regression::ReadLedger((kBaselines / regression::kLedgerFile).string());
  int baselines = 0;
  for (const auto& item : fs::directory_iterator(kBaselines)) {
    if (item.path().extension() != ".json") continue;
    ++baselines;
    const json baseline = ReadJson(item.path());
    const regression::LedgerEntry now{baseline["code_version"], regression::JobKey(baseline["job"]),
                                      regression::TablesKey(baseline["tables"]), item.path().filename().string()};
    const auto recorded = regression::FindEntry(ledger, now.code_version, now.job_key);
    ASSERT_TRUE(recorded) << now.file << ": its version and job are not in the ledger; a baseline written by "
                          << "`strokelab regress --update` is. The line would be: " << regression::FormatLedgerLine(now);
    EXPECT_EQ(recorded->tables_key, now.tables_key)
        << now.file << " changed, but its version " << now.code_version << " did not: cached tasks of the code that "
        << "wrote the old baseline would be served as this code's results. Bump VERSION in CMakeLists.txt and "
        << "rewrite the baselines with --update.";
  }
  EXPECT_GE(baselines, 4);
}

// A baseline of this version whose values lie beyond their tolerance of this run's, as if the code
// had changed its results without a new version.
TEST(ResultsVersion, UpdateRefusesNewResultsUnderTheVersionThatWroteTheOld) {
  const fs::path dir = fs::path(::testing::TempDir()) / "strokelab_results_version";
  fs::remove_all(dir);
  fs::create_directories(dir / "baselines");
  const std::string name = "simulate_8hz_exact.json";
  json baseline = ReadJson(kBaselines / name);
  baseline["code_version"] = strokelab::jobs::kCodeVersion;
  json& force = baseline["tables"]["records"][0]["first_harmonic_force_n"];
  force = force.get<double>() * 1.01;
  std::ofstream(dir / "baselines" / name) << baseline.dump();
  std::ofstream(dir / "baselines" / regression::kLedgerFile)
      << regression::FormatLedgerLine({strokelab::jobs::kCodeVersion, regression::JobKey(baseline["job"]),
                                       regression::TablesKey(baseline["tables"]), name});
  const std::string before = ReadText(dir / "baselines" / name);

  const std::string args = "regress " + (fs::path(STROKELAB_REGRESS_DIR) / "jobs" / name).string() + " --baseline " +
                           (dir / "baselines").string() + " --update";
  CliResult r = RunCli(args);
  EXPECT_EQ(r.exit_code, 1) << r.stdout_text << r.stderr_text;
  EXPECT_THAT(r.stdout_text, HasSubstr("not written: the results changed but the version did not"));
  EXPECT_THAT(r.stdout_text, HasSubstr("bump VERSION in project() of CMakeLists.txt"));
  EXPECT_EQ(ReadText(dir / "baselines" / name), before);

  // Under another version the same results are written, and the ledger gains that version's line.
  baseline["code_version"] = "strokelab-0.0.1";
  std::ofstream(dir / "baselines" / name) << baseline.dump();
  std::ofstream(dir / "baselines" / regression::kLedgerFile)
      << regression::FormatLedgerLine({"strokelab-0.0.1", regression::JobKey(baseline["job"]),
                                       regression::TablesKey(baseline["tables"]), name});
  r = RunCli(args);
  EXPECT_EQ(r.exit_code, 0) << r.stdout_text << r.stderr_text;
  EXPECT_THAT(r.stdout_text, HasSubstr("UPDATED"));
  const auto ledger = regression::ReadLedger((dir / "baselines" / regression::kLedgerFile).string());
  ASSERT_EQ(ledger.size(), 2u);
  EXPECT_EQ(ledger[1].code_version, strokelab::jobs::kCodeVersion);
  EXPECT_EQ(ledger[1].tables_key, regression::TablesKey(ReadJson(dir / "baselines" / name)["tables"]));
}

TEST(ResultsVersion, ALedgerLineTwiceForOneVersionAndJobIsBadInput) {
  const fs::path file = fs::path(::testing::TempDir()) / "strokelab_ledger_twice.txt";
  std::ofstream(file) << "# comment\nv1 aaaa bbbb a.json\nv1 aaaa cccc a.json\n";
  try {
    regression::ReadLedger(file.string());
    FAIL() << "a repeated line was accepted";
  } catch (const std::exception& e) {
    EXPECT_THAT(e.what(), HasSubstr(file.string() + ":3"));
  }
}

}  // namespace
