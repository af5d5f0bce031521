#include "fault/faulty_proxy.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <stdexcept>
#include <string>

namespace strokelab::test_fault {
namespace {

constexpr int kPollMs = 50;               // how often a blocked thread looks at the stop flag [ms]
constexpr int kConnectionLimitMs = 30000; // a connection open longer than this is closed [ms]

sockaddr_in Loopback(int port) {
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  return a;
}

bool WriteAll(int fd, const char* data, size_t n) {
  while (n > 0) {
    const ssize_t w = send(fd, data, n, MSG_NOSIGNAL);
    if (w <= 0) return false;
    data += w;
    n -= static_cast<size_t>(w);
  }
  return true;
}

// Waits up to kPollMs for input on fd: 1 when there is some (or the peer closed), 0 when there is
// none yet, -1 on error.
int WaitReadable(int fd) {
  pollfd p{fd, POLLIN, 0};
  return poll(&p, 1, kPollMs);
}

}  // namespace

const char* ToString(ProxyFault fault) {
  switch (fault) {
    case ProxyFault::kPass: return "pass";
    case ProxyFault::kDelay: return "delay";
    case ProxyFault::kRefuse: return "refuse";
    case ProxyFault::kCutRequest: return "cut request";
    case ProxyFault::kCutReply: return "cut reply";
    case ProxyFault::kDropReply: return "drop reply";
    case ProxyFault::kCount: break;
  }
  return "?";
}

FaultyProxy::FaultyProxy(int server_port, const ProxyOptions& options, uint64_t seed)
    : server_port_(server_port), options_(options), rng_(seed), counts_(static_cast<size_t>(ProxyFault::kCount), 0) {
  if (options_.weights.size() != counts_.size()) throw std::invalid_argument("proxy: one weight per fault");
  listen_fd_ = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a = Loopback(0);
  socklen_t len = sizeof a;
  if (listen_fd_ < 0 || bind(listen_fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || listen(listen_fd_, 64) != 0 ||
      getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
    throw std::runtime_error(std::string("proxy: cannot listen: ") + std::strerror(errno));
  }
  port_ = ntohs(a.sin_port);
  acceptor_ = std::thread([this] { AcceptLoop(); });
}

FaultyProxy::~FaultyProxy() {
  stop_ = true;
  acceptor_.join();
  close(listen_fd_);
  // The acceptor has ended, so no thread is added any more; join outside the lock, which the
  // connections' threads take to draw their fault.
  std::vector<std::thread> connections;
  {
    std::lock_guard lock(mu_);
    connections.swap(connections_);
  }
  for (std::thread& t : connections) t.join();
}

std::vector<int> FaultyProxy::FaultCounts() const {
  std::lock_guard lock(mu_);
  return counts_;
}

void FaultyProxy::AcceptLoop() {
  while (!stop_) {
    if (WaitReadable(listen_fd_) <= 0) continue;
    const int fd = accept(listen_fd_, nullptr, nullptr);
    if (fd < 0) continue;
    std::lock_guard lock(mu_);
    connections_.emplace_back([this, fd] { Relay(fd); });
  }
}

ProxyFault FaultyProxy::Choose(bool is_complete) {
  std::lock_guard lock(mu_);
  ProxyFault f;
  if (is_complete && completes_seen_++ < options_.drop_first_completes) {
    f = ProxyFault::kDropReply;
  } else {
    std::discrete_distribution<int> pick(options_.weights.begin(), options_.weights.end());
    f = static_cast<ProxyFault>(pick(rng_));
  }
  ++counts_[static_cast<size_t>(f)];
  return f;
}

// One connection: read the start of the request (to know whether it is a completion), choose the
// fault, then relay both ways until a side closes, breaking the connection where the fault says.
void FaultyProxy::Relay(int client) {
  const auto start = std::chrono::steady_clock::now();
  auto expired = [&] {
    return stop_ || std::chrono::steady_clock::now() - start > std::chrono::milliseconds(kConnectionLimitMs);
  };
  std::string head;
  char buf[16384];
  while (head.find("\r\n") == std::string::npos && !expired()) {
    const int ready = WaitReadable(client);
    if (ready < 0) break;
    if (ready == 0) continue;
    const ssize_t n = recv(client, buf, sizeof buf, 0);
    if (n <= 0) break;
    head.append(buf, static_cast<size_t>(n));
  }
  const bool is_complete = head.starts_with("POST /v1/tasks/") && head.find("/complete ") < head.find("\r\n");
  const ProxyFault fault = head.empty() ? ProxyFault::kRefuse : Choose(is_complete);
  // One request per connection: the fault is chosen per connection, and workers keep theirs alive
  // between requests, so the server is asked to close it after this reply (the first Connection
  // header is the one it reads).
  if (const size_t line_end = head.find("\r\n"); line_end != std::string::npos)
    head.insert(line_end + 2, "Connection: close\r\n");
  int delay_ms = 0;
  if (fault == ProxyFault::kDelay) {
    std::lock_guard lock(mu_);
    delay_ms = std::uniform_int_distribution<int>(0, options_.max_delay_ms)(rng_);
  }

  int server = -1;
  if (fault != ProxyFault::kRefuse) {
    server = socket(AF_INET, SOCK_STREAM, 0);
    const sockaddr_in a = Loopback(server_port_);
    if (server >= 0 && connect(server, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0) {
      close(server);
      server = -1;
    }
  }
  if (server >= 0) {
    const int one = 1;
    setsockopt(server, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    setsockopt(client, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
    bool ok = fault == ProxyFault::kCutRequest ? WriteAll(server, head.data(), head.size() / 2)
                                               : WriteAll(server, head.data(), head.size());
    ok = ok && fault != ProxyFault::kCutRequest;
    bool reply_started = false;
    while (ok && !expired()) {
      pollfd p[2] = {{client, POLLIN, 0}, {server, POLLIN, 0}};
      if (poll(p, 2, kPollMs) <= 0) continue;
      if (p[0].revents & (POLLIN | POLLHUP | POLLERR)) {
        const ssize_t n = recv(client, buf, sizeof buf, 0);
        ok = n > 0 && WriteAll(server, buf, static_cast<size_t>(n));
      }
      if (ok && (p[1].revents & (POLLIN | POLLHUP | POLLERR))) {
        const ssize_t n = recv(server, buf, sizeof buf, 0);
        if (n <= 0) break;  // the server has said all it will
        if (!reply_started) {
          reply_started = true;
          if (is_complete && (fault == ProxyFault::kDropReply || fault == ProxyFault::kCutReply))
            ++completion_replies_lost_;
          if (fault == ProxyFault::kDropReply) break;
          std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
        }
        if (fault == ProxyFault::kCutReply) {
          WriteAll(client, buf, static_cast<size_t>(n) / 2);
          break;
        }
        ok = WriteAll(client, buf, static_cast<size_t>(n));
      }
    }
    close(server);
  }
  close(client);
}

}  // namespace strokelab::test_fault
