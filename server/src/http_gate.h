// The service's HTTP server: cpp-httplib's request handling behind a gate that holds connections
// while their request line and headers arrive, without a thread. Internal to the service.
//
// cpp-httplib 0.11 gives each connection a pool thread from accept to close, and a recv timeout that
// restarts with every byte: eight clients sending a byte a second held its eight threads for as long
// as they liked, and /v1/health waited. Here the listener hands each accepted connection to one poll
// loop (ConnectionGate), which reads until the blank line that ends the headers, within
// header_timeout of the first byte (408 after it), max_header_bytes and max_header_lines (431), and
// max_request_line_bytes (414), and admits at most max_pending_per_address such connections from one address (429) and max_pending in
// all (503). Only a request whose headers are complete takes a thread, on one of two pools: a small
// one for what must answer while the other is busy (`is_priority`: health and the task lease), and
// the main one. The request is then cpp-httplib's (Server::process_request on a stream that first
// returns the bytes the gate read); its body must keep arriving at min_body_bytes_per_s after a
// grace of body_grace. Between requests a kept-alive connection goes back to the gate (idle for at
// most keep_alive_timeout, and not counted against its address: many workers behind one address
// keep their connections).
#pragma once

#include <httplib.h>

#include <chrono>
#include <cstddef>
#include <functional>
#include <string>
#include <string_view>

namespace strokelab::server::internal {

// The headers every reply carries, the gate's own refusals too: no MIME sniffing, no framing
// (clickjacking), no referrer leaving the page.
inline const httplib::Headers& SecurityHeaders() {
  static const httplib::Headers headers = {
      {"X-Content-Type-Options", "nosniff"}, {"X-Frame-Options", "DENY"}, {"Referrer-Policy", "no-referrer"}};
  return headers;
}

// A complete response that closes its connection: `status reason`, the security headers and
// {"error": {"code", "message"}} (the gate's refusals, and those built on a raw header block).
std::string JsonErrorResponse(int status, const char* reason, const std::string& code, const std::string& message);

struct GateLimits {
  std::chrono::milliseconds header_timeout{10000};
  std::chrono::milliseconds keep_alive_timeout{5000};
  std::chrono::milliseconds body_grace{10000};
  size_t min_body_bytes_per_s = 16 * 1024;
  // Longer request lines get 414 before any route pattern sees them: std::regex matches
  // recursively, a few hundred bytes of stack per character of the path.
  size_t max_request_line_bytes = 2048;
  size_t max_header_bytes = 32 * 1024;
  int max_header_lines = 100;
  int max_pending_per_address = 32;
  int max_pending = 512;  // below FD_SETSIZE, which cpp-httplib still checks
  int threads = 8;
  int priority_threads = 2;
  // Whether a request line ("GET /v1/health HTTP/1.1") goes to the priority pool.
  std::function<bool(std::string_view request_line)> is_priority;
  // A complete HTTP response refusing a header block (request line and headers, CRLF-terminated),
  // or "" to let it through: for what cpp-httplib would lose while parsing (trailing blanks).
  std::function<std::string(std::string_view header_block)> refuse_headers;
  // Told of each connection the gate itself refuses (status, peer address), for the access log.
  std::function<void(int status, const std::string& remote)> on_refused;
};

class GatedServer : public httplib::Server {
 public:
  explicit GatedServer(GateLimits limits = {});
  ~GatedServer() override;

  // Set before listening.
  GateLimits& limits() { return limits_; }

  // Whether the response being written on this thread asked for the connection to close (set by
  // the post-routing hook; the gate then closes instead of keeping the connection).
  static bool& CloseAfterResponse();

 private:
  class ConnectionGate;
  friend class ConnectionGate;

  bool process_and_close_socket(socket_t sock) override;
  // Serves one request whose headers (and perhaps more) the gate has read into `prefix`.
  void ServeRequest(socket_t sock, std::string prefix, size_t header_bytes);

  GateLimits limits_;
  ConnectionGate* gate_ = nullptr;  // the task queue of the running listen loop
};

}  // namespace strokelab::server::internal
