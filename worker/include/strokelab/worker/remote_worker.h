// A worker process that leases tasks from a strokelab server over HTTP, runs them, and sends the
// results back (`strokelab worker --server URL --token T`), so that sweeps scale past one machine.
// A task whose lease expires (the worker died or lost the network) is leased again by someone
// else; a late completion of it is refused by the server, so nothing is stored twice.
#pragma once

#include <atomic>
#include <string>

namespace strokelab::worker {

struct RemoteWorkerOptions {
  std::string server_url = "http://127.0.0.1:8080";
  std::string token;
  std::string name = "remote";      // shown in the server's lease records
  int threads = 1;                  // tasks worked on at once
  int idle_poll_ms = 500;           // wait between leases when the queue is empty
  int max_tasks = -1;               // stop after this many tasks (-1: never; for tests)
};

// Runs until `stop` becomes true (or max_tasks are done). Returns the number of tasks completed.
// Network errors are retried with a pause; a refused token ends the run with std::runtime_error.
int RunRemoteWorker(const RemoteWorkerOptions& options, const std::atomic<bool>& stop);

// "http://host:port" -> (host, port); throws strokelab::InputError("--server", ...) otherwise.
std::pair<std::string, int> ParseServerUrl(const std::string& url);

}  // namespace strokelab::worker
