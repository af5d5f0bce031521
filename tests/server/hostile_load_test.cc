// Issue 15's hostile-load test: the real `strokelab serve` (tokens on, one worker) runs a sweep while
// slow clients, oversized and deeply nested bodies and unauthenticated floods are thrown at it.
// Every /v1/health probe (one every 100 ms, on a fresh connection) must be answered 200 within 2 s,
// the sweep must complete with exactly the points the same sweep has in process, and the server's
// RSS must come back within 20 % of its start. The probes' p50 and p99 are printed, not asserted.
// The attackers come from other loopback addresses than the probe (127.0.0.2 and .3), as they would
// from other hosts: the per-address cap on connections still sending headers is not what is tested.
//
// 10 s of attack in the test command (HostileLoad.TenSeconds; STROKELAB_HOSTILE_LOAD_S=N sets
// another length), 30 s under the `slow` label (HostileLoad.ThirtySeconds).
#include <gtest/gtest.h>
#include <httplib.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "raw_db.h"
#include "raw_http.h"
#include "serve_child.h"
#include "strokelab/jobs/job_spec.h"
#include "strokelab/sweep/sweep.h"
#include "test_tokens.h"

namespace strokelab::testing {
namespace {

using nlohmann::json;
using LoadClock = std::chrono::steady_clock;

// Under AddressSanitizer (its quarantine) and ThreadSanitizer (its shadow) RSS grows by design and
// everything runs several times slower: there the attack is shorter, RSS is not checked and a probe
// may take 10 s; what they look for (races, leaks, overflows) is still attacked.
constexpr double kHealthDeadlineS = kSanitizedBuild ? 10.0 : 2.0;
constexpr double kRssSlack = 0.20;

// A sweep of 9,000 grid points (~13,000 points with the bistable branches): a few seconds on one
// worker, so that it runs while the attack does.
const json kLoadSweep = {{"kind", "sweep"},
                         {"model", "paper"},
                         {"thresholds", false},
                         {"grid",
                          {{"frequency_hz", {{"from", 5}, {"to", 20}, {"points", 300}, {"spacing", "linear"}}},
                           {"amplitude_v", {{"from", 0.1}, {"to", 0.6}, {"points", 30}}}}}};

double Since(LoadClock::time_point start) { return std::chrono::duration<double>(LoadClock::now() - start).count(); }

double Percentile(std::vector<double> values, double p) {
  if (values.empty()) return NAN;
  std::sort(values.begin(), values.end());
  return values[std::min(values.size() - 1, static_cast<size_t>(p * static_cast<double>(values.size())))];
}

class Attack {
 public:
  Attack(int port, double seconds) : port_(port), end_(LoadClock::now() + std::chrono::duration_cast<LoadClock::duration>(std::chrono::duration<double>(seconds))) {}
  bool Over() const { return LoadClock::now() >= end_; }

  // 16 connections from 127.0.0.2 sending their headers one byte a second (408 after 10 s; reopened).
  void SlowClients() {
    const std::string request = "GET /v1/jobs HTTP/1.1\r\nHost: x\r\nX-Slow: " + std::string(64, 's') + "\r\n\r\n";
    std::vector<std::unique_ptr<RawConnection>> connections(16);
    std::vector<size_t> sent(connections.size(), 0);
    while (!Over()) {
      for (size_t i = 0; i < connections.size(); ++i) {
        try {
          if (!connections[i] || sent[i] == request.size() || !connections[i]->Send(request.substr(sent[i], 1))) {
            connections[i] = std::make_unique<RawConnection>(port_, "127.0.0.2");
            sent[i] = 0;
          } else {
            ++sent[i];
          }
        } catch (const std::exception&) {
          connections[i].reset();
        }
      }
      std::this_thread::sleep_for(std::chrono::seconds(1));
    }
  }

  // Oversized bodies from 127.0.0.3: 200 MB declared with no token and with one, and a chunked body
  // that goes past the 1 MiB limit; each refused on its headers or at the limit, never read whole.
  void OversizedBodies() {
    const std::string mib(1 << 20, 'x');
    for (int round = 0; !Over(); ++round) {
      try {
        RawConnection c(port_, "127.0.0.3");
        const bool chunked = round % 3 == 2;
        const std::string auth = round % 3 == 1 ? std::string("Authorization: Bearer ") + kSubmitToken + "\r\n" : "";
        const std::string path = round % 3 == 0 ? "/v1/campaigns" : "/v1/jobs";
        const std::string type = round % 3 == 0 ? "application/x-tar" : "application/json";
        c.Send("POST " + path + " HTTP/1.1\r\nHost: x\r\n" + auth + "Content-Type: " + type + "\r\n" +
               (chunked ? "Transfer-Encoding: chunked\r\n\r\n" : "Content-Length: 200000000\r\n\r\n"));
        for (int i = 0; i < 4; ++i) {
          const std::string piece = chunked ? "100000\r\n" + mib + "\r\n" : mib;
          if (!c.Send(piece)) break;
        }
        statuses_.Add(c.Status());
      } catch (const std::exception&) {
      }
    }
  }

  // Deeply nested JSON with a submit token (400 bad_json), 200,000 levels in 400 KB, from 127.0.0.3.
  void DeepBodies() {
    const std::string deep = std::string(200000, '[') + std::string(200000, ']');
    const std::string request = std::string("POST /v1/jobs HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer ") +
                                kSubmitToken + "\r\nContent-Type: application/json\r\nContent-Length: " +
                                std::to_string(deep.size()) + "\r\nConnection: close\r\n\r\n" + deep;
    while (!Over()) statuses_.Add(OneRequest(request));
  }

  // Requests without a token from 127.0.0.3, one per connection, as fast as they are answered (401).
  void UnauthenticatedFlood() {
    const std::string body = "{\"kind\":\"sweep\"}";
    const std::string get = "GET /v1/jobs HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n";
    const std::string post = "POST /v1/jobs HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: " +
                             std::to_string(body.size()) + "\r\nConnection: close\r\n\r\n" + body;
    for (int i = 0; !Over(); ++i) statuses_.Add(OneRequest(i % 2 ? get : post));
  }

  // One request on a connection of its own from 127.0.0.3: the reply's status (0: none).
  int OneRequest(const std::string& request) {
    try {
      RawConnection c(port_, "127.0.0.3");
      return c.Send(request) ? c.Status() : 0;
    } catch (const std::exception&) {
      return 0;
    }
  }

  struct Statuses {
    std::mutex mutex;
    std::map<int, int> counts;
    void Add(int status) {
      std::lock_guard<std::mutex> lock(mutex);
      ++counts[status];
    }
    std::string Text() {
      std::lock_guard<std::mutex> lock(mutex);
      std::string text;
      for (const auto& [status, n] : counts) text += " " + std::to_string(status) + ": " + std::to_string(n);
      return text;
    }
  };
  Statuses statuses_;

 private:
  int port_;
  LoadClock::time_point end_;
};

void RunHostileLoad(double attack_s) {
  ScratchDirectory dir("hostile-load");
  std::ofstream(dir.path() / "tokens") << "submit " << kSubmitToken << "\nread " << kReadToken << "\nworker "
                                       << kWorkerToken << "\n";
  const fs::path db = dir.path() / "jobs.db";
  ServeChild serve(db, dir.path() / "serve.log",
                   {"--workers", "1", "--token-file", (dir.path() / "tokens").string(), "--quiet"});
  auto client = serve.Client();
  const httplib::Headers submit = {{"Authorization", std::string("Bearer ") + kSubmitToken}};
  const httplib::Headers read = {{"Authorization", std::string("Bearer ") + kReadToken}};
  // RSS at the start is taken once the server has run a sweep as large and answered ordinary requests
  // on all its HTTP threads: what they first page in (code, thread stacks, SQLite's cache) is not
  // what an attack leaves behind.
  const auto wait_for = [&](int64_t id, double seconds) {
    std::string status;
    for (const LoadClock::time_point start = LoadClock::now(); status != "succeeded" && status != "failed" && Since(start) < seconds;) {
      auto r = client->Get("/v1/jobs/" + std::to_string(id), read);
      status = r && r->status == 200 ? json::parse(r->body).value("status", "") : "";
      if (status != "succeeded") std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return status;
  };
  json warm_up = kLoadSweep;  // as large, on another grid (not served from the result cache)
  warm_up["grid"]["amplitude_v"]["to"] = 0.61;
  auto warm = client->Post("/v1/jobs", submit, warm_up.dump(), "application/json");
  ASSERT_TRUE(warm && warm->status == 201) << (warm ? warm->body : "no reply");
  ASSERT_EQ(wait_for(json::parse(warm->body).at("id").get<int64_t>(), 60), "succeeded");
  {
    std::vector<std::thread> readers;  // ordinary requests on every HTTP thread
    for (int i = 0; i < 10; ++i)
      readers.emplace_back([&] {
        httplib::Client reader("127.0.0.1", serve.port());
        for (int k = 0; k < 20; ++k) reader.Get(k % 2 ? "/v1/jobs" : "/v1/health", read);
      });
    for (std::thread& t : readers) t.join();
  }
  const long rss_start_kib = serve.RssKib();
  auto submitted = client->Post("/v1/jobs", submit, kLoadSweep.dump(), "application/json");
  ASSERT_TRUE(submitted && submitted->status == 201) << (submitted ? submitted->body : "no reply");
  const int64_t job = json::parse(submitted->body).at("id").get<int64_t>();

  Attack attack(serve.port(), attack_s);
  std::vector<std::thread> attackers;
  attackers.emplace_back([&] { attack.SlowClients(); });
  attackers.emplace_back([&] { attack.OversizedBodies(); });
  attackers.emplace_back([&] { attack.DeepBodies(); });
  attackers.emplace_back([&] { attack.UnauthenticatedFlood(); });
  attackers.emplace_back([&] { attack.UnauthenticatedFlood(); });
  std::vector<double> latencies_s;
  int unanswered = 0;
  std::string failures;
  long rss_peak_kib = rss_start_kib;
  while (!attack.Over()) {
    const LoadClock::time_point start = LoadClock::now();
    httplib::Client probe("127.0.0.1", serve.port());
    probe.set_connection_timeout(static_cast<time_t>(kHealthDeadlineS));
    probe.set_read_timeout(static_cast<time_t>(kHealthDeadlineS));
    const auto r = probe.Get("/v1/health");
    const double seconds = Since(start);
    if (!r || r->status != 200 || seconds > kHealthDeadlineS) {
      ++unanswered;
      failures += " " + (r ? std::to_string(r->status) : httplib::to_string(r.error())) + " after " +
                  std::to_string(seconds) + " s;";
    } else {
      latencies_s.push_back(seconds);
    }
    rss_peak_kib = std::max(rss_peak_kib, serve.RssKib());
    std::this_thread::sleep_for(std::chrono::milliseconds(100) - (LoadClock::now() - start));
  }
  for (std::thread& t : attackers) t.join();
  const LoadClock::time_point attack_end = LoadClock::now();

  // The sweep: done (it may finish during the attack or after it), with exactly its points.
  ASSERT_EQ(wait_for(job, 120), "succeeded");
  const double sweep_after_attack_s = Since(attack_end);
  const double sweep_s = json::parse(client->Get("/v1/jobs/" + std::to_string(job), read)->body).value("elapsed_s", 0.0);
  RawDb raw(db.string(), SQLITE_OPEN_READONLY);
  const std::string stored =
      raw.Text("SELECT sum(rows) FROM result_blocks WHERE table_name = 'points' AND job_id = " + std::to_string(job));
  const SweepResult reference = RunSweep(jobs::SweepSpecFromJob(kLoadSweep));
  EXPECT_EQ(stored, std::to_string(reference.points.size())) << "the sweep's points, against the same sweep in process";

  std::this_thread::sleep_for(std::chrono::seconds(1));
  const long rss_end_kib = serve.RssKib();
  std::printf("[          ] %.0f s of attack (statuses:%s): %zu health probes answered, %d not; p50 %.1f ms, "
              "p99 %.1f ms, max %.1f ms; the sweep (%s points) ran %.1f s and was done %.1f s after the attack ended; RSS %ld KiB at the "
              "start, %ld KiB at the peak, %ld KiB after\n",
              attack_s, attack.statuses_.Text().c_str(), latencies_s.size(), unanswered,
              1e3 * Percentile(latencies_s, 0.5), 1e3 * Percentile(latencies_s, 0.99),
              1e3 * Percentile(latencies_s, 1.0), stored.c_str(), sweep_s, sweep_after_attack_s,
              rss_start_kib, rss_peak_kib, rss_end_kib);
  EXPECT_EQ(unanswered, 0) << failures;
  EXPECT_GT(latencies_s.size(), 5 * attack_s);
  if (!kSanitizedBuild) {
    EXPECT_LE(rss_end_kib, static_cast<long>((1 + kRssSlack) * static_cast<double>(rss_start_kib)))
        << "RSS did not come back after the attack";
  }
  EXPECT_EQ(serve.Stop(), 0);
}

TEST(HostileLoad, TenSeconds) {
  const char* env = std::getenv("STROKELAB_HOSTILE_LOAD_S");
  RunHostileLoad(env ? std::atof(env) : kSanitizedBuild ? 6.0 : 10.0);
}

TEST(HostileLoad, ThirtySeconds) { RunHostileLoad(30.0); }

}  // namespace
}  // namespace strokelab::testing
