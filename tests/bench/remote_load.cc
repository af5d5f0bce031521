// Load figures for the service with many remote workers (not a ctest test: timings are not
// pass/fail). Starts `strokelab serve --workers 0` on a scratch database (or uses --server URL),
// submits --jobs points-only sweeps (a job has at most 200,000 grid points: 200 tasks of 1000
// frequencies each), and runs --remote-workers simulated workers, each a thread with its own
// kept-alive HTTP connection that loops: POST /v1/tasks/lease, then POST /v1/tasks/{id}/complete
// with prepared rows. The rows are real: one sweep row of the paper model on the job's frequencies,
// computed once here (jobs::RunTask), sent for every task with the task's amplitude written in (the
// jobs' amplitudes differ, so no task is another's cache entry), so
// the server parses, checks (jobs/task_rows.h) and stores them as it does a real worker's. No
// worker computes: the figures are what the server sustains. Meanwhile --status-pollers threads
// read GET /v1/jobs/{id} of the first job every 10 ms.
//
// For --seconds from the first completion it prints: completions and result rows accepted per
// second, the latency of lease, complete and status requests (p50, p99, max), and refusals.
//
//   remote_load [--binary PATH] [--server URL] [--remote-workers 64] [--seconds 10]
//               [--jobs 8] [--frequency-points 1000] [--amplitude-points 200] [--status-pollers 2] [--json]
#include <httplib.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "bench_server.h"
#include "strokelab/jobs/jobs.h"

namespace {

using nlohmann::json;
using strokelab::bench::Percentile;
using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

struct Options : strokelab::bench::LoadOptions {
  int remote_workers = 64, status_pollers = 2, jobs = 8;
};

Options Parse(int argc, char** argv) {
  Options o;
  o.binary = STROKELAB_BINARY;
  o.seconds = 10;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (strokelab::bench::TakeLoadFlag(argc, argv, i, o)) continue;
    const auto next = [&] { return strokelab::bench::FlagValue(argc, argv, i); };
    if (a == "--remote-workers") o.remote_workers = std::stoi(next());
    else if (a == "--status-pollers") o.status_pollers = std::stoi(next());
    else if (a == "--jobs") o.jobs = std::stoi(next());
    else if (a == "--help") {
      std::printf(
          "usage: remote_load [--binary PATH] [--server http://127.0.0.1:PORT] [--remote-workers 64] [--seconds 10]\n"
          "                   [--jobs 8] [--frequency-points 1000] [--amplitude-points 200] [--status-pollers 2] [--json]\n");
      std::exit(0);
    } else {
      throw std::runtime_error("unknown option " + a);
    }
  }
  if (o.remote_workers < 1 || o.status_pollers < 0 || o.jobs < 1 || o.seconds <= 0)
    throw std::runtime_error("bad option value");
  return o;
}

// Job `j` of the run: the same frequencies, amplitudes shifted by j mV.
json SweepJob(const Options& o, int j) {
  return {{"kind", "sweep"},
          {"name", "remote_load-" + std::to_string(j)},
          {"model", "paper"},
          {"thresholds", false},
          {"grid", {{"frequency_hz", {{"from", 5}, {"to", 50}, {"points", o.frequency_points}}},
                    {"amplitude_v", {{"from", 0.1 + 1e-3 * j}, {"to", 0.6 + 1e-3 * j}, {"points", o.amplitude_points}}}}}};
}

// The completion's "rows" array for the job's first task, split where its amplitude stands, so that
// any task's rows are the pieces joined by that task's amplitude.
struct RowsTemplate {
  std::vector<std::string> pieces;
  size_t rows = 0;
  std::string For(double amplitude_v) const {
    const std::string a = json(amplitude_v).dump();
    std::string out;
    out.reserve(pieces.size() * a.size() + pieces.front().size() * pieces.size());
    for (size_t i = 0; i < pieces.size(); ++i) {
      if (i > 0) out += a;
      out += pieces[i];
    }
    return out;
  }
};

RowsTemplate MakeRowsTemplate(const Options& o) {
  const json task = strokelab::jobs::PlanTasks(SweepJob(o, 0)).at(0).spec;
  json rows = json::array();
  for (const strokelab::jobs::ResultRow& r : strokelab::jobs::RunTask(task).AllRows())
    rows.push_back({{"table", r.table}, {"values", r.values}});
  const std::string text = rows.dump();
  const std::string key = "\"amplitude_v\":", value = task.at("amplitude_v").dump();
  RowsTemplate t;
  t.rows = rows.size();
  size_t from = 0;
  for (size_t at; (at = text.find(key + value, from)) != std::string::npos; from = at + key.size() + value.size())
    t.pieces.push_back(text.substr(from, at + key.size() - from));  // up to the amplitude's value
  t.pieces.push_back(text.substr(from));
  return t;
}

struct Latencies {
  std::mutex mu;
  std::vector<double> ms;
  void Add(const std::vector<double>& more) {
    std::lock_guard lock(mu);
    ms.insert(ms.end(), more.begin(), more.end());
  }
  json Summary() { return {{"p50", Percentile(ms, 0.5)}, {"p99", Percentile(ms, 0.99)}, {"max", Percentile(ms, 1)}}; }
};

}  // namespace

int main(int argc, char** argv) try {
  const Options o = Parse(argc, argv);
  strokelab::bench::ServerProcess owned;
  const auto [host, port] = strokelab::bench::ServerToLoad(o.server, owned, o.binary, {"--workers", "0"});
  const RowsTemplate rows_template = MakeRowsTemplate(o);

  httplib::Client c(host, port);
  c.set_read_timeout(60);
  int64_t job_id = 0;  // the first
  for (int j = 0; j < o.jobs; ++j) {
    auto r = c.Post("/v1/jobs", SweepJob(o, j).dump(), "application/json");
    if (!r || r->status != 201) throw std::runtime_error("submit failed: " + (r ? r->body : httplib::to_string(r.error())));
    if (j == 0) job_id = json::parse(r->body)["id"];
  }

  // The window opens at the first accepted completion and closes --seconds later.
  std::atomic<bool> stop{false};
  std::atomic<int64_t> window_start_ns{0};
  const auto in_window = [&] { return window_start_ns.load() != 0 && !stop; };
  std::atomic<int64_t> completions{0}, refused{0}, errors{0}, idle_polls{0};
  Latencies lease_ms, complete_ms, status_ms;

  std::vector<std::thread> threads;
  for (int w = 0; w < o.remote_workers; ++w) {
    threads.emplace_back([&, w] {
      httplib::Client client(host, port);
      client.set_keep_alive(true);
      client.set_read_timeout(120);
      const std::string lease_body = json({{"worker", "load-" + std::to_string(w)}}).dump();
      std::vector<double> leases, completes;
      while (!stop) {
        auto t0 = Clock::now();
        auto lease = client.Post("/v1/tasks/lease", lease_body, "application/json");
        if (in_window()) leases.push_back(Since(t0) * 1e3);
        if (!lease || (lease->status != 200 && lease->status != 204)) {
          ++errors;
          std::this_thread::sleep_for(std::chrono::milliseconds(50));
          continue;
        }
        if (lease->status == 204) {
          ++idle_polls;
          std::this_thread::sleep_for(std::chrono::milliseconds(20));
          continue;
        }
        const json task = json::parse(lease->body);
        const std::string body = "{\"job_id\":" + task.at("job_id").dump() + ",\"lease_token\":" +
                                 task.at("lease_token").dump() + ",\"rows\":" +
                                 rows_template.For(task.at("spec").at("amplitude_v").get<double>()) + "}";
        t0 = Clock::now();
        auto done = client.Post("/v1/tasks/" + task.at("task_id").dump() + "/complete", body, "application/json");
        const bool counted = in_window();
        if (counted) completes.push_back(Since(t0) * 1e3);
        if (done && done->status == 200) {
          if (window_start_ns.load() == 0) {
            int64_t expected = 0;
            window_start_ns.compare_exchange_strong(expected, Clock::now().time_since_epoch().count());
          } else if (counted) {
            ++completions;
          }
        } else if (done && done->status == 409) {
          ++refused;
        } else {
          ++errors;
          if (done && errors < 5) std::fprintf(stderr, "complete: HTTP %d %s\n", done->status, done->body.substr(0, 200).c_str());
        }
      }
      lease_ms.Add(leases);
      complete_ms.Add(completes);
    });
  }
  for (int p = 0; p < o.status_pollers; ++p) {
    threads.emplace_back([&] {
      httplib::Client client(host, port);
      client.set_keep_alive(true);
      client.set_read_timeout(60);
      std::vector<double> polls;
      while (!stop) {
        const auto t0 = Clock::now();
        auto status = client.Get("/v1/jobs/" + std::to_string(job_id));
        if (in_window()) polls.push_back(Since(t0) * 1e3);
        if (!status || status->status != 200) ++errors;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
      status_ms.Add(polls);
    });
  }
  while (window_start_ns.load() == 0) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  const Clock::time_point window_start{Clock::duration(window_start_ns.load())};
  std::this_thread::sleep_for(std::chrono::duration<double>(o.seconds) - (Clock::now() - window_start));
  stop = true;
  const double window_s = Since(window_start);
  for (std::thread& t : threads) t.join();
  const json job = json::parse(c.Get("/v1/jobs/" + std::to_string(job_id))->body);

  const double rows_per_s = static_cast<double>(completions) * static_cast<double>(rows_template.rows) / window_s;
  const json out = {{"remote_workers", o.remote_workers},
                    {"status_pollers", o.status_pollers},
                    {"grid", std::to_string(o.frequency_points) + "x" + std::to_string(o.amplitude_points)},
                    {"rows_per_task", rows_template.rows},
                    {"window_s", window_s},
                    {"completions", completions.load()},
                    {"completions_per_s", static_cast<double>(completions) / window_s},
                    {"rows_per_s", rows_per_s},
                    {"lease_ms", lease_ms.Summary()},
                    {"complete_ms", complete_ms.Summary()},
                    {"status_ms", status_ms.Summary()},
                    {"status_reads", status_ms.ms.size()},
                    {"refused_409", refused.load()},
                    {"errors", errors.load()},
                    {"idle_polls", idle_polls.load()},
                    {"job", {{"status", job["status"]}, {"progress", job["progress"]}}}};
  if (o.json_out) {
    std::printf("%s\n", out.dump(2).c_str());
  } else {
    std::printf("remote load: %d workers, %d status pollers, sweep %s (%zu rows per task), %.1f s window\n",
                o.remote_workers, o.status_pollers, out["grid"].get<std::string>().c_str(), rows_template.rows, window_s);
    std::printf("  accepted   %8.1f completions/s  %10.0f rows/s  (%lld completions; %lld refused, %lld errors)\n",
                out["completions_per_s"].get<double>(), rows_per_s, static_cast<long long>(completions.load()),
                static_cast<long long>(refused.load()), static_cast<long long>(errors.load()));
    for (const char* k : {"lease_ms", "complete_ms", "status_ms"})
      std::printf("  %-11s p50 %8.2f ms  p99 %8.2f ms  max %8.2f ms\n", k, out[k]["p50"].get<double>(),
                  out[k]["p99"].get<double>(), out[k]["max"].get<double>());
  }
  if (job["status"] != "running")
    std::fprintf(stderr, "warning: the sweep was %s at the end, not running: use more --amplitude-points\n",
                 job["status"].get<std::string>().c_str());
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "remote_load: %s\n", e.what());
  return 1;
}
