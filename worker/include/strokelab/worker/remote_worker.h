// A worker process that leases tasks from a strokelab server over HTTP, runs them, and sends the
// results back (`strokelab worker --server URL --token T`), so that sweeps scale past one machine.
// A task whose lease expires (the worker died or lost the network) is leased again by someone
// else; a late completion of it is refused by the server, so nothing is stored twice. A fit or
// diagnose task's campaign is fetched from the server by the SHA-256 in its spec, checked, and cached;
// a diagnosis goes back as data (jobs::RunTaskForRemote), never as a rendered page.
#pragma once

#include <atomic>
#include <string>

namespace strokelab::worker {

struct RemoteWorkerOptions {
  std::string server_url = "http://127.0.0.1:8080";
  std::string token;
  std::string name = "remote";      // shown in the server's lease records
  int threads = 1;                  // tasks worked on at once
  // Polls of an empty queue back off: the first waits idle_poll_ms, each next one twice as long,
  // up to idle_poll_max_ms; a leased task resets the wait. So idle workers cost the server little.
  int idle_poll_ms = 500;
  int idle_poll_max_ms = 10000;
  // Polls (and completions) reuse one kept-alive connection, but before an idle wait longer than
  // this the worker closes it: the server (cpp-httplib) holds one of its few threads for each open
  // connection, so many idle workers keeping theirs open would starve the clients.
  int keep_connection_max_wait_ms = 1000;
  // Where fetched campaigns are kept (fit and diagnose tasks; DIR/SHA256/, checked against the hash
  // before each use and fetched again when changed). Empty: this worker takes no fit or diagnose tasks.
  std::string campaign_cache_dir;
  int max_tasks = -1;               // stop after this many tasks (-1: never; for tests)
  // Exit once every thread has found the queue empty for this long (-1: never), so that a worker
  // under a batch scheduler (Slurm) gives its allocation back when the work is done.
  int exit_when_idle_ms = -1;
};

// The wait before the next poll of an empty queue, after `idle_polls` empty polls in a row (>= 1).
int IdlePollWaitMs(const RemoteWorkerOptions& options, int idle_polls);

// Runs until `stop` becomes true, max_tasks are done, or the worker has been idle for
// exit_when_idle_ms. Returns the number of tasks completed.
// Network errors are retried with a pause; a refused token ends the run with std::runtime_error.
int RunRemoteWorker(const RemoteWorkerOptions& options, const std::atomic<bool>& stop);

// "http://host:port" -> (host, port); throws strokelab::InputError("--server", ...) otherwise.
std::pair<std::string, int> ParseServerUrl(const std::string& url);

}  // namespace strokelab::worker
