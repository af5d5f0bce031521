// Idle remote workers (remote_worker.cc): polls of an empty queue back off up to a cap, reuse one
// kept-alive connection while they are close together, and `exit_when_idle_ms`
// (`strokelab worker --exit-when-idle SECONDS`) ends a worker that found nothing to do, so that a
// batch job gives its allocation back. The server here is a stub that never has a task and records
// the client port of each poll (one port: one connection).
#include <gtest/gtest.h>
#include <httplib.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <thread>
#include <vector>

#include "strokelab/worker/remote_worker.h"

namespace strokelab::worker {
namespace {

// An HTTP server whose lease route always answers 204 (no task), on a port of its own.
class EmptyQueueStub {
 public:
  EmptyQueueStub() {
    http_.Post("/v1/tasks/lease", [this](const httplib::Request& req, httplib::Response& res) {
      std::lock_guard<std::mutex> lock(mutex_);
      ports_.push_back(req.remote_port);
      res.status = 204;
    });
    http_.set_keep_alive_max_count(1000);  // httplib closes a connection after 5 requests by default
    port_ = http_.bind_to_any_port("127.0.0.1");
    thread_ = std::thread([this] { http_.listen_after_bind(); });
    // Listening since the bind; waiting for the loop lets the destructor's stop() end it.
    while (!http_.is_running()) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    // Debian's cpp-httplib is a shared library that ThreadSanitizer does not instrument, and it
    // parses responses with function-local static std::regex objects: TSan cannot see the guard of
    // their first initialisation, so two worker threads making the first requests of the process
    // were reported as a race. One request from this thread initialises them before those threads
    // exist (a path the stub does not record).
    httplib::Client("127.0.0.1", port_).Get("/warm-up");
  }
  ~EmptyQueueStub() {
    http_.stop();
    thread_.join();
  }
  std::string Url() const { return "http://127.0.0.1:" + std::to_string(port_); }
  std::vector<int> Ports() {
    std::lock_guard<std::mutex> lock(mutex_);
    return ports_;
  }

 private:
  httplib::Server http_;
  int port_ = 0;
  std::mutex mutex_;
  std::vector<int> ports_;
  std::thread thread_;
};

// Polls 10 ms apart doubling to 40 ms, so that a test sees many in a fraction of a second.
RemoteWorkerOptions QuickPollOptions(const EmptyQueueStub& stub) {
  RemoteWorkerOptions options;
  options.server_url = stub.Url();
  options.idle_poll_ms = 10;
  options.idle_poll_max_ms = 40;
  return options;
}

TEST(RemoteWorkerIdle, PollWaitDoublesUpToTheCap) {
  RemoteWorkerOptions options;
  options.idle_poll_ms = 500;
  options.idle_poll_max_ms = 10000;
  const std::vector<int> expected = {500, 1000, 2000, 4000, 8000, 10000, 10000};
  for (size_t i = 0; i < expected.size(); ++i) EXPECT_EQ(IdlePollWaitMs(options, static_cast<int>(i) + 1), expected[i]);
  EXPECT_EQ(IdlePollWaitMs(options, 1000000), 10000);  // no overflow after many polls
}

TEST(RemoteWorkerIdle, ExitsWhenIdleAndPollsOnOneConnection) {
  EmptyQueueStub stub;
  RemoteWorkerOptions options = QuickPollOptions(stub);
  options.threads = 2;
  options.exit_when_idle_ms = 400;
  const std::atomic<bool> stop{false};
  // Without exit_when_idle_ms this would never return (nothing sets stop).
  EXPECT_EQ(RunRemoteWorker(options, stop), 0);
  const std::vector<int> ports = stub.Ports();
  ASSERT_GE(ports.size(), 4u);
  // Two threads, each on its own kept-alive connection.
  EXPECT_EQ(std::set<int>(ports.begin(), ports.end()).size(), 2u);
}

TEST(RemoteWorkerIdle, ClosesItsConnectionBeforeALongWait) {
  EmptyQueueStub stub;
  RemoteWorkerOptions options = QuickPollOptions(stub);
  options.keep_connection_max_wait_ms = 5;  // every wait is "long" here
  options.exit_when_idle_ms = 200;
  const std::atomic<bool> stop{false};
  EXPECT_EQ(RunRemoteWorker(options, stop), 0);
  const std::vector<int> ports = stub.Ports();
  ASSERT_GE(ports.size(), 2u);
  EXPECT_EQ(std::set<int>(ports.begin(), ports.end()).size(), ports.size());
}

}  // namespace
}  // namespace strokelab::worker
