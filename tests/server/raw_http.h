// Raw HTTP over a socket, for requests that cpp-httplib's client cannot send: a request cut off in
// its headers, bytes trickled, silent connections, a body that never ends.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <stdexcept>
#include <string>

namespace strokelab::testing {

class RawConnection {
 public:
  // `from`: the loopback address to connect from ("127.0.0.2"; default the kernel's choice), so that
  // a test can play clients at several addresses.
  explicit RawConnection(int port, const char* from = nullptr) {
    sock_ = ::socket(AF_INET, SOCK_STREAM, 0);
    if (from != nullptr && sock_ >= 0) {
      sockaddr_in local{};
      local.sin_family = AF_INET;
      ::inet_pton(AF_INET, from, &local.sin_addr);
      if (::bind(sock_, reinterpret_cast<sockaddr*>(&local), sizeof local) != 0) {
        ::close(sock_);
        throw std::runtime_error(std::string("cannot bind ") + from);
      }
    }
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (sock_ < 0 || ::connect(sock_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0)
      throw std::runtime_error("cannot connect to port " + std::to_string(port));
    timeval guard{60, 0};  // a reply that never comes fails the test instead of hanging it
    ::setsockopt(sock_, SOL_SOCKET, SO_RCVTIMEO, &guard, sizeof guard);
  }
  ~RawConnection() { ::close(sock_); }
  RawConnection(const RawConnection&) = delete;
  RawConnection& operator=(const RawConnection&) = delete;

  // False once the server has closed the connection (or reset it).
  bool Send(const std::string& bytes) {
    size_t sent = 0;
    while (sent < bytes.size()) {
      const ssize_t n = ::send(sock_, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) return false;
      sent += static_cast<size_t>(n);
    }
    return true;
  }

  // The status line of the reply ("HTTP/1.1 408 Request Timeout"), or "" when the connection ends
  // (or the guard timeout passes) without one.
  std::string StatusLine() {
    std::string text;
    char c;
    while (text.find("\r\n") == std::string::npos && ::recv(sock_, &c, 1, 0) == 1) text += c;
    return text.substr(0, text.find("\r\n"));
  }

  // The status code of the reply, or 0 when there is none.
  int Status() {
    const std::string line = StatusLine();
    return line.size() >= 12 ? std::atoi(line.substr(9, 3).c_str()) : 0;
  }

 private:
  int sock_ = -1;
};

}  // namespace strokelab::testing
