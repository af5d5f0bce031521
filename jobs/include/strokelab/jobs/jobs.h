// The bridge between the job store and core: a job is split into tasks, and one task is run.
//
// A sweep becomes one task per amplitude row (continuation in frequency: steady states and jump
// intervals) and one task per chunk of frequency columns (saturation thresholds); a simulate job is
// one task. A fit or diagnose job is one task over a campaign on the server's disk (an upload or a
// directory under the data root): its spec carries the campaign's canonical directory and content
// digest (checked again when the task runs: a campaign changed since submission fails the job), and
// its result is one row, table "fit" (FitResultToJson) or "diagnosis" (DiagnosisToJson), plus, for
// diagnose, the HTML report's files (with the saturation maps of the base and the diagnosed model,
// swept in the same task within what is left of the job's max_seconds, and the diagnosed model's
// model.json) as rows of table "report_files" ({"name", "content_type", "text"}), and what its
// status warns of as rows of table "warnings" ({"warning"}; campaign_warnings.h). Its spec also
// carries the SHA-256 of the campaign's bundle (campaign_sha256, campaign_bundle.h), by which a remote
// worker fetches the campaign and checks what it got; a remote worker sends a diagnosis as data
// (RunTaskForRemote) and the server renders the report (CampaignRowsFromWorker, task_rows.h). Task
// specs carry the full model, so that a task's key (a hash of its spec and the code version)
// identifies its result whatever job it came from.
#pragma once

#include <atomic>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "strokelab/base/progress.h"
#include "strokelab/jobs/campaigns.h"
#include "strokelab/jobs/task.h"
#include "strokelab/jobs/version.h"
#include "strokelab/sweep/sweep.h"

namespace strokelab::jobs {

// Splits a validated job into tasks (throws InputError naming the field for semantic errors). A
// campaign job's campaign is resolved in `campaigns` and read (a bad campaign is an InputError naming
// its file and line).
std::vector<TaskSpec> PlanTasks(const nlohmann::json& job, const CampaignDirs& campaigns = {});

// Whether a job kind works on a campaign (fit, diagnose): a remote worker fetches the campaign first.
bool IsCampaignKind(const std::string& kind);

// A fit or diagnose task's progress: stage k of N with the time elapsed and an estimate of the time
// left (base/progress.h), from the task's thread (a diagnosis's maps: from their sweep's threads, one
// at a time).
using TaskProgressHook = std::function<void(const ProgressReport&)>;

// Runs one task under `cancel` (a CancelScope, base/cancel.h): every loop of every kind (sweep points,
// the engines' steps, the fit's and diagnosis's items and Ceres iterations) polls it, and the task
// ends with strokelab::Cancelled within a few ms of it being raised (a Ceres iteration at worst).
// `progress` (may be empty) hears a fit or diagnose task's stages.
TaskResult RunTask(const nlohmann::json& task_spec, const std::atomic<bool>* cancel = nullptr,
                   const TaskProgressHook& progress = {});

// What a remote worker runs: RunTask (under `cancel` the same way) with every row as JSON (AllRows),
// except that a diagnose task's result is one row of table "diagnosis_data" (report/diagnosis_data.h:
// the diagnosis and its maps as data; "broadband_diagnosis_data" for a campaign of broadband records
// only) instead of the rendered report, which the server renders itself.
// The task's campaign_dir must name the campaign.
std::vector<ResultRow> RunTaskForRemote(const nlohmann::json& task_spec, const std::atomic<bool>* cancel = nullptr,
                                        const TaskProgressHook& progress = {});

// 64-bit FNV-1a of the text, as 16 hex digits (a content key, not a security hash).
std::string ContentKey(const std::string& text);

}  // namespace strokelab::jobs
