// The strokelab service as a child process for tests: start `strokelab serve --port 0` and read
// its port from the "serving" line, start remote workers, and the few HTTP calls tests make.
// STROKELAB_BINARY is the strokelab CLI (defined by strokelab_add_test).
#pragma once

#include <httplib.h>

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "process/child.h"

namespace strokelab::test_process {

using nlohmann::json;

// A `strokelab serve --port 0` process and the port it reported.
struct Server {
  std::unique_ptr<Child> child;
  int port = 0;
  std::string Url() const { return "http://127.0.0.1:" + std::to_string(port); }
};

// `wrapper` runs before the binary (e.g. {"/usr/bin/prlimit", "--fsize=N", "--"}).
inline Server StartServer(const fs::path& dir, const std::string& name, const std::vector<std::string>& extra,
                          const std::vector<std::string>& wrapper = {}) {
  std::vector<std::string> argv = wrapper;
  argv.insert(argv.end(), {STROKELAB_BINARY, "serve", "--port", "0"});
  argv.insert(argv.end(), extra.begin(), extra.end());
  Server s;
  s.child = std::make_unique<Child>(argv, dir / (name + ".log"));
  const std::string marker = "strokelab serving http://127.0.0.1:";
  const auto start = Clock::now();
  for (;;) {
    const std::string log = s.child->Log();
    if (const size_t at = log.find(marker); at != std::string::npos) {
      s.port = std::atoi(log.c_str() + at + marker.size());
      if (s.port > 0) return s;
    }
    if (const auto code = s.child->Poll())
      throw std::runtime_error("server " + name + " exited with " + std::to_string(*code) + ":\n" + log);
    if (SecondsSince(start) > 15) throw std::runtime_error("server " + name + " did not come up in 15 s:\n" + log);
    SleepMs(5);
  }
}

inline std::unique_ptr<Child> StartWorker(const fs::path& dir, const Server& server, const std::string& name,
                                   const std::vector<std::string>& extra) {
  std::vector<std::string> argv = {STROKELAB_BINARY, "worker", "--server", server.Url(), "--name", name};
  argv.insert(argv.end(), extra.begin(), extra.end());
  return std::make_unique<Child>(argv, dir / (name + ".log"));
}

inline httplib::Headers Bearer(const std::string& token) {
  if (token.empty()) return {};
  return {{"Authorization", "Bearer " + token}};
}

inline std::unique_ptr<httplib::Client> Client(const Server& s) {
  auto c = std::make_unique<httplib::Client>("127.0.0.1", s.port);
  c->set_connection_timeout(5);
  c->set_read_timeout(30);
  return c;
}

inline json GetJson(httplib::Client& c, const std::string& path, const std::string& token = "") {
  auto r = c.Get(path, Bearer(token));
  if (!r) throw std::runtime_error("GET " + path + ": " + httplib::to_string(r.error()));
  if (r->status != 200) throw std::runtime_error("GET " + path + ": HTTP " + std::to_string(r->status) + " " + r->body);
  return json::parse(r->body);
}

inline int64_t Submit(httplib::Client& c, const json& job, const std::string& token = "") {
  auto r = c.Post("/v1/jobs", Bearer(token), job.dump(), "application/json");
  if (!r) throw std::runtime_error("POST /v1/jobs: " + httplib::to_string(r.error()));
  if (r->status != 201) throw std::runtime_error("POST /v1/jobs: HTTP " + std::to_string(r->status) + " " + r->body);
  return json::parse(r->body).at("id").get<int64_t>();
}

inline json SweepJob(int frequency_points, int amplitude_points, bool thresholds) {
  return {{"kind", "sweep"},
          {"model", "paper"},
          {"thresholds", thresholds},
          {"grid", {{"frequency_hz", {{"from", 5}, {"to", 50}, {"points", frequency_points}}},
                    {"amplitude_v", {{"from", 0.1}, {"to", 0.6}, {"points", amplitude_points}}}}}};
}

// Polls GET /v1/jobs/{id} every `poll_ms` until it is no longer queued or running.
inline json WaitForFinish(httplib::Client& c, int64_t id, double timeout_s, const std::string& token = "", int poll_ms = 20) {
  const auto start = Clock::now();
  for (;;) {
    const json job = GetJson(c, "/v1/jobs/" + std::to_string(id), token);
    const std::string status = job.at("status");
    if (status != "queued" && status != "running") return job;
    if (SecondsSince(start) > timeout_s)
      throw std::runtime_error("job " + std::to_string(id) + " not finished after " + std::to_string(timeout_s) +
                               " s: " + job.dump());
    SleepMs(poll_ms);
  }
}

// Every row of a job's points (optionally one branch), following the cursors, pages of 1000.
inline std::vector<json> FetchPoints(httplib::Client& c, int64_t id, const std::string& branch = "",
                              const std::string& token = "") {
  std::vector<json> rows;
  std::string cursor = "0";
  for (int pages = 0; pages < 100000; ++pages) {
    std::string path = "/v1/jobs/" + std::to_string(id) + "/points?limit=1000&cursor=" + cursor;
    if (!branch.empty()) path += "&branch=" + branch;
    const json page = GetJson(c, path, token);
    for (const json& p : page.at("points")) rows.push_back(p);
    if (page.at("next_cursor").is_null()) return rows;
    cursor = std::to_string(page.at("next_cursor").get<int64_t>());
  }
  throw std::runtime_error("points: cursor does not end");
}

}  // namespace strokelab::test_process
