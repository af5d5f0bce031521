// The job routes: submit, list, read and cancel jobs, and upload campaigns for fit and diagnose jobs.
#include "service_impl.h"

#include <cmath>

#include "campaign_upload.h"
#include "http_reply.h"
#include "now.h"
#include "request_params.h"
#include "strokelab/base/errors.h"
#include "strokelab/jobs/job_spec.h"
#include "strokelab/jobs/jobs.h"

namespace strokelab::server {

using nlohmann::json;
using namespace internal;

json JobJson(const JobRecord& job) {
  json j = {{"id", job.id},
            {"kind", job.kind},
            {"status", ToString(job.status)},
            {"progress", {{"done", job.tasks_done}, {"total", job.tasks_total}}},
            {"warnings", json::array()},
            {"created_ms", job.created_ms},
            {"started_ms", job.started_ms ? json(job.started_ms) : json(nullptr)},
            {"finished_ms", job.finished_ms ? json(job.finished_ms) : json(nullptr)}};
  if (job.spec.contains("name")) j["name"] = job.spec["name"];
  if (job.started_ms) j["elapsed_s"] = ((job.finished_ms ? job.finished_ms : NowMs()) - job.started_ms) / 1000.0;
  if (!job.error.empty()) j["error"] = job.error;
  return j;
}

json JobDetailJson(const JobRecord& job) {
  json j = JobJson(job);
  j["spec"] = job.spec;
  try {
    j["resolved"] = jobs::ResolvedJob(job.spec);
  } catch (const InputError&) {
    j["resolved"] = nullptr;  // a spec stored by an older strokelab that this one no longer takes
  }
  return j;
}

json StageProgressJson(const ProgressReport& r) {
  return {{"stage", r.stage.stage},
          {"stages", r.stage.stages},
          {"stage_name", r.stage.name},
          {"step", r.stage.step},
          {"elapsed_s", r.elapsed_s},
          {"eta_s", std::isfinite(r.eta_s) ? json(r.eta_s) : json(nullptr)}};
}

void Service::Impl::AddCampaignStatus(const JobRecord& job, json* j) {
  if (!jobs::IsCampaignKind(job.kind)) return;
  if (job.status == JobStatus::kRunning) {
    // The job's newest computation. One that has ended while the job still runs is having its
    // result stored: its last stage is shown as that, not dropped (the page would show "0 / 1
    // tasks" for that moment).
    json live;
    {
      std::lock_guard<std::mutex> lock(computations_mutex);
      for (auto it = computations.rbegin(); it != computations.rend() && live.is_null(); ++it) {
        std::lock_guard<std::mutex> progress_lock(it->second->mutex);
        if (it->second->job_id != job.id || !it->second->progress.is_object()) continue;
        live = it->second->progress;
        if (it->second->done) {
          live["stage_name"] = "storing the result";
          live["eta_s"] = 0.0;
        }
      }
    }
    if (live.is_object()) (*j)["progress"].update(live);
  } else if (job.status == JobStatus::kSucceeded) {
    for (const json& row : store->Results(job.id, "warnings", {}, 0, 1000).rows) (*j)["warnings"].push_back(row.at("warning"));
  }
}

JobRecord Service::Impl::RequireJob(const std::string& id_text) {
  const int64_t id = ParseId(id_text);
  std::optional<JobRecord> job = store->GetJob(id);
  if (!job) throw HttpError{404, "unknown_job", "no job " + id_text, ""};
  return *job;
}

// A job's own wall-time limit held to the server's (serve --max-job-seconds, issue 15): a diagnose
// job's max_seconds or a fit's max_refinement_seconds above it is refused naming the field; a
// job without one gets min(its default, the cap). Jobs of other shapes are left to the
// schema check.
static void HoldToJobSeconds(json* job, double cap_s) {
  if (!job->is_object() || !job->contains("kind") || !(*job)["kind"].is_string()) return;
  const std::string kind = (*job)["kind"];
  const char* key = kind == "diagnose" ? "max_seconds" : kind == "fit" ? "max_refinement_seconds" : nullptr;
  if (key == nullptr) return;
  if (job->contains("options") && !(*job)["options"].is_object()) return;
  const std::string field = std::string("/options/") + key;
  if (job->contains("options") && (*job)["options"].contains(key)) {
    const json& given = (*job)["options"][key];
    if (given.is_number() && given.get<double>() > cap_s)
      throw HttpError{400, "invalid_job", "must be at most " + json(cap_s).dump() + " s on this server (serve --max-job-seconds)", field};
    return;
  }
  const double default_s = kind == "diagnose" ? 600 : 120;  // the schema's defaults
  if (cap_s < default_s) (*job)["options"][key] = cap_s;
}

void Service::Impl::AddJobRoutes() {
  On("POST", "/v1/jobs", Route(Role::kSubmit, [this](const httplib::Request& req, httplib::Response& res) {
              json job = JsonBody(req);
              HoldToJobSeconds(&job, options.max_job_seconds);
              // Validates; InputError -> 400 (a campaign's file and line: jobs::CampaignError).
              const std::vector<TaskSpec> tasks = jobs::PlanTasks(job, campaigns);
              const int64_t id = store->SubmitJob(job.at("kind"), job, tasks, NowMs());
              wake.notify_all();
              // Accepted as queued, unless every task was served from the store at once (a worker
              // may already have started it by the time this reply is written: still "queued" here).
              const std::optional<JobRecord> record = store->GetJob(id);
              const bool done = record && record->status == JobStatus::kSucceeded && record->tasks_done == record->tasks_total &&
                                record->started_ms == record->finished_ms;
              SendJson(res, {{"id", id}, {"status", done ? "succeeded" : "queued"}}, 201);
            }));
  On("GET", "/v1/jobs", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const int limit = QueryLimit(req, 50, 500);
             const int64_t before = req.has_param("before") ? QueryInteger(req, "before") : 0;
             json jobs = json::array();
             int64_t last = 0;
             for (const JobRecord& j : store->ListJobs(limit, before)) {
               json entry = JobJson(j);
               AddCampaignStatus(j, &entry);
               jobs.push_back(std::move(entry));
               last = j.id;
             }
             SendJson(res, {{"jobs", jobs},
                            {"next_before", static_cast<int>(jobs.size()) == limit ? json(last) : json(nullptr)}});
           }));
  On("GET", R"(/v1/jobs/(\d+))", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const JobRecord job = RequireJob(req.matches[1]);
             json detail = JobDetailJson(job);
             AddCampaignStatus(job, &detail);
             SendJson(res, detail);
           }));
  On("DELETE", R"(/v1/jobs/(\d+))", Route(Role::kSubmit, [this](const httplib::Request& req, httplib::Response& res) {
                const JobRecord job = RequireJob(req.matches[1]);
                if (!store->CancelJob(job.id, NowMs()))
                  throw HttpError{409, "already_finished", "job " + std::to_string(job.id) + " has already finished (" +
                                                              ToString(job.status) + ")", ""};
                {
                  std::lock_guard<std::mutex> lock(cancel_mutex);
                  auto [begin, end] = running.equal_range(job.id);
                  for (auto it = begin; it != end; ++it) *it->second = true;
                }
                SendJson(res, JobJson(*store->GetJob(job.id)));
              }));

  // Campaigns for fit and diagnose jobs (campaign_upload.h).
  On("POST", "/v1/campaigns", Route(Role::kSubmit, [this](const httplib::Request& req, httplib::Response& res) {
              const std::string type = req.get_header_value("Content-Type");
              const auto is = [&type](const char* media) { return type.rfind(media, 0) == 0; };
              if (!is("application/x-tar") && !is("application/zip") && !is("application/x-zip-compressed"))
                throw HttpError{415, "unsupported_media_type", UnsupportedCampaignMessage(type), ""};
              // The body's first bytes, not the type, choose the reader (campaign_upload.h).
              ArchiveLimits limits;  // the per-upload quota bounds what the members unpack to
              limits.max_file_bytes = limits.max_total_bytes = options.upload_quota_bytes;
              UploadedCampaign upload;
              try {
                upload = StoreUploadedCampaign(req.body, campaigns.uploads, limits, options.uploads_total_quota_bytes);
              } catch (const UploadQuotaError& e) {
                throw HttpError{507, "storage_quota", e.what(), "archive"};
              }
              SendJson(res, {{"campaign_id", upload.id}, {"campaign", CampaignSummary(upload.campaign)}}, 201);
            }));
}

}  // namespace strokelab::server
