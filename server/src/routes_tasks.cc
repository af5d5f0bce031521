// The remote workers' routes: lease a task, renew the lease, complete the task with its rows or fail it.
#include "service_impl.h"

#include "http_reply.h"
#include "now.h"
#include "request_params.h"
#include "strokelab/base/errors.h"
#include "strokelab/jobs/jobs.h"
#include "strokelab/jobs/task_rows.h"

namespace strokelab::server {

using nlohmann::json;
using namespace internal;

// Leases a task for a remote worker. A fit or diagnose task goes to a worker that fetches campaigns
// (GET /v1/campaigns/{sha256}, routes_campaigns.cc) when its spec names the campaign's hash. One
// drawn for a worker that cannot fetch it stays leased and waits in `handoff` for an in-process
// worker or the next remote worker that fetches campaigns (its lease expires after lease_ms if none
// comes, and it is queued again), and the next task is drawn. A task planned before campaign hashes
// existed is failed at once when there are no in-process workers, since no remote worker can run it.
std::optional<TaskLease> Service::Impl::LeaseForRemote(const std::string& worker, bool fetches_campaigns) {
  if (fetches_campaigns)
    if (std::optional<TaskLease> waiting = TakeHandoff(/*with_campaign_hash=*/true)) return waiting;
  for (;;) {
    std::optional<TaskLease> lease = store->LeaseTask(worker, NowMs(), options.lease_ms);
    if (!lease || !jobs::IsCampaignKind(lease->kind)) return lease;
    const bool hashed = lease->spec.contains("campaign_sha256");
    if (fetches_campaigns && hashed) return lease;
    if (local_workers == 0 && !hashed) {
      store->FailTask(*lease, lease->kind + " task planned before campaign downloads and no in-process workers (serve --workers 0): submit the job again", NowMs());
      continue;
    }
    {
      std::lock_guard<std::mutex> lock(handoff_mutex);
      std::erase_if(handoff, [&](const TaskLease& held) { return held.task_id == lease->task_id; });  // an expired wait
      handoff.push_back(*lease);
    }
    wake.notify_all();
  }
}

void Service::Impl::AddTaskRoutes() {
  On("POST", "/v1/tasks/lease", Route(Role::kWorker, [this](const httplib::Request& req, httplib::Response& res) {
              const json body = req.body.empty() ? json::object() : JsonBody(req);
              if (!body.is_object()) throw HttpError{400, "bad_request", "expected a JSON object", ""};
              if (body.contains("worker") && !body["worker"].is_string())
                throw HttpError{400, "bad_request", "expected a string", "/worker"};
              // Remote names are prefixed so that none can pass for this server's own "local-" workers,
              // whose leases are released at start.
              if (body.contains("fetches_campaigns") && !body["fetches_campaigns"].is_boolean())
                throw HttpError{400, "bad_request", "expected true or false", "/fetches_campaigns"};
              const std::optional<TaskLease> lease = LeaseForRemote("remote:" + body.value("worker", std::string("unnamed")),
                                                                    body.value("fetches_campaigns", false));
              if (!lease) {
                res.status = 204;
                return;
              }
              json spec = lease->spec;
              spec.erase("campaign_dir");  // the server's own path: the worker fetches the campaign by hash
              SendJson(res, {{"task_id", lease->task_id}, {"job_id", lease->job_id}, {"index", lease->index},
                             {"kind", lease->kind}, {"spec", spec}, {"lease_token", lease->lease_token},
                             {"expires_ms", lease->expires_ms}, {"lease_ms", options.lease_ms}});
            }));
  // A remote worker keeps its lease while a long task runs (remote_worker.cc renews every lease_ms / 4).
  On("POST", R"(/v1/tasks/(\d+)/renew)", Route(Role::kWorker, [this](const httplib::Request& req, httplib::Response& res) {
       const TaskLease lease = LeaseOf(req, JsonBody(req));
       if (!store->RenewLease(lease, NowMs(), options.lease_ms))
         throw HttpError{409, "lease_lost", "the lease expired or the job was cancelled", ""};
       SendJson(res, {{"renewed", true}, {"lease_ms", options.lease_ms}});
     }));
  On("POST", R"(/v1/tasks/(\d+)/complete)",
            Route(Role::kWorker, [this](const httplib::Request& req, httplib::Response& res) {
              json body = JsonBody(req);
              const TaskLease lease = LeaseOf(req, body);
              const auto rows_at = body.find("rows");
              if (rows_at == body.end() || !rows_at->is_array())
                throw HttpError{400, "bad_request", "expected an array of rows", "/rows"};
              json& given = *rows_at;
              for (size_t i = 0; i < given.size(); ++i) {  // the shape, before anything is copied
                const std::string at = "/rows/" + std::to_string(i);
                CheckBodyField(given[i], "table", json::value_t::string, at + "/table");
                CheckBodyField(given[i], "values", json::value_t::object, at + "/values");
              }
              // The lease before the rows: a completion without one writes nothing, whatever it carries.
              const std::optional<json> task = store->LeasedTaskSpec(lease, NowMs());
              if (!task) throw HttpError{409, "lease_lost", "the lease expired or the job was cancelled; nothing written", ""};
              std::vector<ResultRow> rows;
              for (json& row : given) rows.push_back({row["table"].get<std::string>(), std::move(row["values"])});
              try {  // what is stored here is also served from the cache to identical jobs
                if (jobs::IsCampaignKind(task->at("type")))  // a diagnosis as data; its report rendered here
                  rows = jobs::CampaignRowsFromWorker(*task, std::move(rows));
                else
                  jobs::ValidateTaskRows(*task, rows);
              } catch (const InputError& e) {
                throw HttpError{400, "invalid_rows", e.bare_message(), e.field()};
              }
              const size_t row_count = rows.size();
              if (!store->CompleteTask(lease, std::move(rows), NowMs()))
                throw HttpError{409, "lease_lost", "the lease expired or the job was cancelled; nothing written", ""};
              metrics.TaskDone(row_count);
              SendJson(res, {{"accepted", true}});
            }));
  On("POST", R"(/v1/tasks/(\d+)/fail)", Route(Role::kWorker, [this](const httplib::Request& req, httplib::Response& res) {
              const json body = JsonBody(req);
              const TaskLease lease = LeaseOf(req, body);
              const std::string error =
                  body.contains("error") ? BodyField<std::string>(body, "error", "/error") : "worker failure";
              // "budget": true, a spent work budget (WorkBudgetSpent): the task is retried once.
              if (body.contains("budget") && BodyField<bool>(body, "budget", "/budget"))
                store->FailTaskOnBudget(lease, error, NowMs());
              else
                store->FailTask(lease, error, NowMs());
              SendJson(res, {{"accepted", true}});
            }));
}

}  // namespace strokelab::server
