// strokelab regress: regression jobs for CI. Runs job files (the service's job JSON) in process,
// compares their result rows with stored baselines field by field (regression.h), prints one line
// per job file, and exits 0 when all pass, 1 on a regression, 2 on bad input.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "commands.h"
#include "regression.h"
#include "strokelab/base/errors.h"
#include "strokelab/jobs/jobs.h"
#include "strokelab/base/json_parse.h"

namespace strokelab::cli {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;
using regression::Tolerance;
using regression::Tolerances;

constexpr size_t kMaxDetails = 10;  // regression lines printed per job file

constexpr const char* kRegressHelp = R"(usage: strokelab regress JOB.json... --baseline DIR [--update]

Regression jobs for CI. Runs each job file in process, as the service's workers would (its tasks
in order), compares the result rows with the baseline DIR/NAME (NAME: the job file's own name)
field by field, prints one line per job file, and exits with
  0  all pass (or, with --update, all baselines written)
  1  a regression: a value beyond its tolerance, a missing or extra row, a missing baseline, a
     job that changed since its baseline was written, a job that fails to run
  2  bad input: a job file that is not JSON or not a valid job, a bad "tolerances" entry, an
     unreadable baseline (one line naming the file and the JSON pointer; nothing is run)

  --baseline DIR   the baselines: one JSON file per job file, with the same name, holding the
                   job, the code version and the result rows by table
  --update         write (or overwrite) the baselines from this run; differences from an old
                   baseline are listed, and only a job that fails to run makes it fail, or one
                   whose results changed while the version did not: DIR/results-ledger.txt holds
                   one line per version and job, and a version has one result per job (bump
                   VERSION in CMakeLists.txt when results change: tasks are cached by version)

Job files are the service's job JSON (schema/job.schema.json, as for POST /v1/jobs and
strokelab submit) with one optional extra member, "tolerances", which is removed before the job
is validated (the job schema admits no unknown members) and changes the tolerance of named fields:
  "tolerances": {"first_harmonic_force_n": {"relative": 1e-6},
                 "points.max_multiplier": "ignore"}
A rule is {"relative": R, "absolute": A} (passes when |now - baseline| <= max(A, R |baseline|);
a part left out is 0), "exact" or "ignore"; it replaces the default rule of that field, in every
table or, as "TABLE.FIELD", in one (points, jumps, thresholds, records).

Rows are matched by table and key (frequency_hz, amplitude_v, branch, and order among rows with
equal keys); missing and extra rows are regressions. null (a non-finite number) equals only null.

Columns: RESULT is PASS, FAIL, NEW (baseline written for the first time) or UPDATED (baseline
overwritten); ROWS the rows compared (or written); WORST the value that came closest to its
tolerance: its relative deviation (absolute when the baseline value is 0), the share of the
tolerance it used, and where; 0 when every value is identical.

Default tolerances by field (other fields: relative 1e-9 for numbers, exact otherwise):
)";

struct JobFile {
  std::string path;              // as given
  std::string name;              // file name: the baseline's name too
  json job;                      // without "tolerances"
  Tolerances tolerances = Tolerances::Defaults();
  std::vector<jobs::TaskSpec> tasks;
  fs::path baseline_path;
  std::optional<json> baseline;  // parsed and checked; none: no (readable) baseline
  std::string baseline_problem;  // with --update: why an existing baseline was not read
};

struct Outcome {
  std::string result;            // PASS, FAIL, NEW, UPDATED
  std::string rows = "-";
  std::string time = "-";
  std::string worst = "-";
  std::vector<std::string> details;
  size_t more = 0;               // details left out
};

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot read the file");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// nlohmann's parse message without its "[json.exception.parse_error.101] " prefix.
std::string ParseMessage(const json::parse_error& e) {
  std::string message = e.what();
  if (const size_t end = message.find("] "); message.rfind("[json.exception", 0) == 0 && end != std::string::npos)
    message = message.substr(end + 2);
  return message;
}

json ParseJsonFile(const std::string& path) {
  const std::string text = ReadFile(path);
  try {
    return ParseJson(text);
  } catch (const json::parse_error& e) {
    throw InputError(path, "not valid JSON: " + ParseMessage(e));
  } catch (const json::exception& e) {  // a number beyond a double (out_of_range 406)
    throw InputError(path, std::string("not valid JSON: ") + e.what());
  }
}

// An InputError from inside a file, with the file named first: "jobs/a.json: /grid/to: must be ...".
InputError InFile(const std::string& path, const InputError& e) {
  return InputError(e.field().empty() ? path : path + ": " + e.field(), e.bare_message());
}

JobFile LoadJobFile(const std::string& path, const fs::path& baseline_dir, bool update) {
  JobFile file;
  file.path = path;
  file.name = fs::path(path).filename().string();
  file.baseline_path = baseline_dir / file.name;
  json job = ParseJsonFile(path);
  if (!job.is_object()) throw InputError(path, "a job file must hold one JSON object (a job)");
  try {
    if (auto it = job.find("tolerances"); it != job.end()) {
      file.tolerances.Apply(*it, "/tolerances");
      job.erase(it);
    }
    file.tasks = jobs::PlanTasks(job);  // validates the job (schema, then semantics)
  } catch (const InputError& e) {
    throw InFile(path, e);
  }
  file.job = std::move(job);
  if (fs::exists(file.baseline_path)) {
    const std::string baseline_file = file.baseline_path.string();
    try {
      json baseline = ParseJsonFile(baseline_file);
      regression::CheckBaseline(baseline, baseline_file);
      file.baseline = std::move(baseline);
    } catch (const InputError& e) {
      if (!update) throw;
      file.baseline_problem = std::string("the old baseline was not readable (") + e.what() + ")";
    }
  }
  return file;
}

// Every task of the job in order; rows collected by table, as written to a baseline.
json RunJob(const JobFile& file) {
  json tables = json::object();
  for (const jobs::TaskSpec& task : file.tasks)
    for (jobs::ResultRow& row : jobs::RunTask(task.spec).AllRows()) tables[row.table].push_back(std::move(row.values));
  return regression::Normalized(tables);
}

// A job as far as it matters for its results ("name" is a label for people).
json WithoutName(json job) {
  if (job.is_object()) job.erase("name");
  return job;
}

size_t RowCount(const json& tables) {
  size_t rows = 0;
  for (const auto& [name, table] : tables.items()) rows += table.size();
  return rows;
}

std::string Format(const char* format, double value) {
  char text[64];
  std::snprintf(text, sizeof text, format, value);
  return text;
}

std::string WorstText(const std::optional<regression::Worst>& worst) {
  if (!worst) return "0";
  const regression::ValueCheck& c = worst->check;
  if (!std::isfinite(c.absolute)) return "mismatch at " + worst->where;
  std::string text = std::isfinite(c.relative) ? Format("%.1e rel", c.relative) : Format("%.1e abs", c.absolute);
  text += !std::isfinite(c.used) ? std::string(" (exact field)")
          : c.used <= 1         ? Format(" (%.0f%% of tol)", 100 * c.used)
                                : Format(" (%.3g x tol)", c.used);
  return text + " at " + worst->where;
}

void AddDetails(Outcome& outcome, const std::vector<std::string>& lines) {
  for (const std::string& line : lines) {
    if (outcome.details.size() < kMaxDetails) {
      outcome.details.push_back(line);
    } else {
      ++outcome.more;
    }
  }
}

void WriteBaseline(const JobFile& file, const json& tables) {
  fs::create_directories(file.baseline_path.parent_path());
  const fs::path temporary = file.baseline_path.string() + ".tmp";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    out << regression::FormatBaseline(file.job, jobs::kCodeVersion, tables);
    if (!out.flush()) throw std::runtime_error("cannot write " + temporary.string());
  }
  fs::rename(temporary, file.baseline_path);
}

// The results ledger of a baseline directory (regression.h): read once, appended as baselines are
// written.
struct Ledger {
  std::string path;
  std::vector<regression::LedgerEntry> entries;

  void Add(const regression::LedgerEntry& entry) {
    std::ofstream out(path, std::ios::app);
    out << regression::FormatLedgerLine(entry);
    if (!out.flush()) throw std::runtime_error("cannot write " + path);
    entries.push_back(entry);
  }
};

Outcome RunOne(const JobFile& file, const fs::path& baseline_dir, bool update, Ledger& ledger) {
  Outcome outcome;
  const std::string update_hint = "strokelab regress " + file.path + " --baseline " + baseline_dir.string() + " --update";
  if (!update && !file.baseline) {
    outcome.result = "FAIL";
    outcome.worst = "no baseline";
    outcome.details.push_back("no baseline " + file.baseline_path.string() +
                              (fs::is_directory(baseline_dir) ? "" : " (the directory does not exist)") +
                              "; create it with: " + update_hint);
    return outcome;
  }

  const auto start = std::chrono::steady_clock::now();
  json tables;
  try {
    tables = RunJob(file);
  } catch (const std::exception& e) {
    outcome.result = "FAIL";
    outcome.details.push_back(std::string("the job failed to run: ") + e.what());
    return outcome;
  }
  outcome.time = Format("%.2f s", std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());

  std::vector<std::string> notes;
  std::optional<regression::Comparison> comparison;
  if (file.baseline) {
    const json& baseline = *file.baseline;
    comparison = regression::CompareTables(baseline["tables"], tables, file.tolerances);
    if (WithoutName(baseline["job"]) != WithoutName(file.job))
      comparison->regressions.insert(comparison->regressions.begin(),
                                     "the job differs from the baseline's \"job\" (the job file changed since the baseline was written)");
    const std::string version = baseline.value("code_version", std::string("?"));
    if (version != jobs::kCodeVersion)
      notes.push_back("the baseline was written by " + version + ", this is " + jobs::kCodeVersion);
    outcome.worst = WorstText(comparison->worst);
  }

  if (update) {
    const regression::LedgerEntry entry{jobs::kCodeVersion, regression::JobKey(file.job), regression::TablesKey(tables),
                                        file.name};
    const auto recorded = regression::FindEntry(ledger.entries, entry.code_version, entry.job_key);
    const bool same_version_and_job = file.baseline && (*file.baseline)["code_version"] == entry.code_version &&
                                      WithoutName((*file.baseline)["job"]) == WithoutName(file.job);
    if (recorded && recorded->tables_key != entry.tables_key && same_version_and_job && comparison->Passed()) {
      // Rounding-level differences (another compiler or CPU): the version's baseline stands.
      outcome.result = "PASS";
      outcome.rows = std::to_string(comparison->rows_compared);
      outcome.details.push_back("kept " + file.baseline_path.string() +
                                ": this version wrote it, and this run is within its tolerances");
      AddDetails(outcome, notes);
      return outcome;
    }
    if (recorded && recorded->tables_key != entry.tables_key) {
      // Tasks are cached by spec and version: the old results would still be served as this code's.
      outcome.result = "FAIL";
      outcome.details.push_back("not written: the results changed but the version did not (" + entry.code_version +
                                " has other results for this job in " + ledger.path +
                                "); bump VERSION in project() of CMakeLists.txt, rebuild, and run --update again");
      AddDetails(outcome, notes);
      return outcome;
    }
    WriteBaseline(file, tables);
    if (!recorded) ledger.Add(entry);
    outcome.result = file.baseline || !file.baseline_problem.empty() ? "UPDATED" : "NEW";
    outcome.rows = std::to_string(RowCount(tables));
    outcome.details.push_back("wrote " + file.baseline_path.string() + " (" + outcome.rows +
                              (outcome.rows == "1" ? " row)" : " rows)"));
    if (!file.baseline_problem.empty()) outcome.details.push_back(file.baseline_problem);
    AddDetails(outcome, notes);
    if (comparison && !comparison->Passed()) {
      outcome.details.push_back("changes from the old baseline beyond tolerance (" +
                                std::to_string(comparison->regressions.size()) + "):");
      AddDetails(outcome, comparison->regressions);
    }
    return outcome;
  }

  outcome.rows = std::to_string(comparison->rows_compared);
  outcome.result = comparison->Passed() ? "PASS" : "FAIL";
  AddDetails(outcome, notes);
  AddDetails(outcome, comparison->regressions);
  if (!comparison->Passed()) {
    // The hint goes last even when details were cut.
    outcome.details.push_back((outcome.more ? "... and " + std::to_string(outcome.more) + " more; " : std::string()) +
                              "if the change is intended: " + update_hint);
    outcome.more = 0;
  }
  return outcome;
}

}  // namespace

int RunRegress(const std::vector<std::string>& argv) {
  const Args args(argv, {"--baseline"}, {"--update", "--help"});
  if (args.Has("--help")) {
    std::cout << kRegressHelp;
    const Tolerances defaults = Tolerances::Defaults();
    for (const std::string& field : defaults.KnownFields())
      std::cout << "  " << field << std::string(field.size() < 28 ? 28 - field.size() : 1, ' ')
                << defaults.For("", field).Describe() << "\n";
    return 0;
  }
  const std::vector<std::string>& paths = args.Positional();
  if (paths.empty()) throw InputError("regress", "give one or more job files (strokelab regress JOB.json... --baseline DIR)");
  const auto baseline_arg = args.Get("--baseline");
  if (!baseline_arg) throw InputError("--baseline", "required: the directory of the baselines");
  const fs::path baseline_dir = *baseline_arg;
  const bool update = args.Has("--update");
  if (fs::exists(baseline_dir) && !fs::is_directory(baseline_dir))
    throw InputError("--baseline", "'" + baseline_dir.string() + "' is not a directory");

  // Every job file is read, validated and planned (and its baseline read) before anything runs, so
  // that bad input stops the run at once with exit code 2.
  std::vector<JobFile> files;
  std::map<std::string, std::string> by_name;
  for (const std::string& path : paths) {
    files.push_back(LoadJobFile(path, baseline_dir, update));
    const auto [it, inserted] = by_name.emplace(files.back().name, path);
    if (!inserted)
      throw InputError(path, "has the same file name as " + it->second + " (their baselines would collide)");
  }

  size_t width = 3;
  for (const JobFile& file : files) width = std::max(width, file.name.size());
  const auto line = [&](const std::string& name, const std::string& result, const std::string& rows,
                        const std::string& time, const std::string& worst) {
    std::printf("%-*s  %-7s  %6s  %7s  %s\n", static_cast<int>(width), name.c_str(), result.c_str(), rows.c_str(),
                time.c_str(), worst.c_str());
    std::fflush(stdout);
  };
  std::printf("strokelab regress: %zu job file%s against %s (%s)%s\n", files.size(), files.size() == 1 ? "" : "s",
              baseline_dir.string().c_str(), jobs::kCodeVersion, update ? ", updating the baselines" : "");
  line("JOB", "RESULT", "ROWS", "TIME", "WORST");

  Ledger ledger{(baseline_dir / regression::kLedgerFile).string(), {}};
  ledger.entries = regression::ReadLedger(ledger.path);

  const auto start = std::chrono::steady_clock::now();
  std::vector<Outcome> outcomes;
  std::map<std::string, int> counts;
  for (const JobFile& file : files) {
    outcomes.push_back(RunOne(file, baseline_dir, update, ledger));
    const Outcome& o = outcomes.back();
    ++counts[o.result];
    line(file.name, o.result, o.rows, o.time, o.worst);
  }
  const double total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  for (size_t i = 0; i < files.size(); ++i) {
    const Outcome& o = outcomes[i];
    if (o.details.empty()) continue;
    std::printf("\n%s: %s\n", files[i].name.c_str(), o.result.c_str());
    for (const std::string& detail : o.details) std::printf("  %s\n", detail.c_str());
    if (o.more) std::printf("  ... and %zu more\n", o.more);
  }
  std::string summary;
  for (const char* result : {"FAIL", "PASS", "NEW", "UPDATED"})
    if (counts[result]) summary += (summary.empty() ? "" : ", ") + std::to_string(counts[result]) + " " +
                                   (std::string(result) == "FAIL" ? "failed" : std::string(result) == "PASS" ? "passed"
                                                                             : std::string(result) == "NEW" ? "new" : "updated");
  std::printf("\n%s in %.2f s\n", summary.c_str(), total_s);
  return counts["FAIL"] ? 1 : 0;
}

}  // namespace strokelab::cli
