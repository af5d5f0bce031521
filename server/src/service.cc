// The service: its HTTP server (limits, socket options, error pages, logs), authorisation and the
// wrapping of every route, the server's own routes (page, health, metrics), start and stop.
#include "strokelab/server/service.h"

#include <sys/socket.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cctype>
#include <filesystem>
#include <random>
#include <string_view>

#include "event_log.h"
#include "http_reply.h"
#include "memory_trim.h"
#include "now.h"
#include "request_params.h"
#include "service_impl.h"
#include "strokelab/base/errors.h"
#include "strokelab/jobs/jobs.h"
#include "strokelab/server/web_page.h"

namespace strokelab::server {

using nlohmann::json;
using namespace internal;

// When this thread's current request was routed (steady clock); unset for requests refused before.
static thread_local std::optional<std::chrono::steady_clock::time_point> t_request_start;

// Health, a job's status and the task routes a worker polls go to the gate's priority pool: they
// answer while the main pool is busy with slow bodies (task completions), or heavy pictures.
static bool IsPriorityRequest(std::string_view request_line) {
  static const std::regex priority(R"((GET /v1/health|GET /v1/jobs/\d+|POST /v1/tasks/(lease|\d+/renew))[ ?].*)");
  return std::regex_match(request_line.begin(), request_line.end(), priority);
}

// The page's policy. Scripts: only the two the page carries, its own inline one and the vendored
// uPlot from /vendor/, both tagged with this response's nonce (no other script of this server or
// any other runs, and no eval: uPlot needs none). Styles: the page's <style>, the uPlot stylesheet
// from this server, and the style attributes of the server's SVG ('unsafe-inline'; uPlot itself sets
// styles through the DOM, which the policy does not govern). Requests to this server only.
static std::string PageContentSecurityPolicy(const std::string& nonce) {
  return "default-src 'none'; script-src 'nonce-" + nonce +
         "'; style-src 'self' 'unsafe-inline'; img-src 'self' data:; connect-src 'self'; form-action 'self'; "
         "base-uri 'none'; frame-ancestors 'none'";
}

// A route pattern that matches `path` as it is ('.' is a regex character).
static std::string LiteralPattern(std::string_view path) {
  std::string pattern;
  for (char c : path) {
    if (c == '.') pattern += '\\';
    pattern += c;
  }
  return pattern;
}

static std::string PageNonce() {
  static thread_local std::mt19937_64 random{std::random_device{}()};
  char hex[33];
  std::snprintf(hex, sizeof hex, "%016llx%016llx", static_cast<unsigned long long>(random()),
                static_cast<unsigned long long>(random()));
  return hex;
}

static std::string WithScriptNonce(std::string page, const std::string& nonce) {
  const std::string tag = "<script", with = "<script nonce=\"" + nonce + "\"";
  for (size_t at = 0; (at = page.find(tag, at)) != std::string::npos; at += with.size()) page.replace(at, tag.size(), with);
  return page;
}

// A bearer token followed by blanks: cpp-httplib trims them from header values, so the token
// would pass for the one without them; refused on the raw header block (http_gate.h).
static bool AuthorizationEndsInBlank(std::string_view block) {
  for (size_t start = 0, end; (end = block.find("\r\n", start)) != std::string_view::npos; start = end + 2) {
    const std::string_view line = block.substr(start, end - start);
    constexpr std::string_view kName = "authorization:";
    if (line.size() <= kName.size()) continue;
    bool name_matches = true;
    for (size_t i = 0; i < kName.size(); ++i)
      name_matches = name_matches && std::tolower(static_cast<unsigned char>(line[i])) == kName[i];
    if (name_matches && (line.back() == ' ' || line.back() == '\t')) return true;
  }
  return false;
}

void Service::Impl::SetUpRoutes() {
  GateLimits& gate = http.limits();
  gate.header_timeout = std::chrono::milliseconds(options.header_timeout_ms);
  gate.max_pending_per_address = options.max_pending_per_address;
  gate.threads = options.http_threads;
  gate.is_priority = IsPriorityRequest;
  if (tokens.enabled()) {
    gate.refuse_headers = [](std::string_view block) -> std::string {
      if (!AuthorizationEndsInBlank(block)) return "";
      return JsonErrorResponse(401, "Unauthorized", "unauthorized", "unknown token (it ends in a blank)");
    };
  }
  if (!options.quiet) {
    gate.on_refused = [](int status, const std::string& remote) {
      internal::WriteLogLine(internal::RequestLogLine(NowMs(), "", "", status, std::nullopt, remote, 0));
    };
  }
  http.set_payload_max_length(std::max(options.max_body_bytes, options.max_campaign_bytes));
  // Before routing: the access log's start time, and the checks on the headers (route_table.cc).
  // The access log (event_log.h): every request, routed or not, one JSON line (but empty-queue polls).
  http.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
    if (!options.quiet) t_request_start = std::chrono::steady_clock::now();
    return RefuseBeforeBody(req, res);
  });
  if (!options.quiet) {
    http.set_logger([](const httplib::Request& req, const httplib::Response& res) {
      // An idle remote worker's poll of the empty queue is not worth a line (/metrics counts it).
      if (res.status == 204 && req.path == "/v1/tasks/lease") {
        t_request_start.reset();
        return;
      }
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
    const std::string type = req.get_header_value("Content-Type");
    if (res.status == 413 && type.rfind("application/x-www-form-urlencoded", 0) == 0) {
      // httplib refuses form bodies over 8 KiB as 413 before any route sees them, but the size is
      // not what is wrong: no route takes a form (curl -d's default type), so say which type to send.
      const bool campaign = req.path == "/v1/campaigns";
      SendError(res, {415, "unsupported_media_type",
                      campaign ? UnsupportedCampaignMessage(type) : UnsupportedJsonBodyMessage(type), ""});
      res.set_header("Connection", "close");  // a body over the payload limit was left unread
    }
    else if (res.status == 413) SendError(res, {413, "body_too_large", "request body exceeds the limit", ""});
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

  // Every response: no MIME sniffing, no framing (clickjacking), no referrer leaving the page.
  http.set_default_headers(SecurityHeaders());
  On("GET", "/", [](const httplib::Request&, httplib::Response& res) {
    const std::string nonce = PageNonce();
    res.set_header("Content-Security-Policy", PageContentSecurityPolicy(nonce));
    res.set_content(WithScriptNonce(WebPage(), nonce), "text/html; charset=utf-8");
  });
  // The page's plotting library, compiled in (no network at run time); open like the page.
  for (const WebLibraryFile& file : WebLibraryFiles()) {
    On("GET", LiteralPattern(file.path), [&file](const httplib::Request&, httplib::Response& res) {
      res.set_content(file.bytes.data(), file.bytes.size(), file.content_type);
    });
  }
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
  AddJobRoutes();
  AddResultRoutes();
  AddTaskRoutes();
  AddCampaignRoutes();
}

std::optional<FieldError> ServiceOptions::IsValid() const {
  if (port < 0 || port > 65535) return FieldError{"port", "must be between 0 and 65535"};
  if (workers < -1 || workers > 256) return FieldError{"workers", "must be between 0 and 256 (-1: one per core)"};
  if (db_path.empty()) return FieldError{"db_path", "must name a file"};
  if (lease_ms < 1) return FieldError{"lease_ms", "must be positive"};
  if (max_body_bytes < 1) return FieldError{"max_body_bytes", "must be at least 1"};
  if (max_campaign_bytes < 1) return FieldError{"max_campaign_bytes", "must be at least 1"};
  if (upload_quota_bytes < 1) return FieldError{"upload_quota_bytes", "must be at least 1"};
  if (uploads_total_quota_bytes < 1) return FieldError{"uploads_total_quota_bytes", "must be at least 1"};
  if (!(max_job_seconds >= 1)) return FieldError{"max_job_seconds", "must be at least 1 s"};
  if (header_timeout_ms < 1) return FieldError{"header_timeout_ms", "must be positive"};
  if (max_pending_per_address < 1) return FieldError{"max_pending_per_address", "must be at least 1"};
  if (http_threads < 1 || http_threads > 1024) return FieldError{"http_threads", "must be between 1 and 1024"};
  if (!data_root.empty() && !std::filesystem::is_directory(data_root))
    return FieldError{"data_root", "'" + data_root + "' is not a directory"};
  return std::nullopt;
}

Service::Service(const ServiceOptions& options) : impl_(std::make_unique<Impl>()) {
  Validate(options);
  BoundHeapRetention();  // memory_trim.h: RSS comes back after large request bodies
  impl_->options = options;
  impl_->store = Store::Open(options.db_path);
  impl_->campaigns.uploads = options.db_path + ".campaigns";
  impl_->campaigns.data_root = options.data_root;
  impl_->campaigns.max_campaign_bytes = options.max_campaign_bytes;
  if (!options.quiet)
    impl_->store->SetJobEventSink([](const JobEvent& e) { internal::WriteLogLine(internal::JobEventLogLine(e)); });
  if (!options.token_file.empty()) impl_->tokens = TokenTable::Load(options.token_file);
  // Uploads cut off by a crash (SIGKILL mid-upload) leave their unpacking directories behind.
  std::error_code ignored;
  if (std::filesystem::is_directory(impl_->campaigns.uploads, ignored))
    for (const auto& entry : std::filesystem::directory_iterator(impl_->campaigns.uploads, ignored))
      if (entry.path().filename().string().rfind(".incoming-", 0) == 0) std::filesystem::remove_all(entry.path(), ignored);
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
  // Every running computation polls its flag (jobs::RunTask) and ends within a few ms.
  {
    std::lock_guard<std::mutex> lock(s.cancel_mutex);
    for (auto& [job, flag] : s.running) *flag = true;
  }
  s.wake.notify_all();
  for (std::thread& t : s.workers) t.join();
  {
    std::lock_guard<std::mutex> lock(s.computations_mutex);
    for (auto& [thread, computation] : s.computations) thread.join();
    s.computations.clear();
  }
  // The tasks they held go back to the queue now, not only at the next start.
  try {
    if (s.local_workers > 0) s.store->ReleaseLeases("local-");
  } catch (const StoreError&) {
    // Released at the next start instead.
  }
  if (s.http_thread.joinable()) s.http_thread.join();
}

}  // namespace strokelab::server
