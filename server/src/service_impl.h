// The service's state, shared by its parts: the routes (service.cc sets up the server, routes_*.cc
// add each group of routes) and the in-process workers (local_workers.cc). Internal to the service.
#pragma once

#include <httplib.h>

#include <atomic>
#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "http_gate.h"
#include "metrics.h"
#include "storage_health.h"
#include "strokelab/base/progress.h"
#include "strokelab/jobs/campaigns.h"
#include "strokelab/server/auth.h"
#include "strokelab/server/service.h"
#include "strokelab/server/store.h"
#include "strokelab/sweep/sweep.h"

namespace strokelab::server {

// A job as the service shows it (lists, cancel replies): id, kind, name, status, progress, times.
nlohmann::json JobJson(const JobRecord& job);
// One job in full (GET /v1/jobs/{id}, the saturation map's "job"): JobJson plus "spec" (as submitted)
// and "resolved" (jobs::ResolvedJob: the model with every parameter, the grid's axes with their
// values, the options with their defaults).
nlohmann::json JobDetailJson(const JobRecord& job);
// A fit or diagnose task's progress as a job's "progress" adds it: stage, stages, stage_name, step,
// elapsed_s, eta_s (an estimate; null until one stage has finished).
nlohmann::json StageProgressJson(const ProgressReport& report);

struct Service::Impl {
  ServiceOptions options;
  std::unique_ptr<Store> store;
  TokenTable tokens;
  internal::GatedServer http;  // cpp-httplib behind a gate for slow clients (http_gate.h)
  internal::Metrics metrics;
  std::vector<std::thread> workers;
  std::thread http_thread;
  std::atomic<bool> http_ended{false};  // listen_after_bind has returned
  std::atomic<bool> stopping{false};
  std::mutex wake_mutex;
  std::condition_variable wake;
  // Cancel flags of the tasks running in this process, by job.
  std::mutex cancel_mutex;
  std::multimap<int64_t, std::shared_ptr<std::atomic<bool>>> running;
  int port = 0;
  internal::StorageHealth storage;  // whether writes work, for /v1/health
  int local_workers = 0;  // in-process workers, set by Start before the HTTP thread
  jobs::CampaignDirs campaigns;
  // Fit and diagnose tasks that a remote lease request drew for a worker that cannot fetch campaigns:
  // kept under that lease for an in-process worker or a remote one that can (LeaseForRemote).
  std::mutex handoff_mutex;
  std::deque<TaskLease> handoff;
  // Every task's computation on a thread of its own (RunHeldTask), ended by its cancel flag; joined
  // when the service stops.
  struct Computation {
    int64_t job_id = 0;
    std::mutex mutex;
    std::condition_variable done_cv;
    nlohmann::json progress;  // the latest StageProgressJson (null before the first stage)
    bool done = false;
    TaskResult result;
    std::exception_ptr error;
  };
  std::mutex computations_mutex;
  std::vector<std::pair<std::thread, std::shared_ptr<Computation>>> computations;

  void Authorize(const httplib::Request& req, Role required);

  // A route's handler with the role it needs (Route); routes without one are open (page, health).
  struct RoutedHandler {
    Role role;
    httplib::Server::Handler handler;
  };
  // Every route: its path pattern, method, role and body limit, checked on the headers before any
  // body is read (RefuseBeforeBody); a known path with another method is answered 405 with Allow.
  struct RouteEntry {
    std::regex pattern;
    std::string method;
    std::optional<Role> role;
    size_t max_body_bytes;  // 0: no body
  };
  std::vector<RouteEntry> routes;

  // Registers a route (httplib matches the whole path against the pattern, as std::regex_match). A
  // POST route reads its body itself, within its limit (a chunked body too), before the handler.
  void On(const std::string& method, const std::string& pattern, RoutedHandler routed);
  void On(const std::string& method, const std::string& pattern, httplib::Server::Handler open);
  void Register(const std::string& method, const std::string& pattern, std::optional<Role> role,
                httplib::Server::Handler handler);

  // The methods routed for `path` ("GET, DELETE"); empty when no route matches it.
  std::string AllowedMethods(const std::string& path) const;

  // Wraps a handler with error mapping, metrics and the storage health; the role is checked before.
  RoutedHandler Route(Role required, std::function<void(const httplib::Request&, httplib::Response&)> h);

  // The pre-routing check, on the headers alone: the route (404, 405), the token (401, 403), the
  // body's encoding and length against the route's limit (415, 413). A refusal whose body may
  // follow closes the connection, so the body is never read.
  httplib::Server::HandlerResponse RefuseBeforeBody(const httplib::Request& req, httplib::Response& res);

  // `text` with the server's own directories (uploads, data root, database) replaced by names, so
  // that error messages and job errors do not show the server's file system.
  std::string WithoutServerPaths(std::string text) const;

  // Adds to a job's JSON (JobJson) what the store's job row does not hold: a running fit or diagnose
  // job's stage progress (from its computation in this process) and a finished one's warnings (its
  // result rows of table "warnings"; jobs.h).
  void AddCampaignStatus(const JobRecord& job, nlohmann::json* job_json);

  // The job of a path's id (404 when there is none).
  JobRecord RequireJob(const std::string& id_text);

  // A sweep job's stored saturation thresholds, in order of frequency.
  std::vector<nlohmann::json> ThresholdRows(const JobRecord& job);

  // The stored results of a sweep job as a SweepResult (for the pictures).
  SweepResult SweepResultOf(const JobRecord& job);

  // A finished fit or diagnose job's stored rows of `table` (409 while it is not finished).
  std::vector<nlohmann::json> CampaignJobRows(const JobRecord& job, const std::string& table);

  // The routes: the server's own (service.cc), then each group's (routes_*.cc).
  void SetUpRoutes();
  void AddJobRoutes();
  void AddResultRoutes();
  void AddTaskRoutes();
  void AddCampaignRoutes();  // routes_campaigns.cc: a leased task's campaign for its remote worker

  // Remote and in-process workers (routes_tasks.cc, local_workers.cc).
  std::optional<TaskLease> LeaseForRemote(const std::string& worker, bool fetches_campaigns);
  std::optional<TaskLease> TakeHandoff(bool with_campaign_hash);
  std::optional<TaskResult> RunHeldTask(const TaskLease& lease,
                                        const std::shared_ptr<std::atomic<bool>>& cancel);
  void WorkLoop(int index);

  // Stores a task's rows. A storage error (disk full, I/O) is not the task's fault: the rows are
  // kept and the write retried every second until it succeeds, the lease is lost (false), or the
  // service stops (false; the lease is released at the next start), instead of failing the job.
  bool StoreCompletion(const TaskLease& lease, const TaskResult& result, const std::string& worker);
};

}  // namespace strokelab::server
