// The service commands: serve (the REST service with its SQLite store and worker pool), worker (a
// remote worker), and the client side: submit, status, results.
#include <httplib.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "ceres_log.h"
#include "commands.h"
#include "service_help.h"
#include "strokelab/base/errors.h"
#include "strokelab/server/service.h"
#include "strokelab/worker/remote_worker.h"
#include "strokelab/base/json_parse.h"

namespace strokelab::cli {
namespace {

using nlohmann::json;

std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop = true; }

void InstallStopSignals() {
  struct sigaction action {};
  action.sa_handler = OnSignal;
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
  // A write past a file-size limit (RLIMIT_FSIZE) then fails with EFBIG, which the store reports as
  // storage trouble (503, health degraded), instead of killing the process with SIGXFSZ.
  signal(SIGXFSZ, SIG_IGN);
}

// The token for client commands: --token, else --token-file's first submit token, else $STROKELAB_TOKEN.
std::string ClientToken(const Args& args) {
  if (auto token = args.Get("--token")) return *token;
  if (const char* env = std::getenv("STROKELAB_TOKEN")) return env;
  return "";
}

constexpr const char* kDefaultServerUrl = "http://127.0.0.1:8080";

// The server for client commands and workers: --server, else $STROKELAB_SERVER, else the default.
std::string ServerUrl(const Args& args) {
  if (auto url = args.Get("--server")) return *url;
  if (const char* env = std::getenv("STROKELAB_SERVER"); env && *env) return env;
  return kDefaultServerUrl;
}

// Where the URL came from, for the message when nothing answers there.
std::string ServerUrlSource(const Args& args) {
  if (args.Get("--server")) return "--server";
  if (const char* env = std::getenv("STROKELAB_SERVER"); env && *env) return "$STROKELAB_SERVER";
  return "the default; give --server URL or set STROKELAB_SERVER";
}

httplib::Headers Headers(const std::string& token) {
  if (token.empty()) return {};
  return {{"Authorization", "Bearer " + token}};
}

struct Connection {
  std::string url, url_source;
  std::string host;
  int port;
  std::string token;
  httplib::Client client() const {
    httplib::Client c(host, port);
    c.set_connection_timeout(5);
    c.set_read_timeout(120);
    return c;
  }
};

Connection Connect(const Args& args) {
  const std::string url = ServerUrl(args);
  const auto [host, port] = worker::ParseServerUrl(url);
  return {url, ServerUrlSource(args), host, port, ClientToken(args)};
}

// The server's error object of a reply ({} when the body is not one).
json ReplyError(const httplib::Result& result) {
  try {
    return ParseJson(result->body).at("error");
  } catch (...) {
    return json::object();
  }
}

// The body of a reply, or a one-line error naming the server's error code and field. A job the
// server refuses as invalid (400 invalid_job, bad_json, job_too_large) is bad input: InputError,
// exit code 2, the field prefixed with `input_name` (the job file).
json Expect(const httplib::Result& result, int status, const std::string& what, const Connection* c = nullptr,
            const std::string& input_name = "") {
  if (!result) {
    throw std::runtime_error(what + ": cannot reach the server" +
                             (c ? " at " + c->url + " (" + c->url_source + ")" : std::string()) + ": " +
                             httplib::to_string(result.error()) + " error");
  }
  if (result->status != status) {
    const json error = ReplyError(result);
    const std::string code = error.value("code", "");
    std::string message = error.empty() ? "HTTP " + std::to_string(result->status) : code + ": " + error.value("message", "");
    const std::string field = error.contains("field") && error["field"].is_string() ? error["field"].get<std::string>() : "";
    if (!input_name.empty() && result->status == 400)
      throw InputError(input_name + (field.empty() ? "" : ":" + field), code + ": " + error.value("message", ""));
    if (!field.empty()) message = field + ": " + message;
    throw std::runtime_error(what + ": " + message);
  }
  return result->body.empty() ? json() : ParseJson(result->body);
}

void PrintProgress(const json& job) {
  const json& progress = job["progress"];
  const int done = progress["done"], total = progress["total"];
  const int width = 30, filled = total > 0 ? width * done / total : 0;
  std::fprintf(stderr, "\r  job %lld [%s%s] %d/%d tasks, %s", static_cast<long long>(job["id"].get<int64_t>()),
               std::string(filled, '#').c_str(), std::string(width - filled, '.').c_str(), done, total,
               job["status"].get<std::string>().c_str());
  if (progress.contains("stage")) {  // a running fit or diagnose job: its stage, with the time
    std::fprintf(stderr, ", stage %d of %d: %s, %.0f s", progress["stage"].get<int>(), progress["stages"].get<int>(),
                 progress["stage_name"].get<std::string>().c_str(), progress["elapsed_s"].get<double>());
    if (progress["eta_s"].is_number()) std::fprintf(stderr, ", about %.0f s left (estimate)", progress["eta_s"].get<double>());
  }
  for (const json& warning : job.value("warnings", json::array()))
    std::fprintf(stderr, ", %s", warning.get<std::string>().c_str());
  std::fputs("\033[K", stderr);  // the rest of a longer line drawn before
  std::fflush(stderr);
}

// Polls a job until it finishes; a progress bar on a terminal. Returns the final status object.
json WaitForJob(const Connection& c, int64_t id) {
  httplib::Client client = c.client();
  const bool tty = isatty(STDERR_FILENO);
  for (;;) {
    const json job = Expect(client.Get("/v1/jobs/" + std::to_string(id), Headers(c.token)), 200, "status", &c);
    if (tty) PrintProgress(job);
    const std::string status = job["status"];
    if (status != "queued" && status != "running") {
      if (tty) std::fprintf(stderr, "\n");
      return job;
    }
    if (g_stop) throw std::runtime_error("interrupted while waiting (the job goes on on the server)");
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
}

}  // namespace

int RunServe(const std::vector<std::string>& argv) {
  const Args args(argv, {"--port", "--db", "--workers", "--token-file", "--host", "--lease-s", "--max-body-bytes",
                   "--data-root", "--max-campaign-bytes", "--upload-quota-bytes", "--uploads-total-quota-bytes",
                   "--max-job-seconds"},
                  {"--demo", "--quiet", "--help"});
  if (args.Has("--help")) {
    std::cout << "usage: strokelab serve [--port 8080] [--db var/strokelab.db] [--workers N] [--token-file F]\n"
                 "                       [--host 127.0.0.1] [--lease-s 120] [--demo] [--quiet]\n"
                 "                       [--data-root DIR] [--max-campaign-bytes 268435456]\n"
                 "                       [--upload-quota-bytes 268435456] [--uploads-total-quota-bytes 4294967296]\n"
                 "                       [--max-job-seconds 600]\n"
                 "  --workers 0 leaves all work to remote workers (strokelab worker --server URL);\n"
                 "    fit and diagnose jobs need in-process workers.\n"
                 "  --data-root DIR lets fit and diagnose jobs name campaigns as {\"path\": P} relative to DIR;\n"
                 "    uploads (POST /v1/campaigns) are kept next to the database, in DB.campaigns/.\n"
                 "  --upload-quota-bytes: what one upload may unpack to; --uploads-total-quota-bytes: all\n"
                 "    uploads on disk together (an upload past it is refused, 507; uploads are never deleted).\n"
                 "  --max-job-seconds: the most a diagnose job's max_seconds or a fit's max_refinement_seconds\n"
                 "    may ask for (more is refused, 400); jobs that give none get at most this.\n"
                 "  --demo submits a sweep of the paper's model once the service is up and prints where to look.\n";
    return 0;
  }
  server::ServiceOptions options;
  options.port = args.Integer("--port", 8080);
  options.db_path = args.GetOr("--db", "var/strokelab.db");
  options.workers = args.Integer("--workers", -1);
  options.token_file = args.GetOr("--token-file", "");
  options.host = args.GetOr("--host", "127.0.0.1");
  options.lease_ms = static_cast<int64_t>(args.Number("--lease-s", 120.0) * 1000);
  // Shorter leases are for tests; a deployment would lose leases to ordinary scheduling jitter.
  if (options.lease_ms < 1000) throw InputError("--lease-s", "must be at least 1 s");
  options.max_body_bytes = static_cast<size_t>(args.Number("--max-body-bytes", 1 << 20));
  options.max_campaign_bytes = static_cast<size_t>(args.Number("--max-campaign-bytes", 256.0 * (1 << 20)));
  options.upload_quota_bytes = static_cast<uint64_t>(args.Number("--upload-quota-bytes", 256.0 * (1 << 20)));
  options.uploads_total_quota_bytes =
      static_cast<uint64_t>(args.Number("--uploads-total-quota-bytes", 4.0 * (1 << 30)));
  options.max_job_seconds = args.Number("--max-job-seconds", 600);
  options.data_root = args.GetOr("--data-root", "");
  options.quiet = args.Has("--quiet");
  if (const std::optional<FieldError> error = options.IsValid()) {
    static const std::map<std::string, std::string> kFlags = {
        {"port", "--port"}, {"workers", "--workers"}, {"db_path", "--db"}, {"lease_ms", "--lease-s"},
        {"max_body_bytes", "--max-body-bytes"}, {"max_campaign_bytes", "--max-campaign-bytes"},
        {"data_root", "--data-root"}, {"upload_quota_bytes", "--upload-quota-bytes"},
        {"uploads_total_quota_bytes", "--uploads-total-quota-bytes"}, {"max_job_seconds", "--max-job-seconds"}};
    throw InputError(kFlags.at(error->field), error->message);
  }
  if (const auto parent = std::filesystem::path(options.db_path).parent_path(); !parent.empty())
    std::filesystem::create_directories(parent);

  // The service's log is JSON lines: Ceres' lines, when asked for, join it as such (ceres_log.h).
  CeresLogSettings ceres_log = CeresLogSettingsFrom(std::getenv("STROKELAB_CERES_LOG"));
  ceres_log.json_lines = true;
  RouteCeresLog(ceres_log);
  InstallStopSignals();
  server::Service service(options);
  const int port = service.Start();
  const std::string url = "http://" + options.host + ":" + std::to_string(port);
  std::fprintf(stderr, "strokelab serving %s (database %s)\n", url.c_str(), options.db_path.c_str());
  if (args.Has("--demo")) {
    httplib::Client client("127.0.0.1", port);
    const json job = {{"kind", "sweep"}, {"name", "demo: paper model, Eq. 1 grid"}, {"model", "paper"},
                      {"grid", {{"frequency_hz", {{"from", 5}, {"points", 117}, {"spacing", "eq1"}}},
                                {"amplitude_v", {{"from", 0.1}, {"to", 0.6}, {"points", 26}}}}}};
    const json reply = Expect(client.Post("/v1/jobs", job.dump(), "application/json"), 201, "demo submit");
    std::fprintf(stderr, "demo sweep submitted as job %lld: its saturation map is at %s/?job=%lld\n",
                 static_cast<long long>(reply["id"].get<int64_t>()), url.c_str(),
                 static_cast<long long>(reply["id"].get<int64_t>()));
  }
  while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  std::fprintf(stderr, "stopping\n");
  service.Stop();
  return 0;
}

namespace {

// $XDG_CACHE_HOME/strokelab/campaigns, else $HOME/.cache/strokelab/campaigns, else under the temp directory.
std::string DefaultCampaignCache() {
  if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg && *xdg) return std::string(xdg) + "/strokelab/campaigns";
  if (const char* home = std::getenv("HOME"); home && *home) return std::string(home) + "/.cache/strokelab/campaigns";
  return (std::filesystem::temp_directory_path() / "strokelab-campaigns").string();
}

}  // namespace

int RunWorker(const std::vector<std::string>& argv) {
  const Args args(argv, {"--server", "--token", "--threads", "--name", "--max-tasks", "--exit-when-idle", "--cache-dir"},
                  {"--help"});
  if (args.Has("--help")) {
    std::cout << kWorkerHelp;
    return 0;
  }
  worker::RemoteWorkerOptions options;
  options.server_url = ServerUrl(args);
  worker::ParseServerUrl(options.server_url);
  options.token = ClientToken(args);
  options.threads = args.Integer("--threads", 1);
  if (options.threads < 1 || options.threads > 256) throw InputError("--threads", "must be between 1 and 256");
  char hostname[256] = "worker";
  gethostname(hostname, sizeof hostname);
  options.name = args.GetOr("--name", std::string(hostname) + "-" + std::to_string(getpid()));
  options.max_tasks = args.Integer("--max-tasks", -1);
  if (args.Has("--exit-when-idle")) {
    const int seconds = args.Integer("--exit-when-idle", 0);
    if (seconds < 0 || seconds > 7 * 24 * 3600) throw InputError("--exit-when-idle", "must be between 0 and 604800 seconds");
    options.exit_when_idle_ms = seconds * 1000;
  }
  options.campaign_cache_dir = args.GetOr("--cache-dir", DefaultCampaignCache());
  std::error_code cache_error;
  std::filesystem::create_directories(options.campaign_cache_dir, cache_error);
  if (cache_error) {
    std::fprintf(stderr, "worker: cannot create the campaign cache %s (%s): fit and diagnose tasks are left to other workers\n",
                 options.campaign_cache_dir.c_str(), cache_error.message().c_str());
    options.campaign_cache_dir.clear();
  }
  InstallStopSignals();
  const int done = worker::RunRemoteWorker(options, g_stop);
  std::fprintf(stderr, "worker %s: %d tasks completed\n", options.name.c_str(), done);
  return 0;
}

int RunSubmit(const std::vector<std::string>& argv) {
  const Args args(argv, {"--server", "--token"}, {"--wait", "--help"});
  if (args.Has("--help") || args.Positional().size() != 1) {
    (args.Has("--help") ? std::cout : std::cerr) << kSubmitHelp;
    return args.Has("--help") ? 0 : 2;
  }
  const std::string path = args.Positional()[0];
  std::ifstream in(path);
  if (!in) throw InputError(path, "cannot read the job file");
  std::stringstream body;
  body << in.rdbuf();
  const Connection c = Connect(args);
  httplib::Client client = c.client();
  const json reply =
      Expect(client.Post("/v1/jobs", Headers(c.token), body.str(), "application/json"), 201, "submit", &c, path);
  const int64_t id = reply["id"];
  std::cout << id << "\n";
  InstallStopSignals();
  if (args.Has("--wait")) {
    const json job = WaitForJob(c, id);
    std::cerr << "job " << id << " " << job["status"].get<std::string>() << "\n";
    return job["status"] == "succeeded" ? 0 : 1;
  }
  return 0;
}

// A job id as the commands take it: digits only, named as the argument when it is not one.
int64_t JobIdArgument(const std::string& text) {
  if (text.empty() || text.size() > 18 || text.find_first_not_of("0123456789") != std::string::npos)
    throw InputError("JOB_ID", "expected a job id (a whole number), got '" + text + "'");
  return std::stoll(text);
}

int RunStatus(const std::vector<std::string>& argv) {
  const Args args(argv, {"--server", "--token"}, {"--wait", "--help"});
  if (args.Has("--help") || args.Positional().size() != 1) {
    (args.Has("--help") ? std::cout : std::cerr) << kStatusHelp;
    return args.Has("--help") ? 0 : 2;
  }
  const int64_t id = JobIdArgument(args.Positional()[0]);
  const Connection c = Connect(args);
  InstallStopSignals();
  json job;
  if (args.Has("--wait")) {
    job = WaitForJob(c, id);
  } else {
    httplib::Client client = c.client();
    job = Expect(client.Get("/v1/jobs/" + std::to_string(id), Headers(c.token)), 200, "status", &c);
  }
  std::cout << job.dump(2) << "\n";
  return 0;
}

namespace {

// A sweep's points: CSV as the server streams every row in one body (?format=csv without limit and
// cursor), written out as it arrives; or {"points": [...]} over every JSON page.
void PrintSweepPoints(const Args& args, const Connection& c, int64_t id) {
  httplib::Client client = c.client();
  const httplib::Headers headers = Headers(c.token);
  std::string filters;
  if (auto b = args.Get("--branch")) filters += "&branch=" + *b;
  if (auto a = args.Get("--amplitude-v")) filters += "&amplitude_v=" + *a;
  const std::string points = "/v1/jobs/" + std::to_string(id) + "/points?";
  if (args.Has("--csv")) {
    const std::string path = points + "format=csv" + filters;
    int status = 0;
    auto result = client.Get(
        path, headers, [&status](const httplib::Response& r) { return (status = r.status) == 200; },
        [](const char* data, size_t length) { return static_cast<bool>(std::cout.write(data, static_cast<std::streamsize>(length))); });
    if (status != 200) Expect(client.Get(path, headers), 200, "results", &c);  // the server's error, read whole
    if (!result) Expect(result, 200, "results", &c);                           // cut off while streaming
    std::cout.flush();
    return;
  }
  json all = json::array();
  for (std::string cursor = "0";;) {
    const json page = Expect(client.Get(points + "limit=10000" + filters + "&cursor=" + cursor, headers), 200, "results", &c);
    for (const json& p : page["points"]) all.push_back(p);
    if (page["next_cursor"].is_null()) break;
    cursor = std::to_string(page["next_cursor"].get<int64_t>());
  }
  std::cout << json({{"points", all}}).dump(2) << "\n";
}

}  // namespace

int RunResults(const std::vector<std::string>& argv) {
  const Args args(argv, {"--server", "--token", "--branch", "--amplitude-v"}, {"--csv", "--help"});
  if (args.Has("--help") || args.Positional().size() != 1) {
    (args.Has("--help") ? std::cout : std::cerr) << kResultsHelp;
    return args.Has("--help") ? 0 : 2;
  }
  const int64_t id = JobIdArgument(args.Positional()[0]);
  const Connection c = Connect(args);
  httplib::Client client = c.client();
  // The job's kind says where its results are: a sweep's points, a fit's or diagnosis's document.
  const json job = Expect(client.Get("/v1/jobs/" + std::to_string(id), Headers(c.token)), 200, "results", &c);
  const std::string kind = job.value("kind", "");
  if (kind == "sweep") {
    PrintSweepPoints(args, c, id);
    return 0;
  }
  if (kind != "fit" && kind != "diagnose")
    throw std::runtime_error("results: job " + std::to_string(id) + " is a " + kind +
                             " job, whose results the service does not serve (only sweep, fit and diagnose jobs)");
  for (const char* flag : {"--csv", "--branch", "--amplitude-v"})
    if (args.Has(flag))
      throw InputError(flag, "applies to sweep jobs; job " + std::to_string(id) + " is a " + kind +
                                 " job, whose result is one JSON document");
  const json result = Expect(client.Get("/v1/jobs/" + std::to_string(id) + "/result", Headers(c.token)), 200,
                             "results", &c);
  std::cout << result.dump(2) << "\n";
  return 0;
}

}  // namespace strokelab::cli
