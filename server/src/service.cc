#include "strokelab/server/service.h"

#include <httplib.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <map>
#include <mutex>
#include <thread>

#include "strokelab/errors.h"
#include "strokelab/parse.h"
#include "strokelab/server/auth.h"
#include "strokelab/server/job_spec.h"
#include "strokelab/server/jobs.h"
#include "strokelab/server/store.h"
#include "strokelab/server/web_page.h"
#include "strokelab/sweep.h"
#include "strokelab/sweep_report.h"

namespace strokelab::server {
namespace {

using nlohmann::json;

int64_t NowMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// An error that ends a request, turned into {"error": {"code", "message", "field"}} with a status.
struct HttpError {
  int status;
  std::string code, message, field;
};

void SendError(httplib::Response& res, const HttpError& e) {
  json body = {{"error", {{"code", e.code}, {"message", e.message}}}};
  if (!e.field.empty()) body["error"]["field"] = e.field;
  res.status = e.status;
  res.set_content(body.dump(), "application/json");
}

void SendJson(httplib::Response& res, const json& body, int status = 200) {
  res.status = status;
  res.set_content(body.dump(), "application/json");
}

// Request latency histogram and counters for /metrics.
class Metrics {
 public:
  static constexpr double kBuckets[] = {0.001, 0.005, 0.01, 0.05, 0.1, 0.5, 1.0, 5.0};
  void ObserveRequest(double seconds) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++requests_;
    latency_sum_ += seconds;
    for (size_t i = 0; i < std::size(kBuckets); ++i)
      if (seconds <= kBuckets[i]) ++latency_buckets_[i];
  }
  void TaskDone(size_t rows) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++tasks_done_;
    rows_written_ += rows;
    const int64_t now = NowMs();
    // Tasks per second, an exponentially weighted average over ~10 s.
    if (last_task_ms_ > 0) {
      const double dt = std::max(1e-3, (now - last_task_ms_) / 1000.0);
      const double w = std::exp(-dt / 10.0);
      tasks_per_second_ = w * tasks_per_second_ + (1 - w) / dt;
    }
    last_task_ms_ = now;
  }
  std::string Text(const Store::Counts& counts) const {
    std::lock_guard<std::mutex> lock(mutex_);
    std::string out;
    char line[1024];
    out += "# HELP strokelab_jobs Jobs by state.\n# TYPE strokelab_jobs gauge\n";
    const char* states[] = {"queued", "running", "succeeded", "failed", "cancelled"};
    for (int i = 0; i < 5; ++i) {
      std::snprintf(line, sizeof line, "strokelab_jobs{state=\"%s\"} %lld\n", states[i],
                    static_cast<long long>(counts.jobs[i]));
      out += line;
    }
    std::snprintf(line, sizeof line,
                  "# HELP strokelab_queue_depth Tasks waiting for a worker.\n# TYPE strokelab_queue_depth gauge\n"
                  "strokelab_queue_depth %lld\n"
                  "# HELP strokelab_tasks_leased Tasks being worked on.\n# TYPE strokelab_tasks_leased gauge\n"
                  "strokelab_tasks_leased %lld\n",
                  static_cast<long long>(counts.tasks_queued), static_cast<long long>(counts.tasks_leased));
    out += line;
    std::snprintf(line, sizeof line,
                  "# HELP strokelab_tasks_completed_total Tasks completed by this process.\n"
                  "# TYPE strokelab_tasks_completed_total counter\nstrokelab_tasks_completed_total %llu\n"
                  "# HELP strokelab_tasks_per_second Recent task completion rate.\n"
                  "# TYPE strokelab_tasks_per_second gauge\nstrokelab_tasks_per_second %.6g\n"
                  "# HELP strokelab_result_rows_written_total Result rows written to SQLite.\n"
                  "# TYPE strokelab_result_rows_written_total counter\nstrokelab_result_rows_written_total %llu\n",
                  static_cast<unsigned long long>(tasks_done_), tasks_per_second_,
                  static_cast<unsigned long long>(rows_written_));
    out += line;
    out += "# HELP strokelab_request_duration_seconds Request latency.\n"
           "# TYPE strokelab_request_duration_seconds histogram\n";
    for (size_t i = 0; i < std::size(kBuckets); ++i) {
      std::snprintf(line, sizeof line, "strokelab_request_duration_seconds_bucket{le=\"%g\"} %llu\n", kBuckets[i],
                    static_cast<unsigned long long>(latency_buckets_[i]));
      out += line;
    }
    std::snprintf(line, sizeof line,
                  "strokelab_request_duration_seconds_bucket{le=\"+Inf\"} %llu\n"
                  "strokelab_request_duration_seconds_sum %.6f\nstrokelab_request_duration_seconds_count %llu\n",
                  static_cast<unsigned long long>(requests_), latency_sum_,
                  static_cast<unsigned long long>(requests_));
    out += line;
    return out;
  }

 private:
  mutable std::mutex mutex_;
  uint64_t requests_ = 0, latency_buckets_[std::size(kBuckets)] = {}, tasks_done_ = 0, rows_written_ = 0;
  double latency_sum_ = 0, tasks_per_second_ = 0;
  int64_t last_task_ms_ = 0;
};

json JobJson(const JobRecord& job) {
  json j = {{"id", job.id},
            {"kind", job.kind},
            {"status", ToString(job.status)},
            {"progress", {{"done", job.tasks_done}, {"total", job.tasks_total}}},
            {"created_ms", job.created_ms},
            {"started_ms", job.started_ms ? json(job.started_ms) : json(nullptr)},
            {"finished_ms", job.finished_ms ? json(job.finished_ms) : json(nullptr)}};
  if (job.spec.contains("name")) j["name"] = job.spec["name"];
  if (job.started_ms) j["elapsed_s"] = ((job.finished_ms ? job.finished_ms : NowMs()) - job.started_ms) / 1000.0;
  if (!job.error.empty()) j["error"] = job.error;
  return j;
}

int64_t ParseId(const std::string& text) {
  try {
    return std::stoll(text);
  } catch (...) {
    throw HttpError{404, "unknown_job", "no job " + text, ""};
  }
}

double QueryNumber(const httplib::Request& req, const std::string& name) {
  try {
    return ParseNumber(req.get_param_value(name), name);
  } catch (const InputError& e) {
    throw HttpError{400, "bad_query", e.bare_message(), name};
  }
}

int QueryLimit(const httplib::Request& req, int fallback, int maximum) {
  if (!req.has_param("limit")) return fallback;
  const double limit = QueryNumber(req, "limit");
  if (limit < 1 || limit > maximum || limit != std::floor(limit))
    throw HttpError{400, "bad_query", "must be an integer from 1 to " + std::to_string(maximum), "limit"};
  return static_cast<int>(limit);
}

const std::vector<std::string> kPointColumns = {
    "frequency_hz",       "amplitude_v",        "branch",       "stable",           "period",
    "first_harmonic_force_n", "first_harmonic_phase_rad", "h_re", "h_im",          "min_displacement_m",
    "max_displacement_m", "peak_force_n",       "contacts_per_period", "max_multiplier"};

std::string PointsCsv(const std::vector<json>& rows) {
  std::string out;
  for (size_t i = 0; i < kPointColumns.size(); ++i) out += (i ? "," : "") + kPointColumns[i];
  out += "\n";
  for (const json& row : rows) {
    for (size_t i = 0; i < kPointColumns.size(); ++i) {
      if (i) out += ",";
      const json& v = row.value(kPointColumns[i], json(nullptr));
      if (v.is_string()) out += v.get<std::string>();
      else if (v.is_boolean()) out += v.get<bool>() ? "1" : "0";
      else if (!v.is_null()) out += v.dump();
    }
    out += "\n";
  }
  return out;
}

}  // namespace

struct Service::Impl {
  ServiceOptions options;
  std::unique_ptr<Store> store;
  TokenTable tokens;
  httplib::Server http;
  Metrics metrics;
  std::vector<std::thread> workers;
  std::thread http_thread;
  std::atomic<bool> stopping{false};
  std::mutex wake_mutex;
  std::condition_variable wake;
  // Cancel flags of the tasks running in this process, by job.
  std::mutex cancel_mutex;
  std::multimap<int64_t, std::shared_ptr<std::atomic<bool>>> running;
  int port = 0;

  void Authorize(const httplib::Request& req, Role required) {
    if (!tokens.enabled()) return;
    const std::string header = req.get_header_value("Authorization");
    const std::string prefix = "Bearer ";
    if (header.rfind(prefix, 0) != 0)
      throw HttpError{401, "unauthorized", "missing bearer token (Authorization: Bearer TOKEN)", ""};
    const std::optional<Role> role = tokens.Lookup(header.substr(prefix.size()));
    if (!role) throw HttpError{401, "unauthorized", "unknown token", ""};
    if (!TokenTable::Allows(*role, required))
      throw HttpError{403, "forbidden",
                      required == Role::kWorker ? "this token may not lease tasks (needs a worker or submit token)"
                                                : "this token may not do that (needs a submit token)",
                      ""};
  }

  // Wraps a handler with authorisation, error mapping, metrics and the access log.
  httplib::Server::Handler Route(Role required, std::function<void(const httplib::Request&, httplib::Response&)> h) {
    return [this, required, h](const httplib::Request& req, httplib::Response& res) {
      const auto start = std::chrono::steady_clock::now();
      try {
        Authorize(req, required);
        h(req, res);
      } catch (const HttpError& e) {
        SendError(res, e);
      } catch (const JobLimitError& e) {
        SendError(res, {400, "job_too_large", e.bare_message(), e.field()});
      } catch (const InputError& e) {
        SendError(res, {400, "invalid_job", e.bare_message(), e.field()});
      } catch (const json::exception& e) {
        SendError(res, {400, "bad_json", std::string("request body is not valid JSON: ") + e.what(), ""});
      } catch (const std::exception& e) {
        SendError(res, {500, "internal", e.what(), ""});
      }
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      metrics.ObserveRequest(seconds);
      if (!options.quiet) {
        const json line = {{"ts_ms", NowMs()}, {"method", req.method}, {"path", req.path},
                           {"status", res.status}, {"ms", seconds * 1e3}};
        std::fprintf(stderr, "%s\n", line.dump().c_str());
      }
    };
  }

  JobRecord RequireJob(const std::string& id_text) {
    const int64_t id = ParseId(id_text);
    std::optional<JobRecord> job = store->GetJob(id);
    if (!job) throw HttpError{404, "unknown_job", "no job " + id_text, ""};
    return *job;
  }

  // The stored results of a sweep job as a SweepResult (for the pictures).
  SweepResult SweepResultOf(const JobRecord& job) {
    SweepResult r;
    const SweepSpec spec = SweepSpecFromJob(job.spec);
    r.frequency_hz = spec.frequency_hz.Values();
    r.amplitude_v = spec.amplitude_v.Values();
    for (int64_t cursor = 0;;) {
      const Store::Page page = store->Results(job.id, "points", {}, cursor, 10000);
      for (const json& p : page.rows) {
        SweepPoint s;
        s.frequency_hz = p.at("frequency_hz");
        s.amplitude_v = p.at("amplitude_v");
        const std::string branch = p.at("branch");
        s.branch = branch == "up" ? Branch::kUp : (branch == "down" ? Branch::kDown : Branch::kUnstable);
        s.stable = p.at("stable");
        s.period = p.at("period").is_number() ? p.at("period").get<int>() : 0;
        s.h = {p.at("h_re").get<double>(), p.at("h_im").get<double>()};
        s.first_harmonic_force_n = p.at("first_harmonic_force_n");
        s.first_harmonic_phase_rad = p.at("first_harmonic_phase_rad");
        s.min_displacement_m = p.at("min_displacement_m");
        s.max_displacement_m = p.at("max_displacement_m");
        s.peak_force_n = p.at("peak_force_n");
        s.contacts_per_period = p.at("contacts_per_period");
        s.max_multiplier = p.at("max_multiplier");
        r.points.push_back(s);
      }
      if (page.next_cursor == 0) break;
      cursor = page.next_cursor;
    }
    for (const json& t : store->Results(job.id, "thresholds", {}, 0, 1000000).rows)
      r.saturation_threshold.push_back({t.at("frequency_hz"), t.at("grazing_amplitude_v").is_number()
                                                                  ? t.at("grazing_amplitude_v").get<double>()
                                                                  : NAN,
                                        t.at("lowest_contact_amplitude_v").is_number()
                                            ? t.at("lowest_contact_amplitude_v").get<double>()
                                            : NAN});
    std::sort(r.saturation_threshold.begin(), r.saturation_threshold.end(),
              [](const auto& a, const auto& b) { return a.frequency_hz < b.frequency_hz; });
    for (const json& j : store->Results(job.id, "jumps", {}, 0, 1000000).rows)
      r.jump.push_back({j.at("amplitude_v"), j.at("bistable_from_hz"), j.at("bistable_to_hz"), j.at("from_kind"),
                        j.at("to_kind")});
    return r;
  }

  void SetUpRoutes();
  void WorkLoop(int index);
};

void Service::Impl::SetUpRoutes() {
  http.set_payload_max_length(options.max_body_bytes);
  // Without TCP_NODELAY a keep-alive response written in two parts (headers, body) waits for the
  // client's delayed ACK: ~40 ms per request after the first on a connection (~90 instead of
  // ~15,000 GET /v1/jobs/{id} per second on loopback; tests/bench/service_load).
  http.set_tcp_nodelay(true);
  http.set_error_handler([](const httplib::Request&, httplib::Response& res) {
    if (!res.body.empty()) return;
    if (res.status == 413) SendError(res, {413, "body_too_large", "request body exceeds the limit", ""});
    else if (res.status == 404) SendError(res, {404, "not_found", "no such endpoint", ""});
    else if (res.status == 400) SendError(res, {400, "bad_request", "malformed HTTP request (e.g. a POST without Content-Length)", ""});
    else if (res.status >= 400) SendError(res, {res.status, "http_error", "HTTP error " + std::to_string(res.status), ""});
  });

  http.Get("/", [](const httplib::Request&, httplib::Response& res) { res.set_content(WebPage(), "text/html"); });
  // Health is open (load balancers and probes carry no token) and says nothing about jobs.
  http.Get("/v1/health", [this](const httplib::Request&, httplib::Response& res) {
    SendJson(res, {{"status", "ok"}, {"schema_version", store->SchemaVersion()}, {"code_version", kCodeVersion}});
  });
  http.Get("/metrics", Route(Role::kRead, [this](const httplib::Request&, httplib::Response& res) {
             res.set_content(metrics.Text(store->GetCounts(NowMs())), "text/plain; version=0.0.4");
           }));

  http.Post("/v1/jobs", Route(Role::kSubmit, [this](const httplib::Request& req, httplib::Response& res) {
              json job;
              try {
                job = json::parse(req.body);
              } catch (const json::parse_error& e) {
                throw HttpError{400, "bad_json", std::string("request body is not valid JSON: ") + e.what(), ""};
              }
              const std::vector<TaskSpec> tasks = PlanTasks(job);  // validates; InputError -> 400
              const int64_t id = store->SubmitJob(job.at("kind"), job, tasks, NowMs());
              wake.notify_all();
              // Accepted as queued, unless every task was served from the store at once (a worker
              // may already have started it by the time this reply is written: still "queued" here).
              const std::optional<JobRecord> record = store->GetJob(id);
              const bool done = record && record->status == JobStatus::kSucceeded && record->tasks_done == record->tasks_total &&
                                record->started_ms == record->finished_ms;
              SendJson(res, {{"id", id}, {"status", done ? "succeeded" : "queued"}}, 201);
            }));
  http.Get("/v1/jobs", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const int limit = QueryLimit(req, 50, 500);
             const int64_t before = req.has_param("before") ? static_cast<int64_t>(QueryNumber(req, "before")) : 0;
             json jobs = json::array();
             int64_t last = 0;
             for (const JobRecord& j : store->ListJobs(limit, before)) {
               jobs.push_back(JobJson(j));
               last = j.id;
             }
             SendJson(res, {{"jobs", jobs},
                            {"next_before", static_cast<int>(jobs.size()) == limit ? json(last) : json(nullptr)}});
           }));
  http.Get(R"(/v1/jobs/(\d+))", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             SendJson(res, JobJson(RequireJob(req.matches[1])));
           }));
  http.Delete(R"(/v1/jobs/(\d+))", Route(Role::kSubmit, [this](const httplib::Request& req, httplib::Response& res) {
                const JobRecord job = RequireJob(req.matches[1]);
                if (!store->CancelJob(job.id, NowMs()))
                  throw HttpError{409, "already_finished", "job " + std::to_string(job.id) + " has already " +
                                                              ToString(job.status), ""};
                {
                  std::lock_guard<std::mutex> lock(cancel_mutex);
                  auto [begin, end] = running.equal_range(job.id);
                  for (auto it = begin; it != end; ++it) *it->second = true;
                }
                SendJson(res, JobJson(*store->GetJob(job.id)));
              }));
  http.Get(R"(/v1/jobs/(\d+)/points)", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const JobRecord job = RequireJob(req.matches[1]);
             Store::Filter filter;
             if (req.has_param("frequency_min_hz")) filter.frequency_min_hz = QueryNumber(req, "frequency_min_hz");
             if (req.has_param("frequency_max_hz")) filter.frequency_max_hz = QueryNumber(req, "frequency_max_hz");
             if (req.has_param("amplitude_v")) filter.amplitude_v = QueryNumber(req, "amplitude_v");
             if (req.has_param("branch")) {
               const std::string b = req.get_param_value("branch");
               if (b != "up" && b != "down" && b != "unstable")
                 throw HttpError{400, "bad_query", "must be up, down or unstable", "branch"};
               filter.branch = b;
             }
             const int limit = QueryLimit(req, 1000, 10000);
             const int64_t cursor = req.has_param("cursor") ? static_cast<int64_t>(QueryNumber(req, "cursor")) : 0;
             const Store::Page page = store->Results(job.id, "points", filter, cursor, limit);
             if (req.get_header_value("Accept").find("text/csv") != std::string::npos) {
               res.set_header("X-Next-Cursor", std::to_string(page.next_cursor));
               res.set_content(PointsCsv(page.rows), "text/csv");
               return;
             }
             SendJson(res, {{"points", page.rows},
                            {"next_cursor", page.next_cursor ? json(page.next_cursor) : json(nullptr)}});
           }));
  http.Get(R"(/v1/jobs/(\d+)/saturation-map)",
           Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const JobRecord job = RequireJob(req.matches[1]);
             if (job.kind != "sweep") throw HttpError{400, "not_a_sweep", "only sweep jobs have a saturation map", ""};
             if (req.get_param_value("format") == "svg") {
               res.set_content(report::SaturationMapSvg(SweepResultOf(job), Branch::kUp), "image/svg+xml");
               return;
             }
             json thresholds = store->Results(job.id, "thresholds", {}, 0, 1000000).rows;
             std::sort(thresholds.begin(), thresholds.end(),
                       [](const json& a, const json& b) { return a["frequency_hz"] < b["frequency_hz"]; });
             SendJson(res, {{"job", JobJson(job)},
                            {"saturation_threshold", thresholds},
                            {"jump", store->Results(job.id, "jumps", {}, 0, 1000000).rows}});
           }));
  http.Get(R"(/v1/jobs/(\d+)/frf)", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const JobRecord job = RequireJob(req.matches[1]);
             if (job.kind != "sweep") throw HttpError{400, "not_a_sweep", "only sweep jobs have FRFs", ""};
             if (req.get_param_value("format") == "svg") {
               const std::string branch = req.has_param("branch") ? req.get_param_value("branch") : "up";
               res.set_content(report::FrfMagnitudeSvg(SweepResultOf(job), branch == "down" ? Branch::kDown : Branch::kUp),
                               "image/svg+xml");
               return;
             }
             if (!req.has_param("amplitude_v"))
               throw HttpError{400, "bad_query", "is required (one of the job's amplitudes)", "amplitude_v"};
             Store::Filter filter;
             filter.amplitude_v = QueryNumber(req, "amplitude_v");
             json branches = {{"up", json::array()}, {"down", json::array()}, {"unstable", json::array()}};
             for (const json& p : store->Results(job.id, "points", filter, 0, 1000000).rows)
               branches[p.at("branch").get<std::string>()].push_back(
                   {{"frequency_hz", p["frequency_hz"]}, {"h_re", p["h_re"]}, {"h_im", p["h_im"]},
                    {"magnitude_n_per_v", std::hypot(p["h_re"].get<double>(), p["h_im"].get<double>())}});
             SendJson(res, {{"amplitude_v", *filter.amplitude_v}, {"branches", branches}});
           }));

  // Remote workers.
  http.Post("/v1/tasks/lease", Route(Role::kWorker, [this](const httplib::Request& req, httplib::Response& res) {
              const json body = req.body.empty() ? json::object() : json::parse(req.body);
              // Remote names are prefixed so that none can pass for this server's own "local-" workers,
              // whose leases are released at start.
              const std::optional<TaskLease> lease = store->LeaseTask(
                  "remote:" + body.value("worker", std::string("unnamed")), NowMs(), options.lease_ms);
              if (!lease) {
                res.status = 204;
                return;
              }
              SendJson(res, {{"task_id", lease->task_id}, {"job_id", lease->job_id}, {"index", lease->index},
                             {"kind", lease->kind}, {"spec", lease->spec}, {"lease_token", lease->lease_token},
                             {"expires_ms", lease->expires_ms}});
            }));
  http.Post(R"(/v1/tasks/(\d+)/complete)",
            Route(Role::kWorker, [this](const httplib::Request& req, httplib::Response& res) {
              const json body = json::parse(req.body);
              TaskLease lease;
              lease.task_id = std::stoll(req.matches[1]);
              lease.job_id = body.at("job_id");
              lease.lease_token = body.at("lease_token");
              std::vector<ResultRow> rows;
              for (const json& r : body.at("rows")) rows.push_back({r.at("table"), r.at("values")});
              if (!store->CompleteTask(lease, rows, NowMs()))
                throw HttpError{409, "lease_lost", "the lease expired or the job was cancelled; nothing written", ""};
              metrics.TaskDone(rows.size());
              SendJson(res, {{"accepted", true}});
            }));
  http.Post(R"(/v1/tasks/(\d+)/fail)", Route(Role::kWorker, [this](const httplib::Request& req, httplib::Response& res) {
              const json body = json::parse(req.body);
              TaskLease lease;
              lease.task_id = std::stoll(req.matches[1]);
              lease.job_id = body.at("job_id");
              lease.lease_token = body.at("lease_token");
              store->FailTask(lease, body.value("error", std::string("worker failure")), NowMs());
              SendJson(res, {{"accepted", true}});
            }));
}

void Service::Impl::WorkLoop(int index) {
  const std::string name = "local-" + std::to_string(index);
  while (!stopping) {
    std::optional<TaskLease> lease;
    try {
      lease = store->LeaseTask(name, NowMs(), options.lease_ms);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s\n", json({{"worker", name}, {"error", e.what()}}).dump().c_str());
    }
    if (!lease) {
      std::unique_lock<std::mutex> lock(wake_mutex);
      wake.wait_for(lock, std::chrono::milliseconds(200));
      continue;
    }
    auto cancel = std::make_shared<std::atomic<bool>>(false);
    {
      std::lock_guard<std::mutex> lock(cancel_mutex);
      running.emplace(lease->job_id, cancel);
    }
    try {
      const std::vector<ResultRow> rows = RunTask(lease->spec, cancel.get());
      if (store->CompleteTask(*lease, rows, NowMs())) metrics.TaskDone(rows.size());
    } catch (const Cancelled&) {
      // The job was cancelled: its lease is void and nothing is written.
    } catch (const std::exception& e) {
      try {
        store->FailTask(*lease, e.what(), NowMs());
      } catch (const std::exception& inner) {
        std::fprintf(stderr, "%s\n", json({{"worker", name}, {"error", inner.what()}}).dump().c_str());
      }
    }
    std::lock_guard<std::mutex> lock(cancel_mutex);
    for (auto it = running.begin(); it != running.end(); ++it) {
      if (it->second == cancel) {
        running.erase(it);
        break;
      }
    }
  }
}

Service::Service(const ServiceOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  impl_->store = Store::Open(options.db_path);
  if (!options.token_file.empty()) impl_->tokens = TokenTable::Load(options.token_file);
  impl_->SetUpRoutes();
}

Service::~Service() { Stop(); }

int Service::Start() {
  Impl& s = *impl_;
  const int released = s.store->ReleaseLeases("local-");
  if (released > 0 && !s.options.quiet)
    std::fprintf(stderr, "%s\n", json({{"event", "resume"}, {"released_leases", released}}).dump().c_str());
  if (s.options.port == 0) {
    s.port = s.http.bind_to_any_port(s.options.host);
    if (s.port <= 0) throw std::runtime_error("cannot bind " + s.options.host);
  } else {
    if (!s.http.bind_to_port(s.options.host, s.options.port))
      throw std::runtime_error("cannot bind " + s.options.host + ":" + std::to_string(s.options.port) +
                               " (in use? try another --port)");
    s.port = s.options.port;
  }
  s.http_thread = std::thread([&s] { s.http.listen_after_bind(); });
  const int workers = s.options.workers < 0 ? static_cast<int>(std::max(1u, std::thread::hardware_concurrency()))
                                            : s.options.workers;
  for (int i = 0; i < workers; ++i) s.workers.emplace_back([&s, i] { s.WorkLoop(i); });
  return s.port;
}

void Service::Wait() {
  if (impl_->http_thread.joinable()) impl_->http_thread.join();
}

void Service::Stop() {
  Impl& s = *impl_;
  if (s.stopping.exchange(true)) return;
  s.http.stop();
  s.wake.notify_all();
  for (std::thread& t : s.workers) t.join();  // each finishes (and stores) the task it holds
  if (s.http_thread.joinable()) s.http_thread.join();
}

}  // namespace strokelab::server
