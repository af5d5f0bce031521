#include "strokelab/jobs/jobs.h"

#include <algorithm>
#include <cstdio>
#include <functional>

#include "strokelab/base/cancel.h"
#include "strokelab/base/json_number.h"
#include "strokelab/diagnose/diagnose.h"
#include "strokelab/report/broadband_report.h"
#include "strokelab/report/diagnose_report.h"
#include "strokelab/report/diagnosis_data.h"
#include "strokelab/report/diagnosis_maps.h"
#include "campaign_rows_internal.h"
#include "strokelab/jobs/campaign_bundle.h"
#include "strokelab/report/sweep_tables.h"
#include "strokelab/engines/engine.h"
#include "strokelab/base/errors.h"
#include "strokelab/identify/broadband_campaign.h"
#include "strokelab/identify/fit.h"
#include "strokelab/identify/mixed_campaign.h"
#include "strokelab/model/model_json.h"
#include "strokelab/engines/record_summary.h"
#include "strokelab/data/recordings.h"
#include "strokelab/jobs/campaign_warnings.h"
#include "strokelab/jobs/campaigns.h"
#include "strokelab/jobs/job_spec.h"
#include "strokelab/sweep/sweep.h"

namespace strokelab::jobs {
namespace {

constexpr size_t kColumnsPerTask = 16;  // threshold columns take ~2 ms each: chunks of ~30 ms

TaskSpec MakeTask(nlohmann::json spec) {
  spec["code_version"] = kCodeVersion;
  return {ContentKey(spec.dump()), std::move(spec)};
}

namespace fs = std::filesystem;

// The report's files: one HTML page and CSV tables (diagnose_report.h).
std::string ContentTypeOf(const std::string& name) {
  if (name.ends_with(".html")) return "text/html; charset=utf-8";
  if (name.ends_with(".csv")) return "text/csv; charset=utf-8";
  if (name.ends_with(".svg")) return "image/svg+xml";
  if (name.ends_with(".json")) return "application/json";
  return "text/plain; charset=utf-8";
}

// A report's files (`write` into a scratch directory, then `files` read back) as result rows. They are
// UTF-8 text (an HTML page, CSV tables, the model file), stored as JSON strings.
std::vector<ResultRow> ReportRows(const std::function<void(const fs::path&)>& write, const std::vector<std::string>& files) {
  const fs::path dir = fs::temp_directory_path() / ("strokelab-report-" + NewCampaignId());
  std::vector<ResultRow> rows;
  try {
    write(dir);
    for (const std::string& name : files)
      rows.push_back({"report_files",
                      {{"name", name}, {"content_type", ContentTypeOf(name)}, {"text", ReadFileBytes(dir / name)}}});
  } catch (...) {
    std::error_code ignored;
    fs::remove_all(dir, ignored);
    throw;
  }
  fs::remove_all(dir);
  return rows;
}

std::vector<ResultRow> WithWarningsAndReport(std::vector<ResultRow> rows, const std::vector<std::string>& warnings,
                                             std::vector<ResultRow> report) {
  for (ResultRow& row : WarningRows(warnings)) rows.push_back(std::move(row));
  for (ResultRow& row : report) rows.push_back(std::move(row));
  return rows;
}

}  // namespace

std::vector<ResultRow> DiagnosisRows(const Diagnosis& diagnosis, const report::DiagnosisMaps& maps) {
  return WithWarningsAndReport(
      {{"diagnosis", DiagnosisToJson(diagnosis)}}, DiagnosisWarnings(diagnosis),
      ReportRows([&](const fs::path& dir) { report::WriteDiagnosisReport(diagnosis, dir, &maps); },
                 report::DiagnosisReportFiles()));
}

std::vector<ResultRow> BroadbandDiagnosisRows(const BroadbandDiagnosis& diagnosis, nlohmann::json base_fit,
                                              const report::DiagnosisMaps& maps) {
  return WithWarningsAndReport(
      {{"diagnosis", BroadbandDiagnosisToJson(diagnosis, std::move(base_fit))}}, BroadbandDiagnosisWarnings(diagnosis),
      ReportRows([&](const fs::path& dir) { report::WriteBroadbandDiagnosisReport(diagnosis, dir, &maps); },
                 report::BroadbandDiagnosisReportFiles()));
}

namespace {

// A fit or diagnose task: the campaign is read again (and must still have the digest it was planned
// with), then fitted or diagnosed, its progress reported with the time. `as_data`: a diagnosis goes
// out as data (RunTaskForRemote), and the server adds its warnings (CampaignRowsFromWorker).
std::vector<ResultRow> RunCampaignTask(const nlohmann::json& task, bool as_data, const TaskProgressHook& progress) {
  ProgressClock clock;
  const std::string type = task.at("type");
  const fs::path dir = task.at("campaign_dir").get<std::string>();
  if (CampaignDigest(dir) != task.at("campaign_digest"))
    throw std::runtime_error("the campaign changed after the job was submitted; submit the job again");
  const Campaign campaign = ReadCampaign(dir);
  const nlohmann::json& job = task.at("job");
  if (type == "fit") {
    // The fit reports no stages of its own: one stage, with the time.
    if (progress) progress(clock.Report({1, 1, "fit on " + std::to_string(campaign.records.size()) + " records", {}}));
    // By the campaign's records: stepped sines, broadband records, or both (mixed_campaign.h).
    const FitOptions options = FitOptionsFromJob(job);
    std::vector<ResultRow> rows;
    std::vector<std::string> warnings;
    switch (FitKindOf(campaign, options)) {
      case CampaignFitKind::kSteppedSine: {
        const FitResult fit = FitCampaign(campaign, options);
        rows = {{"fit", FitResultToJson(fit)}};
        warnings = FitWarnings(fit);
        break;
      }
      case CampaignFitKind::kBroadband: {
        const BroadbandCampaignFit fit = FitBroadbandCampaign(campaign, options);
        rows = {{"fit", BroadbandCampaignFitToJson(fit)}};
        warnings = BroadbandFitWarnings(fit.result);
        break;
      }
      case CampaignFitKind::kMixed: {
        const MixedCampaignFit fit = FitMixedCampaign(campaign, options);
        rows = {{"fit", MixedCampaignFitToJson(fit)}};
        warnings = BroadbandFitWarnings(fit.result);
        break;
      }
    }
    if (as_data) return rows;  // a remote fit's row alone (CampaignRowsFromWorker takes one row)
    for (ResultRow& row : WarningRows(warnings)) rows.push_back(std::move(row));
    return rows;
  }
  DiagnoseOptions options = DiagnoseOptionsFromJob(job);
  if (progress) options.progress = [&](const ProgressStage& stage) { progress(clock.Report(stage)); };
  // As `strokelab diagnose`: broadband records only by their time series, otherwise the stepped sines.
  // The report's maps of the base and the diagnosed model, within what is left of max_seconds.
  if (FitKindOf(campaign) == CampaignFitKind::kBroadband) {
    const BroadbandDiagnosis diagnosis = DiagnoseBroadbandCampaign(campaign, options);
    const report::DiagnosisMaps maps = report::SweepBroadbandDiagnosisMaps(diagnosis, campaign, options);
    if (as_data) return {{"broadband_diagnosis_data", report::BroadbandDiagnosisDataToJson(diagnosis, maps)}};
    return BroadbandDiagnosisRows(diagnosis, BroadbandCampaignFitToJson(diagnosis.base), maps);
  }
  const Diagnosis diagnosis = DiagnoseCampaign(campaign, options);
  const report::DiagnosisMaps maps = report::SweepDiagnosisMaps(diagnosis, options);
  if (as_data) return {{"diagnosis_data", report::DiagnosisDataToJson(diagnosis, maps)}};
  return DiagnosisRows(diagnosis, maps);
}

}  // namespace

bool IsCampaignKind(const std::string& kind) { return kind == "fit" || kind == "diagnose"; }

std::string ContentKey(const std::string& text) {
  uint64_t hash = 1469598103934665603ull;
  for (unsigned char c : text) {
    hash ^= c;
    hash *= 1099511628211ull;
  }
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(hash));
  return hex;
}

std::vector<TaskSpec> PlanTasks(const nlohmann::json& job, const CampaignDirs& campaigns) {
  ValidateJob(job);
  const std::string kind = job.at("kind");
  std::vector<TaskSpec> tasks;
  if (kind == "sweep") {
    const SweepSpec spec = SweepSpecFromJob(job);
    const nlohmann::json model = ModelToJson(spec.model);
    const std::vector<double> frequencies = spec.frequency_hz.Values();
    for (double amplitude : spec.amplitude_v.Values())
      tasks.push_back(MakeTask({{"type", "sweep_row"}, {"model", model}, {"amplitude_v", amplitude},
                                {"frequencies_hz", frequencies}}));
    if (spec.thresholds) {
      for (size_t first = 0; first < frequencies.size(); first += kColumnsPerTask) {
        const size_t last = std::min(frequencies.size(), first + kColumnsPerTask);
        tasks.push_back(MakeTask({{"type", "sweep_columns"},
                                  {"model", model},
                                  {"frequencies_hz", std::vector<double>(frequencies.begin() + first,
                                                                         frequencies.begin() + last)}}));
      }
    }
  } else if (kind == "simulate") {
    nlohmann::json spec = job;
    spec.erase("name");
    spec["type"] = "simulate";
    spec["model"] = ModelToJson(ModelFromJson(job.at("model"), "/model"));
    tasks.push_back(MakeTask(spec));
  } else if (IsCampaignKind(kind)) {
    const fs::path dir = ResolveCampaign(job.at("campaign"), campaigns);
    const bool under_root = job.at("campaign").contains("path");
    const std::string digest =
        CampaignDigest(dir, under_root ? fs::canonical(campaigns.data_root) : fs::path(), campaigns.max_campaign_bytes);
    // Uploads were read when they were stored; a fit without the refinement reads the campaign for its
    // kind of records (FitKindOf: a broadband campaign has no staged estimates to stop at).
    const bool staged_only = kind == "fit" && !FitOptionsFromJob(job).refine;
    if (under_root || staged_only) {
      Campaign campaign;
      try {
        campaign = ReadCampaign(dir);
      } catch (const InputError& e) {
        throw CampaignError(e.field(), e.bare_message());
      }
      if (staged_only) {
        try {
          (void)FitKindOf(campaign, FitOptionsFromJob(job));
        } catch (const InputError& e) {
          throw InputError("/options/refine", e.bare_message());
        }
      }
    }
    nlohmann::json spec_job = job;
    spec_job.erase("name");
    tasks.push_back(MakeTask({{"type", kind}, {"job", spec_job}, {"campaign_dir", dir.string()},
                              {"campaign_digest", digest}, {"campaign_sha256", CampaignSha256(dir)}}));
  } else {
    throw InputError("/kind", "job kind '" + kind + "' is not served yet");
  }
  return tasks;
}

namespace {

// A sweep table's rows as flat records (task.h), if there are any.
template <class Row>
void AddRecords(const std::string& table, const std::vector<Row>& rows, TaskResult& result) {
  if (rows.empty()) return;
  ResultRecords& records = result.records.emplace_back();
  records.table = table;
  records.columns = report::ColumnNames<Row>();
  records.cells.reserve(rows.size() * records.columns.size());
  for (const Row& row : rows) report::AppendCells(row, records.cells);
}

// One task's rows; its loops poll the thread's cancel flag (RunTask sets it). `as_data`: a diagnose
// task's result as data (RunTaskForRemote) instead of the rendered report.
TaskResult RunTaskRows(const nlohmann::json& task, bool as_data, const TaskProgressHook& progress) {
  const std::string type = task.at("type");
  if (IsCampaignKind(type)) return RunCampaignTask(task, as_data, progress);
  const ActuatorModel model = ModelFromJson(task.at("model"), "/model");
  TaskResult result;
  std::vector<ResultRow>& rows = result.rows;
  if (type == "sweep_row") {
    const SweepRowResult row =
        SweepRow(model, task.at("amplitude_v").get<double>(), task.at("frequencies_hz").get<std::vector<double>>());
    AddRecords("points", row.points, result);
    AddRecords("jumps", row.jumps, result);
  } else if (type == "sweep_columns") {
    std::vector<SaturationThreshold> thresholds;
    for (double f : task.at("frequencies_hz").get<std::vector<double>>()) thresholds.push_back(SweepColumn(model, f));
    AddRecords("thresholds", thresholds, result);
  } else if (type == "simulate") {
    const SineDrive drive{task.at("amplitude_v").get<double>(), task.at("frequency_hz").get<double>(), 0.0};
    SimulationOptions options;
    options.duration_s = task.value("duration_s", 10.0);
    options.sample_rate_hz = task.value("sample_rate_hz", 51200.0);
    options.record_velocity = false;
    const MethodChoice method = ChooseMethod(task.value("method", std::string("auto")), model);
    const Record record = MakeEngine(method.method)->Simulate(model, drive, options);
    const RecordSummary s = Summarize(record, drive);
    rows.push_back({"records",
                    {{"frequency_hz", drive.frequency_hz},
                     {"amplitude_v", drive.amplitude_v},
                     {"method", method.Describe()},
                     {"min_displacement_m", s.min_displacement_m},
                     {"max_displacement_m", s.max_displacement_m},
                     {"contacts", s.contacts},
                     {"mean_contact_ms", JsonNumber(s.mean_contact_ms)},
                     {"peak_force_n", s.peak_force_n},
                     {"first_harmonic_force_n", s.first_harmonic_force_n},
                     {"first_harmonic_phase_rad", s.first_harmonic_phase_rad}}});
  } else {
    throw InputError("type", "unknown task type '" + type + "'");
  }
  return result;
}

// Runs the task's rows under `cancel`: every loop of the task polls it (base/cancel.h): engines,
// sweeps, ParallelFor, Ceres solves.
TaskResult RunRowsUnder(const nlohmann::json& task, const std::atomic<bool>* cancel, bool as_data,
                        const TaskProgressHook& progress) {
  const CancelScope scope(cancel);
  TaskResult result = RunTaskRows(task, as_data, progress);
  // A solve the flag aborted returns what it had: rows computed while it was raised are dropped.
  ThrowIfCancelled();
  return result;
}

}  // namespace

TaskResult RunTask(const nlohmann::json& task, const std::atomic<bool>* cancel, const TaskProgressHook& progress) {
  return RunRowsUnder(task, cancel, false, progress);
}

std::vector<ResultRow> RunTaskForRemote(const nlohmann::json& task, const std::atomic<bool>* cancel,
                                        const TaskProgressHook& progress) {
  return RunRowsUnder(task, cancel, true, progress).AllRows();
}

}  // namespace strokelab::jobs
