#include "strokelab/worker/remote_worker.h"

#include <httplib.h>

#include <algorithm>
#include <filesystem>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>
#include <vector>

#include "strokelab/base/errors.h"
#include "strokelab/jobs/campaign_bundle.h"
#include "strokelab/jobs/campaigns.h"
#include "strokelab/jobs/jobs.h"
#include "strokelab/jobs/sha256.h"
#include "strokelab/sweep/sweep.h"
#include "strokelab/base/json_parse.h"

namespace strokelab::worker {
namespace {

using nlohmann::json;

httplib::Headers AuthHeaders(const std::string& token) {
  if (token.empty()) return {};
  return {{"Authorization", "Bearer " + token}};
}

void Pause(int ms, const std::atomic<bool>& stop) {
  for (int waited = 0; waited < ms && !stop; waited += 50) std::this_thread::sleep_for(std::chrono::milliseconds(50));
}

// Renews a task's lease every period_ms while it lives (the task runs), so that a task longer than
// the lease is not leased again by another worker. Its own client: httplib clients are not shared
// between threads. A renewal answered 409 (the job was cancelled or the lease lost) or the worker's
// stop raises cancel(), which the task polls (jobs::RunTask): it ends within a few ms. Other failed
// renewals are left to the completion (the server answers 409 if the lease was lost).
class LeaseKeeper {
 public:
  LeaseKeeper(const std::string& host, int port, httplib::Headers headers, std::string endpoint, std::string body,
              int period_ms, const std::atomic<bool>& stop)
      : thread_([=, this, &stop] {
          httplib::Client client(host, port);
          client.set_connection_timeout(5);
          client.set_read_timeout(10);
          auto renewed = std::chrono::steady_clock::now();
          std::unique_lock<std::mutex> lock(mutex_);
          while (!cv_.wait_for(lock, std::chrono::milliseconds(std::min(period_ms, 100)), [this] { return done_; })) {
            if (stop) cancel_ = true;
            if (std::chrono::steady_clock::now() - renewed < std::chrono::milliseconds(period_ms)) continue;
            lock.unlock();
            const auto reply = client.Post(endpoint, headers, body, "application/json");
            if (reply && reply->status == 409) cancel_ = true;
            renewed = std::chrono::steady_clock::now();
            lock.lock();
          }
        }) {}
  const std::atomic<bool>& cancel() const { return cancel_; }
  ~LeaseKeeper() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  bool done_ = false;
  std::atomic<bool> cancel_{false};
  std::thread thread_;  // last: started once the members it uses exist
};

namespace fs = std::filesystem;

// Unpacks a downloaded bundle (already checked against `sha256`) into cache/SHA256 through a scratch
// directory, so that a half-written campaign is never taken for a cached one.
fs::path StoreCampaign(const fs::path& cache, const std::string& sha256, const std::string& bundle) {
  const fs::path dir = cache / sha256;
  const fs::path incoming = cache / (".incoming-" + jobs::NewCampaignId());
  try {
    jobs::UnpackCampaignBundle(bundle, incoming);
    if (jobs::CampaignSha256(incoming) != sha256) throw std::runtime_error("campaign " + sha256 + " unpacked differently");
    std::error_code taken;
    fs::rename(incoming, dir, taken);  // fails when another thread stored it first: theirs is kept
    if (taken) fs::remove_all(incoming);
  } catch (...) {
    std::error_code ignored;
    fs::remove_all(incoming, ignored);
    throw;
  }
  return dir;
}

// The directory of the campaign `sha256` for the leased task: from the cache when its files still
// hash to it (a changed cache is dropped), else fetched with the lease's headers and checked. A
// download that fails the check is fetched again, up to three times, then the task fails with why.
fs::path FetchCampaign(httplib::Client& client, httplib::Headers headers, const fs::path& cache,
                       const std::string& sha256, const json& task, const std::atomic<bool>& stop) {
  if (!jobs::IsSha256Hex(sha256)) throw std::runtime_error("the task's campaign_sha256 is not a SHA-256");
  fs::create_directories(cache);
  const fs::path dir = cache / sha256;
  std::error_code ignored;
  if (fs::is_directory(dir)) {
    if (jobs::CampaignSha256(dir) == sha256) return dir;
    fs::remove_all(dir, ignored);
  }
  headers.emplace("X-Strokelab-Task", std::to_string(task.at("task_id").get<int64_t>()));
  headers.emplace("X-Strokelab-Job", std::to_string(task.at("job_id").get<int64_t>()));
  headers.emplace("X-Strokelab-Lease", task.at("lease_token").get<std::string>());
  std::string why = "no answer from the server";
  for (int attempt = 0; attempt < 3 && !stop; ++attempt) {
    if (attempt > 0) Pause(500, stop);
    auto reply = client.Get("/v1/campaigns/" + sha256, headers);
    if (!reply) continue;
    if (reply->status != 200)
      throw std::runtime_error("campaign " + sha256 + ": the server answered HTTP " + std::to_string(reply->status) +
                               ": " + reply->body.substr(0, 300));
    const std::string got = jobs::Sha256Hex(reply->body);
    if (got == sha256) return StoreCampaign(cache, sha256, reply->body);
    why = "the download failed its hash check (SHA-256 " + got + ", expected " + sha256 + ")";
  }
  if (stop) throw Cancelled();  // the worker stops: nothing to send, as for a running task
  throw std::runtime_error("campaign " + sha256 + ": " + why);
}

}  // namespace

std::pair<std::string, int> ParseServerUrl(const std::string& url) {
  const std::string prefix = "http://";
  if (url.rfind(prefix, 0) != 0) throw InputError("--server", "expected http://HOST:PORT, got '" + url + "'");
  std::string rest = url.substr(prefix.size());
  if (!rest.empty() && rest.back() == '/') rest.pop_back();
  const size_t colon = rest.rfind(':');
  if (colon == std::string::npos || colon == 0) throw InputError("--server", "expected http://HOST:PORT, got '" + url + "'");
  int port = 0;
  try {
    port = std::stoi(rest.substr(colon + 1));
  } catch (...) {
    port = 0;
  }
  if (port <= 0 || port > 65535) throw InputError("--server", "bad port in '" + url + "'");
  return {rest.substr(0, colon), port};
}

int IdlePollWaitMs(const RemoteWorkerOptions& options, int idle_polls) {
  int64_t wait_ms = std::max(options.idle_poll_ms, 1);
  for (int i = 1; i < idle_polls && wait_ms < options.idle_poll_max_ms; ++i) wait_ms *= 2;
  return static_cast<int>(std::min<int64_t>(wait_ms, std::max(options.idle_poll_max_ms, options.idle_poll_ms)));
}

int RunRemoteWorker(const RemoteWorkerOptions& options, const std::atomic<bool>& stop) {
  const auto [host, port] = ParseServerUrl(options.server_url);
  std::atomic<int> completed{0};
  std::atomic<bool> refused{false};
  std::string refusal;
  // For --exit-when-idle: the worker is idle when no thread holds a task, since the last lease.
  using Clock = std::chrono::steady_clock;
  const auto since_start_ms = [start = Clock::now()] {
    return std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - start).count();
  };
  std::atomic<int> busy_threads{0};
  std::atomic<int64_t> last_activity_ms{0};
  std::atomic<bool> idle_exit{false};
  auto loop = [&, host = host, port = port](int index) {
    httplib::Client client(host, port);
    client.set_connection_timeout(5);
    client.set_read_timeout(60);
    client.set_keep_alive(true);  // idle polls reuse one connection instead of a new one each
    const httplib::Headers headers = AuthHeaders(options.token);
    const std::string name = options.name + "-" + std::to_string(index);
    int idle_polls = 0;
    while (!stop && !refused && !idle_exit && (options.max_tasks < 0 || completed < options.max_tasks)) {
      const bool fetches_campaigns = !options.campaign_cache_dir.empty();
      auto lease = client.Post("/v1/tasks/lease", headers,
                               json({{"worker", name}, {"fetches_campaigns", fetches_campaigns}}).dump(), "application/json");
      if (!lease) {  // network trouble: the server may be restarting
        Pause(1000, stop);
        continue;
      }
      if (lease->status == 401 || lease->status == 403) {
        // Only the first refused thread writes the message (read after the joins).
        if (!refused.exchange(true)) refusal = "server refused the token (HTTP " + std::to_string(lease->status) + ")";
        break;
      }
      if (lease->status == 204) {
        int wait_ms = IdlePollWaitMs(options, ++idle_polls);
        if (options.exit_when_idle_ms >= 0) {
          const int64_t idle_ms = since_start_ms() - last_activity_ms;
          if (busy_threads == 0 && idle_ms >= options.exit_when_idle_ms) {
            idle_exit = true;
            break;
          }
          // Wake at the idle limit rather than up to a whole backed-off wait after it.
          wait_ms = static_cast<int>(std::clamp<int64_t>(options.exit_when_idle_ms - idle_ms, 50, wait_ms));
        }
        if (wait_ms > options.keep_connection_max_wait_ms) client.stop();  // reconnects on the next request
        Pause(wait_ms, stop);
        continue;
      }
      if (lease->status != 200) {
        Pause(1000, stop);
        continue;
      }
      idle_polls = 0;
      ++busy_threads;
      last_activity_ms = since_start_ms();
      const json task = ParseJson(lease->body);
      json reply = {{"job_id", task.at("job_id")}, {"lease_token", task.at("lease_token")}};
      std::string endpoint = "/v1/tasks/" + std::to_string(task.at("task_id").get<int64_t>());
      try {
        // Renewed at a quarter of the lease, so that one or two lost renewals do not lose it.
        const int64_t lease_ms = task.value("lease_ms", int64_t{120000});
        const LeaseKeeper keeper(host, port, headers, endpoint + "/renew", reply.dump(),
                                 static_cast<int>(std::max<int64_t>(lease_ms / 4, 10)), stop);
        json spec = task.at("spec");
        if (jobs::IsCampaignKind(spec.at("type")))
          spec["campaign_dir"] =
              FetchCampaign(client, headers, options.campaign_cache_dir, spec.value("campaign_sha256", ""), task, stop).string();
        json rows = json::array();
        for (const jobs::ResultRow& row : jobs::RunTaskForRemote(spec, &keeper.cancel()))
          rows.push_back({{"table", row.table}, {"values", row.values}});
        reply["rows"] = std::move(rows);
        endpoint += "/complete";
      } catch (const Cancelled&) {
        // The job was cancelled (or the lease lost) or this worker stops: nothing to send; a lease
        // still held expires and the task is leased again.
        last_activity_ms = since_start_ms();
        --busy_threads;
        continue;
      } catch (const WorkBudgetSpent& e) {  // the server retries such a task once (Store::FailTaskOnBudget)
        reply["error"] = e.what();
        reply["budget"] = true;
        endpoint += "/fail";
      } catch (const std::exception& e) {
        reply["error"] = e.what();
        endpoint += "/fail";
      }
      // Results are sent until the server answers: a lost answer is retried, and the server
      // refuses a second completion of the same lease (409), so nothing is stored twice.
      for (int attempt = 0; attempt < 20 && !stop; ++attempt) {
        auto done = client.Post(endpoint, headers, reply.dump(), "application/json");
        if (done && (done->status == 200 || done->status == 409)) {
          if (done->status == 200 && endpoint.ends_with("/complete")) ++completed;
          break;
        }
        Pause(500, stop);
      }
      last_activity_ms = since_start_ms();
      --busy_threads;
    }
  };
  std::vector<std::thread> threads;
  for (int i = 1; i < options.threads; ++i) threads.emplace_back(loop, i);
  loop(0);
  for (std::thread& t : threads) t.join();
  if (refused) throw std::runtime_error(refusal);
  return completed;
}

}  // namespace strokelab::worker
