#include "strokelab/server/service.h"

#include <httplib.h>
#include <sys/socket.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <exception>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <regex>
#include <thread>
#include <type_traits>

#include "campaign_upload.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/parse.h"
#include "strokelab/server/auth.h"
#include "strokelab/jobs/job_spec.h"
#include "strokelab/jobs/jobs.h"
#include "strokelab/server/store.h"
#include "strokelab/server/web_page.h"
#include "storage_health.h"
#include "strokelab/sweep/sweep.h"
#include "strokelab/report/sweep_report.h"
#include "strokelab/report/sweep_tables.h"
#include "event_log.h"

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
  // Messages may quote what the client sent, which need not be UTF-8.
  res.set_content(body.dump(-1, ' ', false, json::error_handler_t::replace), "application/json");
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

// A finite number: an infinite filter or limit is a client's mistake, never a useful query.
double QueryNumber(const httplib::Request& req, const std::string& name) {
  double value = 0;
  try {
    value = ParseNumber(req.get_param_value(name), name);
  } catch (const InputError& e) {
    throw HttpError{400, "bad_query", e.bare_message(), name};
  }
  if (!std::isfinite(value)) throw HttpError{400, "bad_query", "must be a finite number", name};
  return value;
}

// A cursor or job id bound: digits only, parsed as an integer (a double would round cursors above
// 2^53 and casting one beyond int64 is undefined).
int64_t QueryInteger(const httplib::Request& req, const std::string& name) {
  const std::string text = req.get_param_value(name);
  int64_t value = -1;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || value < 0)
    throw HttpError{400, "bad_query", "expected a whole number >= 0 (as returned by the service)", name};
  return value;
}

// ?format= of the picture endpoints: absent or "json" (JSON), "svg" (a picture).
bool WantsSvg(const httplib::Request& req) {
  if (!req.has_param("format")) return false;
  const std::string format = req.get_param_value("format");
  if (format != "json" && format != "svg") throw HttpError{400, "bad_query", "must be json or svg", "format"};
  return format == "svg";
}

// A JSON request body: sent as application/json (parameters such as charset allowed), and parsed.
json JsonBody(const httplib::Request& req) {
  const std::string type = req.get_header_value("Content-Type");
  if (type.substr(0, type.find(';')) != "application/json")
    throw HttpError{415, "unsupported_media_type",
                    "send the body as Content-Type: application/json (got '" + type + "')", ""};
  try {
    return json::parse(req.body);
  } catch (const json::exception& e) {
    throw HttpError{400, "bad_json", std::string("request body is not valid JSON: ") + e.what(), ""};
  }
}

// A member of a worker's request body with the JSON type of T; 400 naming it (a JSON pointer)
// when it is missing or of another type.
template <typename T>
T BodyField(const json& object, const std::string& key, const std::string& pointer) {
  if (!object.is_object()) throw HttpError{400, "bad_request", "expected a JSON object", pointer.substr(0, pointer.rfind('/'))};
  const auto it = object.find(key);
  if (it == object.end()) throw HttpError{400, "bad_request", "is required", pointer};
  static_assert(std::is_same_v<T, std::string> || std::is_same_v<T, int64_t> || std::is_same_v<T, json>);
  if constexpr (std::is_same_v<T, std::string>) {
    if (!it->is_string()) throw HttpError{400, "bad_request", "expected a string", pointer};
  } else if constexpr (std::is_same_v<T, int64_t>) {
    if (!it->is_number_integer()) throw HttpError{400, "bad_request", "expected an integer", pointer};
  } else if (!it->is_object()) {
    throw HttpError{400, "bad_request", "expected an object", pointer};
  }
  return it->template get<T>();
}

// The lease a worker's complete or fail request names.
TaskLease LeaseOf(const httplib::Request& req, const json& body) {
  TaskLease lease;
  const std::string id = req.matches[1];
  const auto [end, ec] = std::from_chars(id.data(), id.data() + id.size(), lease.task_id);
  if (ec != std::errc() || end != id.data() + id.size()) throw HttpError{404, "unknown_task", "no task " + id, ""};
  lease.job_id = BodyField<int64_t>(body, "job_id", "/job_id");
  lease.lease_token = BodyField<std::string>(body, "lease_token", "/lease_token");
  return lease;
}

int QueryLimit(const httplib::Request& req, int fallback, int maximum) {
  if (!req.has_param("limit")) return fallback;
  const double limit = QueryNumber(req, "limit");
  if (limit < 1 || limit > maximum || limit != std::floor(limit))
    throw HttpError{400, "bad_query", "must be an integer from 1 to " + std::to_string(maximum), "limit"};
  return static_cast<int>(limit);
}

// Stored point rows as CSV (sweep_tables.h: the columns and cells of the sweep folder's points.csv).
std::string PointsCsv(const std::vector<json>& rows) {
  std::string out = report::CsvHeader<SweepPoint>();
  for (const json& row : rows) out += report::CsvLine(report::RowFromJson<SweepPoint>(row));
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
  // Fit and diagnose tasks that a remote lease request drew: they need the server's disk, so they
  // are handed to the in-process workers under that lease (LeaseForRemote).
  std::mutex handoff_mutex;
  std::deque<TaskLease> handoff;
  // Fit and diagnose computations on threads of their own (RunHeldTask); joined when the service is
  // destroyed, since core's fit and diagnosis cannot be interrupted.
  struct Computation {
    std::mutex mutex;
    std::condition_variable done_cv;
    bool done = false;
    std::vector<ResultRow> rows;
    std::exception_ptr error;
  };
  std::mutex computations_mutex;
  std::vector<std::pair<std::thread, std::shared_ptr<Computation>>> computations;

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

  // Every route's path pattern with its methods: a request for a known path with another method is
  // answered 405 with an Allow header, not 404 (set_error_handler).
  std::vector<std::pair<std::regex, std::string>> route_methods;

  // Registers a route (httplib matches the whole path against the pattern, as std::regex_match).
  void On(const std::string& method, const std::string& pattern, httplib::Server::Handler handler) {
    route_methods.emplace_back(std::regex(pattern), method);
    if (method == "GET") {
      http.Get(pattern, std::move(handler));
    } else if (method == "POST") {
      http.Post(pattern, std::move(handler));
    } else if (method == "DELETE") {
      http.Delete(pattern, std::move(handler));
    } else {
      throw std::logic_error("no route registration for method " + method);
    }
  }

  // The methods routed for `path` ("GET, DELETE"); empty when no route matches it.
  std::string AllowedMethods(const std::string& path) const {
    std::string allowed;
    for (const auto& [pattern, method] : route_methods)
      if (std::regex_match(path, pattern) && allowed.find(method) == std::string::npos)
        allowed += (allowed.empty() ? "" : ", ") + method;
    return allowed;
  }

  // Wraps a handler with authorisation, error mapping, metrics and the access log.
  httplib::Server::Handler Route(Role required, std::function<void(const httplib::Request&, httplib::Response&)> h) {
    return [this, required, h](const httplib::Request& req, httplib::Response& res) {
      const auto start = std::chrono::steady_clock::now();
      try {
        Authorize(req, required);
        if (req.body.size() > options.max_body_bytes && req.path != "/v1/campaigns")  // chunked: RefuseOversizeBody
          throw HttpError{413, "body_too_large", "request body exceeds the limit", ""};
        h(req, res);
        // A write route that answered with content wrote to the store.
        if (required != Role::kRead && res.status < 300 && res.status != 204) storage.WriteSucceeded();
      } catch (const StoreError& e) {
        storage.WriteFailed(e.what(), NowMs());
        SendError(res, {503, "storage_error", e.what(), ""});
      } catch (const HttpError& e) {
        SendError(res, e);
      } catch (const ArchiveError& e) {
        SendError(res, {400, "bad_archive", e.bare_message(), e.field()});
      } catch (const jobs::CampaignError& e) {
        SendError(res, {400, "invalid_campaign", e.bare_message(), e.field()});
      } catch (const jobs::JobLimitError& e) {
        SendError(res, {400, "job_too_large", e.bare_message(), e.field()});
      } catch (const InputError& e) {
        SendError(res, {400, "invalid_job", e.bare_message(), e.field()});
      } catch (const json::exception& e) {
        SendError(res, {400, "bad_json", std::string("request body is not valid JSON: ") + e.what(), ""});
      } catch (const std::exception& e) {
        SendError(res, {500, "internal", e.what(), ""});
      }
      metrics.ObserveRequest(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
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
    const SweepSpec spec = jobs::SweepSpecFromJob(job.spec);
    r.frequency_hz = spec.frequency_hz.Values();
    r.amplitude_v = spec.amplitude_v.Values();
    for (int64_t cursor = 0;;) {
      const Store::Page page = store->Results(job.id, "points", {}, cursor, 10000);
      for (const json& p : page.rows) r.points.push_back(report::RowFromJson<SweepPoint>(p));
      if (page.next_cursor == 0) break;
      cursor = page.next_cursor;
    }
    for (const json& t : store->Results(job.id, "thresholds", {}, 0, 1000000).rows)
      r.saturation_threshold.push_back(report::RowFromJson<SaturationThreshold>(t));
    std::sort(r.saturation_threshold.begin(), r.saturation_threshold.end(),
              [](const auto& a, const auto& b) { return a.frequency_hz < b.frequency_hz; });
    for (const json& j : store->Results(job.id, "jumps", {}, 0, 1000000).rows)
      r.jump.push_back(report::RowFromJson<JumpInterval>(j));
    return r;
  }

  // A finished fit or diagnose job's stored rows of `table` (409 while it is not finished).
  std::vector<json> CampaignJobRows(const JobRecord& job, const std::string& table) {
    if (!jobs::IsCampaignKind(job.kind))
      throw HttpError{400, "no_result_document",
                      "only fit and diagnose jobs have a result document (a sweep's results are at /points, "
                      "/saturation-map and /frf)", ""};
    if (job.status != JobStatus::kSucceeded)
      throw HttpError{409, "not_finished", "job " + std::to_string(job.id) + " is " + ToString(job.status) +
                                               (job.error.empty() ? "" : ": " + job.error), ""};
    return store->Results(job.id, table, {}, 0, 100000).rows;
  }

  // Campaign uploads may be larger than other bodies: the limit of the others is checked from
  // Content-Length before their body is read (a chunked body is checked once read, at submission).
  httplib::Server::HandlerResponse RefuseOversizeBody(const httplib::Request& req, httplib::Response& res) {
    if (req.path == "/v1/campaigns" || !req.has_header("Content-Length")) return httplib::Server::HandlerResponse::Unhandled;
    const std::string length = req.get_header_value("Content-Length");
    if (length.size() < 19 && length.find_first_not_of("0123456789") == std::string::npos &&
        std::stoull("0" + length) <= options.max_body_bytes)
      return httplib::Server::HandlerResponse::Unhandled;
    SendError(res, {413, "body_too_large", "request body exceeds the limit", ""});
    res.set_header("Connection", "close");  // the unread body must not be taken for the next request
    return httplib::Server::HandlerResponse::Handled;
  }

  std::optional<TaskLease> LeaseForRemote(const std::string& worker);
  std::optional<TaskLease> TakeHandoff();
  std::optional<std::vector<ResultRow>> RunHeldTask(const TaskLease& lease, const std::atomic<bool>& cancel);
  void SetUpRoutes();
  void WorkLoop(int index);

  // Stores a task's rows. A storage error (disk full, I/O) is not the task's fault: the rows are
  // kept and the write retried every second until it succeeds, the lease is lost (false), or the
  // service stops (false; the lease is released at the next start), instead of failing the job.
  bool StoreCompletion(const TaskLease& lease, const std::vector<ResultRow>& rows, const std::string& worker) {
    for (;;) {
      try {
        const bool stored = store->CompleteTask(lease, rows, NowMs());
        storage.WriteSucceeded();
        return stored;
      } catch (const StoreError& e) {
        storage.WriteFailed(e.what(), NowMs());
        std::fprintf(stderr, "%s\n", json({{"worker", worker}, {"error", e.what()}, {"retry_s", 1}}).dump().c_str());
      }
      std::unique_lock<std::mutex> lock(wake_mutex);
      if (wake.wait_for(lock, std::chrono::seconds(1), [this] { return stopping.load(); })) return false;
    }
  }
};

// Leases a task for a remote worker. Fit and diagnose tasks read campaigns from the server's disk,
// which a remote worker need not see: one drawn here stays leased and goes to the in-process workers
// (or fails the job at once when there are none), and the next task is drawn for the remote worker.
std::optional<TaskLease> Service::Impl::LeaseForRemote(const std::string& worker) {
  for (;;) {
    std::optional<TaskLease> lease = store->LeaseTask(worker, NowMs(), options.lease_ms);
    if (!lease || !jobs::IsCampaignKind(lease->kind)) return lease;
    if (local_workers == 0) {
      store->FailTask(*lease, lease->kind + " jobs need the server's in-process workers (serve --workers >= 1)", NowMs());
      continue;
    }
    {
      std::lock_guard<std::mutex> lock(handoff_mutex);
      handoff.push_back(*lease);
    }
    wake.notify_all();
  }
}

// A task handed over by LeaseForRemote whose lease is still held (renewed now), if any.
std::optional<TaskLease> Service::Impl::TakeHandoff() {
  for (;;) {
    TaskLease lease;
    {
      std::lock_guard<std::mutex> lock(handoff_mutex);
      if (handoff.empty()) return std::nullopt;
      lease = handoff.front();
      handoff.pop_front();
    }
    if (store->RenewLease(lease, NowMs(), options.lease_ms)) return lease;
  }
}

// Runs a fit or diagnose task on a thread of its own, renewing the lease every lease_ms / 4 (these
// tasks take seconds to minutes). Gives up, returning nullopt, when the service stops (the lease is
// released at the next start and the task runs again), the job is cancelled or the lease is lost;
// the computation then runs on to its end (core cannot interrupt it) and its result is dropped.
std::optional<std::vector<ResultRow>> Service::Impl::RunHeldTask(const TaskLease& lease,
                                                                 const std::atomic<bool>& cancel) {
  auto computation = std::make_shared<Computation>();
  {
    std::lock_guard<std::mutex> lock(computations_mutex);
    std::erase_if(computations, [](auto& c) {
      std::lock_guard<std::mutex> done_lock(c.second->mutex);
      if (!c.second->done) return false;
      c.first.join();
      return true;
    });
    computations.emplace_back(std::thread([computation, spec = lease.spec] {
                                std::vector<ResultRow> rows;
                                std::exception_ptr error;
                                try {
                                  rows = jobs::RunTask(spec);
                                } catch (...) {
                                  error = std::current_exception();
                                }
                                std::lock_guard<std::mutex> done_lock(computation->mutex);
                                computation->rows = std::move(rows);
                                computation->error = error;
                                computation->done = true;
                                computation->done_cv.notify_all();
                              }),
                              computation);
  }
  int64_t renewed_ms = NowMs();
  std::unique_lock<std::mutex> lock(computation->mutex);
  while (!computation->done) {
    computation->done_cv.wait_for(lock, std::chrono::milliseconds(100));
    if (computation->done) break;
    if (stopping || cancel) return std::nullopt;
    if (NowMs() - renewed_ms >= options.lease_ms / 4) {
      lock.unlock();
      const bool held = store->RenewLease(lease, NowMs(), options.lease_ms);
      lock.lock();
      if (!held) return std::nullopt;
      renewed_ms = NowMs();
    }
  }
  if (computation->error) std::rethrow_exception(computation->error);
  return std::move(computation->rows);
}

// When this thread's current request was routed (steady clock); unset for requests refused before.
static thread_local std::optional<std::chrono::steady_clock::time_point> t_request_start;

void Service::Impl::SetUpRoutes() {
  http.set_payload_max_length(std::max(options.max_body_bytes, options.max_campaign_bytes));
  // Before routing: the access log's start time, and the body limit of all but campaign uploads.
  // The access log (event_log.h): every request, routed or not, one JSON line.
  http.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    if (!options.quiet) t_request_start = std::chrono::steady_clock::now();
    return RefuseOversizeBody(req, res);
  });
  if (!options.quiet) {
    http.set_logger([](const httplib::Request& req, const httplib::Response& res) {
      std::optional<double> ms;
      if (t_request_start)
        ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - *t_request_start).count();
      t_request_start.reset();
      internal::WriteLogLine(
          internal::RequestLogLine(NowMs(), req.method, req.path, res.status, ms, req.remote_addr, req.remote_port));
    });
  }
  // Without TCP_NODELAY a keep-alive response written in two parts (headers, body) waits for the
  // client's delayed ACK: ~40 ms per request after the first on a connection (~90 instead of
  // ~15,000 GET /v1/jobs/{id} per second on loopback; tests/bench/service_load).
  http.set_tcp_nodelay(true);
  // httplib's default socket options set SO_REUSEPORT, with which a second listener of the same
  // user binds the same port without error and the kernel splits the connections between the two:
  // a second `serve --port 8080` started silently, and a port-0 service could be handed a port
  // another process listens on (found by tests/fuzz/fuzz_http: requests lost, never answered).
  // SO_REUSEADDR alone still allows a restart while old connections are in TIME_WAIT.
  http.set_socket_options([](socket_t sock) {
    int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  http.set_error_handler([this](const httplib::Request& req, httplib::Response& res) {
    if (!res.body.empty()) return;
    if (res.status == 413) SendError(res, {413, "body_too_large", "request body exceeds the limit", ""});
    else if (res.status == 404) {
      const std::string allowed = AllowedMethods(req.path);
      if (allowed.empty()) {
        SendError(res, {404, "not_found", "no such endpoint", ""});
      } else {
        SendError(res, {405, "method_not_allowed", req.method + " is not allowed here; allowed: " + allowed, ""});
        res.set_header("Allow", allowed);
      }
    }
    else if (res.status == 400) {
      SendError(res, {400, "bad_request", "malformed HTTP request (e.g. a POST without Content-Length)", ""});
      // The request could not be parsed, so where its body ends is unknown: read on, its bytes would
      // be taken for the next request on the connection.
      res.set_header("Connection", "close");
    }
    else if (res.status >= 400) SendError(res, {res.status, "http_error", "HTTP error " + std::to_string(res.status), ""});
  });

  On("GET", "/", [](const httplib::Request&, httplib::Response& res) { res.set_content(WebPage(), "text/html"); });
  // Health is open (load balancers and probes carry no token) and says nothing about jobs.
  On("GET", "/v1/health", [this](const httplib::Request&, httplib::Response& res) {
    // 503 while writes fail (disk full, I/O error): the service answers reads but cannot take work.
    const json problem = storage.Problem();
    json body = {{"status", problem.is_null() ? "ok" : "degraded"}, {"code_version", jobs::kCodeVersion}};
    if (!problem.is_null()) body["storage_error"] = problem;
    try {
      body["schema_version"] = store->SchemaVersion();
    } catch (const StoreError& e) {
      body["status"] = "degraded";
      body["storage_error"] = {{"message", e.what()}};
    }
    SendJson(res, body, body["status"] == "ok" ? 200 : 503);
  });
  On("GET", "/metrics", Route(Role::kRead, [this](const httplib::Request&, httplib::Response& res) {
             res.set_content(metrics.Text(store->GetCounts(NowMs())), "text/plain; version=0.0.4");
           }));

  On("POST", "/v1/jobs", Route(Role::kSubmit, [this](const httplib::Request& req, httplib::Response& res) {
              const json job = JsonBody(req);
              // Validates; InputError -> 400 (a campaign's file and line: jobs::CampaignError).
              const std::vector<TaskSpec> tasks = jobs::PlanTasks(job, campaigns);
              if (jobs::IsCampaignKind(job.at("kind")) && local_workers == 0)
                throw HttpError{400, "unsupported_kind",
                                job.at("kind").get<std::string>() +
                                    " jobs need the server's in-process workers (this server runs with --workers 0)",
                                "/kind"};
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
               jobs.push_back(JobJson(j));
               last = j.id;
             }
             SendJson(res, {{"jobs", jobs},
                            {"next_before", static_cast<int>(jobs.size()) == limit ? json(last) : json(nullptr)}});
           }));
  On("GET", R"(/v1/jobs/(\d+))", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             SendJson(res, JobJson(RequireJob(req.matches[1])));
           }));
  On("DELETE", R"(/v1/jobs/(\d+))", Route(Role::kSubmit, [this](const httplib::Request& req, httplib::Response& res) {
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
  On("GET", R"(/v1/jobs/(\d+)/points)", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
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
             const int64_t cursor = req.has_param("cursor") ? QueryInteger(req, "cursor") : 0;
             const Store::Page page = store->Results(job.id, "points", filter, cursor, limit);
             if (req.get_header_value("Accept").find("text/csv") != std::string::npos) {
               res.set_header("X-Next-Cursor", std::to_string(page.next_cursor));
               res.set_content(PointsCsv(page.rows), "text/csv");
               return;
             }
             SendJson(res, {{"points", page.rows},
                            {"next_cursor", page.next_cursor ? json(page.next_cursor) : json(nullptr)}});
           }));
  On("GET", R"(/v1/jobs/(\d+)/saturation-map)",
           Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const JobRecord job = RequireJob(req.matches[1]);
             if (job.kind != "sweep") throw HttpError{400, "not_a_sweep", "only sweep jobs have a saturation map", ""};
             if (WantsSvg(req)) {
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
  On("GET", R"(/v1/jobs/(\d+)/frf)", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const JobRecord job = RequireJob(req.matches[1]);
             if (job.kind != "sweep") throw HttpError{400, "not_a_sweep", "only sweep jobs have FRFs", ""};
             if (WantsSvg(req)) {
               const std::string branch = req.has_param("branch") ? req.get_param_value("branch") : "up";
               if (branch != "up" && branch != "down") throw HttpError{400, "bad_query", "must be up or down", "branch"};
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

  // Campaigns for fit and diagnose jobs (campaign_upload.h).
  On("POST", "/v1/campaigns", Route(Role::kSubmit, [this](const httplib::Request& req, httplib::Response& res) {
              const std::string type = req.get_header_value("Content-Type");
              const auto is = [&type](const char* media) { return type.rfind(media, 0) == 0; };
              if (!is("application/x-tar") && !is("application/zip") && !is("application/x-zip-compressed"))
                throw HttpError{415, "unsupported_media_type",
                                "send the campaign as a tar archive (ustar or pax) with Content-Type "
                                "application/x-tar, or as a zip archive with Content-Type application/zip, "
                                "not '" + type + "'", ""};
              // The body's first bytes, not the type, choose the reader (campaign_upload.h).
              ArchiveLimits limits;
              limits.max_file_bytes = limits.max_total_bytes = options.max_campaign_bytes;
              const UploadedCampaign upload = StoreUploadedCampaign(req.body, campaigns.uploads, limits);
              SendJson(res, {{"campaign_id", upload.id}, {"campaign", CampaignSummary(upload.campaign)}}, 201);
            }));
  On("GET", R"(/v1/jobs/(\d+)/result)", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const JobRecord job = RequireJob(req.matches[1]);
             const std::vector<json> rows = CampaignJobRows(job, job.kind == "fit" ? "fit" : "diagnosis");
             if (rows.empty()) throw std::runtime_error("job " + std::to_string(job.id) + " has no stored result");
             SendJson(res, rows.front());
           }));
  // The report's main page is its index.html (else its first .html file); FILE is another file of it.
  On("GET", R"(/v1/jobs/(\d+)/report(/.*)?)", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const JobRecord job = RequireJob(req.matches[1]);
             if (job.kind != "diagnose")
               throw HttpError{400, "no_report", "only diagnose jobs have an HTML report", ""};
             const std::vector<json> files = CampaignJobRows(job, "report_files");
             const std::string wanted = req.matches[2].length() > 1 ? req.matches[2].str().substr(1) : "";
             const json* found = nullptr;
             for (const json& f : files) {
               const std::string name = f.at("name");
               if (wanted.empty() ? name == "index.html" : name == wanted) {
                 found = &f;
                 break;
               }
               if (wanted.empty() && found == nullptr && name.ends_with(".html")) found = &f;
             }
             if (found == nullptr)
               throw HttpError{404, "no_report_file",
                               files.empty() ? "this server stored no report for the job (built without the report writer)"
                                             : "the report has no file '" + wanted + "'", ""};
             std::string body = found->at("text");
             // At .../report (no slash) the page's relative links (records.csv) would miss the report.
             if (req.matches[2].length() == 0)
               if (const size_t head = body.find("<head>"); head != std::string::npos)
                 body.insert(head + 6, "<base href=\"/v1/jobs/" + std::to_string(job.id) + "/report/\">");
             res.set_content(body, found->at("content_type").get<std::string>());
           }));

  // Remote workers.
  On("POST", "/v1/tasks/lease", Route(Role::kWorker, [this](const httplib::Request& req, httplib::Response& res) {
              const json body = req.body.empty() ? json::object() : JsonBody(req);
              if (!body.is_object()) throw HttpError{400, "bad_request", "expected a JSON object", ""};
              if (body.contains("worker") && !body["worker"].is_string())
                throw HttpError{400, "bad_request", "expected a string", "/worker"};
              // Remote names are prefixed so that none can pass for this server's own "local-" workers,
              // whose leases are released at start.
              const std::optional<TaskLease> lease = LeaseForRemote("remote:" + body.value("worker", std::string("unnamed")));
              if (!lease) {
                res.status = 204;
                return;
              }
              SendJson(res, {{"task_id", lease->task_id}, {"job_id", lease->job_id}, {"index", lease->index},
                             {"kind", lease->kind}, {"spec", lease->spec}, {"lease_token", lease->lease_token},
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
              const json body = JsonBody(req);
              const TaskLease lease = LeaseOf(req, body);
              const auto rows_at = body.find("rows");
              if (rows_at == body.end() || !rows_at->is_array())
                throw HttpError{400, "bad_request", "expected an array of rows", "/rows"};
              const json& given = *rows_at;
              std::vector<ResultRow> rows;
              for (size_t i = 0; i < given.size(); ++i) {
                const std::string at = "/rows/" + std::to_string(i);
                rows.push_back({BodyField<std::string>(given[i], "table", at + "/table"),
                                BodyField<json>(given[i], "values", at + "/values")});
              }
              if (!store->CompleteTask(lease, rows, NowMs()))
                throw HttpError{409, "lease_lost", "the lease expired or the job was cancelled; nothing written", ""};
              metrics.TaskDone(rows.size());
              SendJson(res, {{"accepted", true}});
            }));
  On("POST", R"(/v1/tasks/(\d+)/fail)", Route(Role::kWorker, [this](const httplib::Request& req, httplib::Response& res) {
              const json body = JsonBody(req);
              const TaskLease lease = LeaseOf(req, body);
              const std::string error =
                  body.contains("error") ? BodyField<std::string>(body, "error", "/error") : "worker failure";
              store->FailTask(lease, error, NowMs());
              SendJson(res, {{"accepted", true}});
            }));
}

void Service::Impl::WorkLoop(int index) {
  const std::string name = "local-" + std::to_string(index);
  while (!stopping) {
    std::optional<TaskLease> lease;
    try {
      lease = TakeHandoff();
      if (!lease) lease = store->LeaseTask(name, NowMs(), options.lease_ms);
    } catch (const std::exception& e) {
      if (dynamic_cast<const StoreError*>(&e)) storage.WriteFailed(e.what(), NowMs());
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
      const std::optional<std::vector<ResultRow>> rows =
          jobs::IsCampaignKind(lease->kind) ? RunHeldTask(*lease, *cancel) : jobs::RunTask(lease->spec, cancel.get());
      if (rows && StoreCompletion(*lease, *rows, name)) metrics.TaskDone(rows->size());
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
  impl_->campaigns.uploads = options.db_path + ".campaigns";
  if (!options.data_root.empty()) {
    if (!std::filesystem::is_directory(options.data_root))
      throw InputError("data_root", "'" + options.data_root + "' is not a directory");
    impl_->campaigns.data_root = options.data_root;
  }
  if (!options.quiet)
    impl_->store->SetJobEventSink([](const JobEvent& e) { internal::WriteLogLine(internal::JobEventLogLine(e)); });
  if (!options.token_file.empty()) impl_->tokens = TokenTable::Load(options.token_file);
  impl_->SetUpRoutes();
}

Service::~Service() {
  Stop();
  // Fit and diagnose computations given up by Stop run to their end (core cannot interrupt them).
  for (auto& [thread, computation] : impl_->computations) thread.join();
}

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
  const int workers = s.options.workers < 0 ? static_cast<int>(std::max(1u, std::thread::hardware_concurrency()))
                                            : s.options.workers;
  s.local_workers = workers;
  s.http_thread = std::thread([&s] {
    s.http.listen_after_bind();
    s.http_ended = true;
  });
  // httplib's stop() does nothing until the listen loop has begun, so a Stop() right after Start()
  // (a SIGTERM that came while the store waited for a lock) would leave Stop() joining a thread that
  // accepts forever: return only once it listens (or has already given up).
  while (!s.http.is_running() && !s.http_ended) std::this_thread::sleep_for(std::chrono::milliseconds(1));
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
  // Each finishes (and stores) the task it holds; a fit or diagnose task is given up (RunHeldTask).
  for (std::thread& t : s.workers) t.join();
  if (s.http_thread.joinable()) s.http_thread.join();
}

}  // namespace strokelab::server
