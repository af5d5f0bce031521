// libFuzzer harness: raw bytes sent to the REST service as an HTTP request, so that the whole request
// path runs: cpp-httplib's parser and router, the service's pre-routing checks and handlers, the job
// store. The service is started once, in process, on 127.0.0.1 with a free port, a SQLite file in a
// scratch directory and no workers (a submitted job stays queued; no simulation runs). Each input is
// one connection: the bytes are written, the client half-closes, and the response is read to the end
// (httplib closes once it has answered everything the client sent), so that each input's work is
// done, and its coverage counted, before the next one starts.
//
// The contract checked: the service answers bad input with 4xx. A 5xx status line is a bug (an
// exception that the request path did not turn into a client error) and aborts with the response.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>

#include "fuzz_temp_dir.h"
#include "strokelab/server/service.h"

namespace {

// Longer than any request the service should take: past it the harness calls the input a hang.
constexpr int kResponseTimeoutMs = 20000;

int g_port = 0;

[[noreturn]] void Fail(const char* what) {
  std::perror(what);
  std::abort();
}

// poll() for `events` on `fd` for up to timeout_ms in all. libFuzzer's -timeout runs on SIGALRM, which
// interrupts system calls (EINTR) about once a second: poll taken for "no answer" looked like a server
// hang (10-minute runs; strace showed the alarm and the harness giving up 16 ms after connect), and an
// interrupted connect, send or recv must be finished or retried too.
int PollFor(int fd, short events, int timeout_ms) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    pollfd p{fd, events, 0};
    const int ready = ::poll(&p, 1, static_cast<int>(std::max<long long>(0, left.count())));
    if (ready < 0 && errno == EINTR) continue;
    return ready;
  }
}

int Connect() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) Fail("socket");
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(g_port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
    if (errno != EINTR) Fail("connect");
    // Interrupted: the connection goes on in the background; wait for it and read its outcome.
    int error = 0;
    socklen_t length = sizeof error;
    if (PollFor(fd, POLLOUT, kResponseTimeoutMs) != 1) Fail("connect (no completion)");
    if (::getsockopt(fd, SOL_SOCKET, SO_ERROR, &error, &length) != 0) Fail("getsockopt");
    if (error != 0) {
      errno = error;
      Fail("connect");
    }
  }
  return fd;
}

// Where the service's threads are when a request hangs (gdb, when it is installed: a debugging aid,
// not a dependency).
void PrintThreadStacks() {
  const std::string command = "gdb -p " + std::to_string(::getpid()) +
                              " -batch -ex 'thread apply all bt' 1>&2 2>/dev/null";
  if (std::system(command.c_str()) != 0) std::fprintf(stderr, "(no thread stacks: gdb failed or is missing)\n");
}

// Sends the request and reads the whole response. The server may answer and close before it has
// read everything (e.g. 413 on a large Content-Length): then the rest cannot be sent, which is fine.
std::string Exchange(std::string_view request) {
  const int fd = Connect();
  while (!request.empty()) {
    const ssize_t n = ::send(fd, request.data(), request.size(), MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    request.remove_prefix(static_cast<size_t>(n));
  }
  ::shutdown(fd, SHUT_WR);
  std::string response;
  char buffer[65536];
  for (;;) {
    if (PollFor(fd, POLLIN, kResponseTimeoutMs) != 1) {
      std::fprintf(stderr, "no end of response within %d ms; so far:\n%s\n", kResponseTimeoutMs, response.c_str());
      PrintThreadStacks();
      std::abort();
    }
    const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;  // end of stream (or a reset after an early answer)
    response.append(buffer, static_cast<size_t>(n));
  }
  ::close(fd);
  return response;
}

// Whether a status line of the response (at its start or after a CRLF: JSON bodies escape line ends)
// says 5xx.
bool HasServerError(const std::string& response) {
  for (size_t at = response.find("HTTP/1.1 5"); at != std::string::npos; at = response.find("HTTP/1.1 5", at + 1))
    if (at == 0 || (at >= 2 && response.compare(at - 2, 2, "\r\n") == 0)) return true;
  return false;
}

// The service under test. Replaced by a fresh one on an empty directory every kInputsPerService
// inputs: accepted jobs and campaign uploads pile up in the store, and a store that grows without
// bound would make later inputs slower and the scratch directory (in RAM) large.
constexpr int kInputsPerService = 20000;
std::unique_ptr<strokelab::server::Service> g_service;
int g_inputs = 0;

void StartFreshService() {
  if (g_service) g_service->Stop();
  g_service.reset();
  const std::filesystem::path dir = strokelab::fuzz::ProcessTempDir() / "service";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  strokelab::server::ServiceOptions options;
  options.host = "127.0.0.1";
  options.port = 0;
  options.db_path = (dir / "fuzz.db").string();
  options.workers = 0;
  options.quiet = true;
  g_service = std::make_unique<strokelab::server::Service>(options);
  g_port = g_service->Start();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (g_inputs++ % kInputsPerService == 0) StartFreshService();
  const std::string response = Exchange(std::string_view(reinterpret_cast<const char*>(data), size));
  if (HasServerError(response)) {
    std::fprintf(stderr, "server error for a request; response:\n%s\n", response.c_str());
    std::abort();
  }
  return 0;
}
