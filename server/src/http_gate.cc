// The gated HTTP server (http_gate.h): one poll loop holds connections until their headers are
// complete, two pools serve the requests.
#include "http_gate.h"

#include <fcntl.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>
#include <vector>

namespace strokelab::server::internal {
namespace {

using Clock = std::chrono::steady_clock;

// Waits up to `timeout` for `events` on `sock`.
bool PollSocket(socket_t sock, short events, Clock::duration timeout) {
  pollfd fd{sock, events, 0};
  const int ms = static_cast<int>(std::max<int64_t>(0, std::chrono::duration_cast<std::chrono::milliseconds>(timeout).count()));
  int ready;
  do ready = ::poll(&fd, 1, ms);
  while (ready < 0 && errno == EINTR);
  return ready > 0;
}

void IpAndPort(const sockaddr_storage& address, socklen_t length, std::string& ip, int& port) {
  char host[NI_MAXHOST] = "", service[NI_MAXSERV] = "";
  if (::getnameinfo(reinterpret_cast<const sockaddr*>(&address), length, host, sizeof host, service, sizeof service,
                    NI_NUMERICHOST | NI_NUMERICSERV) == 0) {
    ip = host;
    port = std::atoi(service);
  }
}

std::string PeerAddress(socket_t sock) {
  sockaddr_storage address{};
  socklen_t length = sizeof address;
  std::string ip;
  int port = 0;
  if (::getpeername(sock, reinterpret_cast<sockaddr*>(&address), &length) == 0) IpAndPort(address, length, ip, port);
  return ip;
}

// Sends what fits without blocking, ends the connection's writing, drops what the client sent and
// closes: a refusal from the gate is answered once and never read further.
void AnswerAndClose(socket_t sock, const std::string& response) {
  if (!response.empty()) (void)::send(sock, response.data(), response.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
  ::shutdown(sock, SHUT_WR);
  char drain[16384];
  for (int i = 0; i < 4 && ::recv(sock, drain, sizeof drain, MSG_DONTWAIT) > 0; ++i) {
  }
  ::close(sock);
}

// After a response that closes the connection, often a refusal sent before the body was read: what
// the client still sends is read and dropped (never kept), up to 64 MiB and 2 s, so that a client
// that writes its whole body before it reads (cpp-httplib's, curl without Expect) gets the refusal
// rather than a reset connection; past that the connection is reset.
void LingerAndClose(socket_t sock) {
  ::shutdown(sock, SHUT_WR);
  const auto until = Clock::now() + std::chrono::seconds(2);
  char drain[65536];
  for (size_t dropped = 0; dropped < (size_t{64} << 20) && PollSocket(sock, POLLIN, until - Clock::now());) {
    const ssize_t n = ::recv(sock, drain, sizeof drain, 0);
    if (n <= 0) break;
    dropped += static_cast<size_t>(n);
  }
  ::close(sock);
}

// A request's stream: the bytes the gate read first, then the socket, with read and write timeouts
// and a floor on the body's rate (GateLimits).
class GateStream final : public httplib::Stream {
 public:
  GateStream(socket_t sock, std::string prefix, size_t header_bytes, const GateLimits& limits,
             std::chrono::milliseconds read_timeout, std::chrono::milliseconds write_timeout)
      : sock_(sock), prefix_(std::move(prefix)), header_bytes_(header_bytes), limits_(limits),
        read_timeout_(read_timeout), write_timeout_(write_timeout), headers_done_(Clock::now()) {}

  bool is_readable() const override { return offset_ < prefix_.size() || PollSocket(sock_, POLLIN, read_timeout_); }
  bool is_writable() const override { return PollSocket(sock_, POLLOUT, write_timeout_); }

  ssize_t read(char* ptr, size_t size) override {
    if (offset_ < prefix_.size()) {
      const size_t n = std::min(size, prefix_.size() - offset_);
      std::memcpy(ptr, prefix_.data() + offset_, n);
      offset_ += n;
      consumed_ += n;
      return static_cast<ssize_t>(n);
    }
    // The body may take body_grace, plus 1 s per min_body_bytes_per_s already received.
    const size_t body_bytes = consumed_ > header_bytes_ ? consumed_ - header_bytes_ : 0;
    const auto allowed = limits_.body_grace + std::chrono::milliseconds(
                                                  body_bytes * 1000 / std::max<size_t>(1, limits_.min_body_bytes_per_s));
    const auto left = allowed - (Clock::now() - headers_done_);
    if (left <= Clock::duration::zero()) return -1;
    if (!PollSocket(sock_, POLLIN, std::min<Clock::duration>(left, read_timeout_))) return -1;
    ssize_t n;
    do n = ::recv(sock_, ptr, size, 0);
    while (n < 0 && errno == EINTR);
    if (n > 0) consumed_ += static_cast<size_t>(n);
    return n;
  }

  ssize_t write(const char* ptr, size_t size) override {
    if (!is_writable()) return -1;
    ssize_t n;
    do n = ::send(sock_, ptr, size, MSG_NOSIGNAL);
    while (n < 0 && errno == EINTR);
    return n;
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage address{};
    socklen_t length = sizeof address;
    if (::getpeername(sock_, reinterpret_cast<sockaddr*>(&address), &length) == 0) IpAndPort(address, length, ip, port);
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage address{};
    socklen_t length = sizeof address;
    if (::getsockname(sock_, reinterpret_cast<sockaddr*>(&address), &length) == 0) IpAndPort(address, length, ip, port);
  }
  socket_t socket() const override { return sock_; }

  // What the gate read beyond this request (a pipelined next request).
  std::string TakeUnread() { return prefix_.substr(offset_); }

 private:
  socket_t sock_;
  std::string prefix_;
  size_t offset_ = 0, consumed_ = 0, header_bytes_;
  const GateLimits& limits_;
  std::chrono::milliseconds read_timeout_, write_timeout_;
  Clock::time_point headers_done_;
};

}  // namespace

std::string JsonErrorResponse(int status, const char* reason, const std::string& code, const std::string& message) {
  const std::string body = nlohmann::json({{"error", {{"code", code}, {"message", message}}}}).dump();
  std::string response = "HTTP/1.1 " + std::to_string(status) + " " + reason + "\r\n";
  for (const auto& [name, value] : SecurityHeaders()) response += name + ": " + value + "\r\n";
  return response + "Content-Type: application/json\r\nContent-Length: " + std::to_string(body.size()) +
         "\r\nConnection: close\r\n\r\n" + body;
}

// The listen loop's task queue: "enqueue" is cpp-httplib handing over an accepted connection (its
// process_and_close_socket, which GatedServer makes an Admit), done at once on the listener thread.
class GatedServer::ConnectionGate final : public httplib::TaskQueue {
 public:
  explicit ConnectionGate(GatedServer& server)
      : server_(server), priority_(std::max(1, server.limits_.priority_threads)),
        main_(std::max(1, server.limits_.threads)) {
    if (::pipe2(wake_, O_NONBLOCK | O_CLOEXEC) != 0) throw std::runtime_error("pipe2 failed");
    loop_ = std::thread([this] { Loop(); });
    server_.gate_ = this;
  }
  ~ConnectionGate() override {
    server_.gate_ = nullptr;
    ::close(wake_[0]);
    ::close(wake_[1]);
  }

  void enqueue(std::function<void()> fn) override { fn(); }

  void shutdown() override {
    stopping_ = true;
    Wake();
    loop_.join();
    priority_.shutdown();  // requests being served finish; their connections then close
    main_.shutdown();
  }

  // Takes a connection: new (`kept_alive` false; counted against its address) or back from a
  // request (with what the gate had read beyond it).
  void Admit(socket_t sock, std::string prefix, bool kept_alive) {
    Waiting w{sock, kept_alive ? std::string() : PeerAddress(sock), std::move(prefix), {}, !kept_alive,
              kept_alive};
    const GateLimits& limits = server_.limits_;
    w.deadline = Clock::now() + (w.idle && w.buffer.empty() ? limits.keep_alive_timeout : limits.header_timeout);
    if (!w.buffer.empty()) w.idle = false;
    int refuse = 0;
    {
      std::lock_guard lock(mu_);
      if (stopping_) refuse = -1;
      else if (held_ >= limits.max_pending) refuse = 503;
      else if (w.counted && per_address_[w.address] >= limits.max_pending_per_address) refuse = 429;
      if (refuse == 0) {
        ++held_;
        if (w.counted) ++per_address_[w.address];
        incoming_.push_back(std::move(w));
      }
    }
    if (refuse == 0) return Wake();
    if (refuse == -1) return AnswerAndClose(sock, "");
    if (limits.on_refused) limits.on_refused(refuse, w.address);
    AnswerAndClose(sock, refuse == 429 ? JsonErrorResponse(429, "Too Many Requests", "too_many_connections",
                                                           "too many connections from this address are still "
                                                           "sending their request headers")
                                       : JsonErrorResponse(503, "Service Unavailable", "too_many_connections",
                                                           "too many connections are still sending their request headers"));
  }

 private:
  struct Waiting {
    socket_t sock;
    std::string address;  // of a counted connection
    std::string buffer;   // bytes read so far
    Clock::time_point deadline;
    bool counted;  // new: counted against its address until its headers are in
    bool idle;     // kept alive and nothing of its next request read yet
  };

  void Wake() { (void)!::write(wake_[1], "x", 1); }

  void Release(const Waiting& w) {
    std::lock_guard lock(mu_);
    --held_;
    if (w.counted && --per_address_[w.address] == 0) per_address_.erase(w.address);
  }

  void Refuse(const Waiting& w, int status, const char* reason, const std::string& code, const std::string& message) {
    Release(w);
    if (server_.limits_.on_refused) server_.limits_.on_refused(status, w.address.empty() ? PeerAddress(w.sock) : w.address);
    AnswerAndClose(w.sock, JsonErrorResponse(status, reason, code, message));
  }

  // Whether `w` left the gate: its headers are complete (served or refused) or too large.
  bool Examine(Waiting& w) {
    const GateLimits& limits = server_.limits_;
    const size_t end = w.buffer.find("\r\n\r\n");
    const size_t header_bytes = end == std::string::npos ? w.buffer.size() : end + 4;
    const std::string_view block(w.buffer.data(), std::min(header_bytes, w.buffer.size()));
    const long lines = std::count(block.begin(), block.end(), '\n');
    if (header_bytes > limits.max_header_bytes || lines > limits.max_header_lines + 2) {
      Refuse(w, 431, "Request Header Fields Too Large", "headers_too_large",
             "the request line and headers exceed " + std::to_string(limits.max_header_bytes) + " bytes or " +
                 std::to_string(limits.max_header_lines) + " header lines");
      return true;
    }
    if (const size_t line_end = block.find("\r\n"); std::min(line_end, block.size()) > limits.max_request_line_bytes) {
      Refuse(w, 414, "URI Too Long", "uri_too_long",
             "the request line exceeds " + std::to_string(limits.max_request_line_bytes) + " bytes");
      return true;
    }
    if (end == std::string::npos) return false;
    if (limits.refuse_headers) {
      if (std::string refusal = limits.refuse_headers(block); !refusal.empty()) {
        Release(w);
        AnswerAndClose(w.sock, refusal);
        return true;
      }
    }
    Release(w);
    const std::string_view request_line = block.substr(0, block.find("\r\n"));
    httplib::ThreadPool& pool = limits.is_priority && limits.is_priority(request_line) ? priority_ : main_;
    pool.enqueue([server = &server_, sock = w.sock, prefix = std::move(w.buffer), header_bytes]() mutable {
      server->ServeRequest(sock, std::move(prefix), header_bytes);
    });
    return true;
  }

  // Reads what arrived; false when the peer closed or failed (the connection is then closed).
  bool ReadMore(Waiting& w) {
    char chunk[16384];
    ssize_t n;
    do n = ::recv(w.sock, chunk, sizeof chunk, MSG_DONTWAIT);
    while (n < 0 && errno == EINTR);
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return true;
    if (n <= 0) return false;
    if (w.idle) {  // the next request has begun: its headers get header_timeout from now
      w.idle = false;
      w.deadline = Clock::now() + server_.limits_.header_timeout;
    }
    w.buffer.append(chunk, static_cast<size_t>(n));
    return true;
  }

  void Loop() {
    std::vector<Waiting> waiting;
    std::vector<pollfd> fds;
    while (!stopping_) {
      {
        std::lock_guard lock(mu_);
        for (Waiting& w : incoming_) waiting.push_back(std::move(w));
        incoming_.clear();
      }
      // A connection back with a pipelined request may be complete already.
      for (size_t i = waiting.size(); i-- > 0;)
        if (!waiting[i].buffer.empty() && Examine(waiting[i])) Remove(waiting, i);
      fds.assign(1, pollfd{wake_[0], POLLIN, 0});
      auto next = Clock::now() + std::chrono::seconds(1);
      for (const Waiting& w : waiting) {
        fds.push_back(pollfd{w.sock, POLLIN, 0});
        next = std::min(next, w.deadline);
      }
      const auto wait = std::chrono::duration_cast<std::chrono::milliseconds>(next - Clock::now()).count();
      if (::poll(fds.data(), fds.size(), static_cast<int>(std::max<int64_t>(0, wait) + 1)) < 0 && errno != EINTR) break;
      char drain[64];
      while (::read(wake_[0], drain, sizeof drain) > 0) {
      }
      const auto now = Clock::now();
      // fds[i + 1] is waiting[i]: walk back so that removing the last-but-swapped entry is safe.
      for (size_t i = waiting.size(); i-- > 0;) {
        Waiting& w = waiting[i];
        if (fds[i + 1].revents != 0) {
          if (!ReadMore(w)) {
            Release(w);
            AnswerAndClose(w.sock, "");
            Remove(waiting, i);
            continue;
          }
          if (!w.buffer.empty() && Examine(w)) {
            Remove(waiting, i);
            continue;
          }
        }
        if (now >= w.deadline) {
          if (w.idle) {  // a kept-alive connection that sent nothing more: closed quietly
            Release(w);
            AnswerAndClose(w.sock, "");
          } else {
            Refuse(w, 408, "Request Timeout", "request_timeout",
                   "the request line and headers did not arrive within " +
                       std::to_string(server_.limits_.header_timeout.count()) + " ms");
          }
          Remove(waiting, i);
        }
      }
    }
    std::lock_guard lock(mu_);
    for (Waiting& w : incoming_) waiting.push_back(std::move(w));
    incoming_.clear();
    for (const Waiting& w : waiting) AnswerAndClose(w.sock, "");
  }

  static void Remove(std::vector<Waiting>& waiting, size_t i) {
    if (i + 1 != waiting.size()) waiting[i] = std::move(waiting.back());
    waiting.pop_back();
  }

  GatedServer& server_;
  int wake_[2] = {-1, -1};
  std::atomic<bool> stopping_{false};
  std::mutex mu_;
  std::vector<Waiting> incoming_;            // guarded by mu_
  std::map<std::string, int> per_address_;  // guarded by mu_
  int held_ = 0;                             // guarded by mu_
  std::thread loop_;
  httplib::ThreadPool priority_, main_;
};

GatedServer::GatedServer(GateLimits limits) : limits_(std::move(limits)) {
  new_task_queue = [this] { return new ConnectionGate(*this); };
  set_post_routing_handler([](const httplib::Request&, httplib::Response& res) {
    if (res.get_header_value("Connection") == "close") CloseAfterResponse() = true;
  });
}

GatedServer::~GatedServer() = default;

bool& GatedServer::CloseAfterResponse() {
  static thread_local bool close = false;
  return close;
}

bool GatedServer::process_and_close_socket(socket_t sock) {
  if (gate_) gate_->Admit(sock, "", false);
  else AnswerAndClose(sock, "");
  return true;
}

void GatedServer::ServeRequest(socket_t sock, std::string prefix, size_t header_bytes) {
  using std::chrono::duration_cast, std::chrono::milliseconds, std::chrono::seconds, std::chrono::microseconds;
  GateStream stream(sock, std::move(prefix), header_bytes, limits_,
                    duration_cast<milliseconds>(seconds(read_timeout_sec_) + microseconds(read_timeout_usec_)),
                    duration_cast<milliseconds>(seconds(write_timeout_sec_) + microseconds(write_timeout_usec_)));
  CloseAfterResponse() = false;
  bool connection_closed = false;
  const bool served = process_request(stream, false, connection_closed, nullptr);
  if (served && !connection_closed && !CloseAfterResponse() && svr_sock_ != INVALID_SOCKET && gate_)
    gate_->Admit(sock, stream.TakeUnread(), true);
  else if (served)
    LingerAndClose(sock);
  else
    AnswerAndClose(sock, "");
}

}  // namespace strokelab::server::internal
