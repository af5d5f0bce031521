// Load figures for the service on loopback (not a ctest test: timings are not pass/fail).
//
// Starts `strokelab serve --port 0` on a scratch database (or uses --server URL), submits a large
// sweep, and while it runs measures, in phases of --seconds each:
//   idle     no client load: the rate of result rows written to SQLite (from /metrics);
//   status   --threads clients looping on GET /v1/jobs/{id};
//   points   --threads clients paging GET /v1/jobs/{id}/points?limit=1000 (each follows
//            next_cursor through the rows stored so far and starts over at the end);
// and prints requests per second, latency percentiles and the rows-written rate per phase.
//
// With --baseline it then waits for the sweep to finish and repeats status and points on the
// quiet server, which separates the cost of a request from the wait behind the writer.
//
//   service_load [--binary PATH] [--server URL] [--workers 1] [--threads 4] [--seconds 5]
//                [--frequency-points 1000] [--amplitude-points 200] [--baseline] [--json]
#include <httplib.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "bench_server.h"

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

struct Options : strokelab::bench::LoadOptions {
  int workers = 1, threads = 4;
  bool baseline = false;
};

Options Parse(int argc, char** argv) {
  Options o;
  o.binary = STROKELAB_BINARY;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (strokelab::bench::TakeLoadFlag(argc, argv, i, o)) continue;
    if (a == "--workers") o.workers = std::stoi(strokelab::bench::FlagValue(argc, argv, i));
    else if (a == "--threads") o.threads = std::stoi(strokelab::bench::FlagValue(argc, argv, i));
    else if (a == "--baseline") o.baseline = true;
    else if (a == "--help") {
      std::printf(
          "usage: service_load [--binary PATH] [--server http://127.0.0.1:PORT] [--workers 1] [--threads 4]\n"
          "                    [--seconds 5] [--frequency-points 1000] [--amplitude-points 200] [--baseline] [--json]\n"
          "  --baseline: afterwards, wait for the sweep to finish and measure status and points again on\n"
          "              the quiet server (phases status-after, points-after).\n");
      std::exit(0);
    } else {
      throw std::runtime_error("unknown option " + a);
    }
  }
  return o;
}

double RowsWritten(httplib::Client& c) {
  auto r = c.Get("/metrics");
  if (!r || r->status != 200) throw std::runtime_error("GET /metrics failed");
  const std::string key = "\nstrokelab_result_rows_written_total ";
  const size_t at = r->body.find(key);
  return at == std::string::npos ? 0 : std::atof(r->body.c_str() + at + key.size());
}

struct PhaseResult {
  std::string name;
  double seconds = 0;
  size_t requests = 0, errors = 0, bytes = 0;
  std::vector<double> latencies_ms;
  double rows_per_s = 0;
  int tasks_done_before = 0, tasks_done_after = 0;
  double Percentile(double q) const { return strokelab::bench::Percentile(latencies_ms, q); }
};

int TasksDone(httplib::Client& c, int64_t id) {
  auto r = c.Get("/v1/jobs/" + std::to_string(id));
  if (!r || r->status != 200) throw std::runtime_error("GET job failed");
  return json::parse(r->body)["progress"]["done"];
}

// `kind`: "idle", "status" or "points".
PhaseResult RunPhase(const std::string& kind, const Options& o, const std::string& host, int port, int64_t id) {
  PhaseResult result;
  result.name = kind;
  httplib::Client probe(host, port);
  probe.set_read_timeout(30);
  result.tasks_done_before = TasksDone(probe, id);
  const double rows0 = RowsWritten(probe);
  const auto start = Clock::now();
  std::vector<std::vector<double>> latencies(o.threads);
  std::vector<size_t> errors(o.threads), bytes(o.threads);
  std::vector<std::thread> threads;
  if (kind != "idle") {
    for (int t = 0; t < o.threads; ++t) {
      threads.emplace_back([&, t] {
        httplib::Client c(host, port);
        c.set_keep_alive(true);
        c.set_read_timeout(30);
        std::string cursor = "0";
        while (Since(start) < o.seconds) {
          const std::string path = kind == "status"
                                       ? "/v1/jobs/" + std::to_string(id)
                                       : "/v1/jobs/" + std::to_string(id) + "/points?limit=1000&cursor=" + cursor;
          const auto t0 = Clock::now();
          auto r = c.Get(path);
          const double ms = Since(t0) * 1e3;
          if (!r || r->status != 200) {
            ++errors[t];
            continue;
          }
          latencies[t].push_back(ms);
          bytes[t] += r->body.size();
          if (kind == "points") {  // next_cursor without parsing the whole page (the client shares the CPUs)
            const size_t at = r->body.rfind("\"next_cursor\":");
            const long long next = at == std::string::npos ? 0 : std::atoll(r->body.c_str() + at + 14);
            cursor = std::to_string(next);
          }
        }
      });
    }
    for (auto& th : threads) th.join();
  } else {
    std::this_thread::sleep_for(std::chrono::duration<double>(o.seconds));
  }
  result.seconds = Since(start);
  result.rows_per_s = (RowsWritten(probe) - rows0) / result.seconds;
  result.tasks_done_after = TasksDone(probe, id);
  for (int t = 0; t < o.threads; ++t) {
    result.latencies_ms.insert(result.latencies_ms.end(), latencies[t].begin(), latencies[t].end());
    result.errors += errors[t];
    result.bytes += bytes[t];
  }
  result.requests = result.latencies_ms.size();
  return result;
}

}  // namespace

int main(int argc, char** argv) try {
  const Options o = Parse(argc, argv);
  strokelab::bench::ServerProcess owned;
  const auto [host, port] = strokelab::bench::ServerToLoad(o.server, owned, o.binary, {"--workers", std::to_string(o.workers)});
  httplib::Client c(host, port);
  c.set_read_timeout(30);
  const json job = {{"kind", "sweep"},
                    {"name", "service_load"},
                    {"model", "paper"},
                    {"grid", {{"frequency_hz", {{"from", 5}, {"to", 50}, {"points", o.frequency_points}}},
                              {"amplitude_v", {{"from", 0.1}, {"to", 0.6}, {"points", o.amplitude_points}}}}}};
  auto r = c.Post("/v1/jobs", job.dump(), "application/json");
  if (!r || r->status != 201) throw std::runtime_error("submit failed: " + (r ? r->body : httplib::to_string(r.error())));
  const int64_t id = json::parse(r->body)["id"];
  // Let some rows land so that the first pages of points exist.
  for (const auto start = Clock::now(); TasksDone(c, id) < 3 && Since(start) < 60;) usleep(50000);

  std::vector<PhaseResult> phases;
  for (const std::string kind : {"idle", "status", "points"}) phases.push_back(RunPhase(kind, o, host, port, id));
  const json status = json::parse(c.Get("/v1/jobs/" + std::to_string(id))->body);
  if (o.baseline) {
    for (const auto start = Clock::now(); Since(start) < 600;) {
      const json s = json::parse(c.Get("/v1/jobs/" + std::to_string(id))->body);
      if (s["status"] != "running" && s["status"] != "queued") break;
      usleep(200000);
    }
    for (const std::string kind : {"status", "points"}) {
      phases.push_back(RunPhase(kind, o, host, port, id));
      phases.back().name += "-after";
    }
  }

  json out = {{"server_workers", o.workers}, {"client_threads", o.threads},
              {"grid", std::to_string(o.frequency_points) + "x" + std::to_string(o.amplitude_points)},
              {"job_status_after", status["status"]}, {"phases", json::array()}};
  for (const PhaseResult& p : phases) {
    out["phases"].push_back({{"phase", p.name}, {"seconds", p.seconds}, {"requests", p.requests},
                             {"errors", p.errors}, {"requests_per_s", p.requests / p.seconds},
                             {"p50_ms", p.Percentile(0.50)}, {"p99_ms", p.Percentile(0.99)},
                             {"max_ms", p.Percentile(1.0)}, {"mean_response_bytes", p.requests ? p.bytes / p.requests : 0},
                             {"rows_written_per_s", p.rows_per_s},
                             {"tasks_done", {p.tasks_done_before, p.tasks_done_after}}});
  }
  if (o.json_out) {
    std::printf("%s\n", out.dump(2).c_str());
  } else {
    std::printf("service load: %d in-process worker(s), %d client threads, %.0f s per phase, sweep %s (%s after)\n",
                o.workers, o.threads, o.seconds, out["grid"].get<std::string>().c_str(),
                status["status"].get<std::string>().c_str());
    std::printf("%-13s %9s %8s %10s %9s %9s %9s %10s %14s\n", "phase", "requests", "errors", "req/s", "p50 ms",
                "p99 ms", "max ms", "bytes/req", "rows written/s");
    for (const PhaseResult& p : phases)
      std::printf("%-13s %9zu %8zu %10.0f %9.3f %9.3f %9.3f %10zu %14.0f\n", p.name.c_str(), p.requests, p.errors,
                  p.requests / p.seconds, p.Percentile(0.5), p.Percentile(0.99), p.Percentile(1.0),
                  p.requests ? p.bytes / p.requests : 0, p.rows_per_s);
  }
  if (status["status"] != "running")
    std::fprintf(stderr, "warning: the sweep was no longer running at the end; use a larger grid\n");
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "service_load: %s\n", e.what());
  return 1;
}
