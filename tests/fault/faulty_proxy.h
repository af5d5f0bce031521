// A TCP proxy on loopback that breaks connections on purpose, for tests of the worker-server link.
// Every connection accepted gets one fault, drawn from a seeded generator:
//
//   kPass        forwarded as is
//   kDelay       the request and the first part of the reply each held back 0..max_delay_ms
//   kRefuse      closed as soon as the request begins: the server sees nothing
//   kCutRequest  part of the request forwarded, then both sides closed: the server sees half a request
//   kCutReply    the request forwarded, part of the reply, then closed: the server has acted
//   kDropReply   the request forwarded, both sides closed when the reply begins: the server has
//                acted (a handler runs to its end before the reply is written), the client hears nothing
//
// and the first `drop_first_completes` requests to /v1/tasks/{id}/complete get kDropReply, so that a
// test can count on completions the server stored but the worker never heard of.
// httplib clients send one request per connection (no keep-alive), so a fault hits one request.
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <random>
#include <thread>
#include <vector>

namespace strokelab::test_fault {

enum class ProxyFault { kPass, kDelay, kRefuse, kCutRequest, kCutReply, kDropReply, kCount };
const char* ToString(ProxyFault fault);

struct ProxyOptions {
  // Weights of the faults, in ProxyFault order (need not sum to 1).
  std::vector<double> weights = {0.45, 0.2, 0.08, 0.08, 0.09, 0.1};
  int max_delay_ms = 300;
  int drop_first_completes = 3;
};

class FaultyProxy {
 public:
  // Listens on 127.0.0.1 (any port) and forwards to 127.0.0.1:server_port.
  FaultyProxy(int server_port, const ProxyOptions& options, uint64_t seed);
  ~FaultyProxy();  // stops accepting and joins every connection's thread
  FaultyProxy(const FaultyProxy&) = delete;
  FaultyProxy& operator=(const FaultyProxy&) = delete;

  int port() const { return port_; }
  // Connections that got each fault so far; and completions whose reply was cut or dropped.
  std::vector<int> FaultCounts() const;
  int CompletionRepliesLost() const { return completion_replies_lost_; }

 private:
  void AcceptLoop();
  void Relay(int client_fd);
  ProxyFault Choose(bool is_complete);

  int server_port_, port_ = 0, listen_fd_ = -1;
  ProxyOptions options_;
  std::atomic<bool> stop_{false};
  mutable std::mutex mu_;  // guards the generator, the counts and the threads
  std::mt19937_64 rng_;
  std::vector<int> counts_;
  int completes_seen_ = 0;
  std::atomic<int> completion_replies_lost_{0};
  std::vector<std::thread> connections_;
  std::thread acceptor_;
};

}  // namespace strokelab::test_fault
