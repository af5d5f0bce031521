// The real `strokelab serve` as a child process for tests that need the whole binary (its memory,
// its stderr log, its database file under a second reader): started on a free port in a scratch
// directory, stopped with SIGTERM (then SIGKILL) when the object goes, so no test leaves one behind.
#pragma once

#include <fcntl.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

extern "C" char** environ;

namespace strokelab::testing {

namespace fs = std::filesystem;

// A sanitizer build (CMake defines STROKELAB_SANITIZED_BUILD with STROKELAB_SANITIZE): memory and
// time checks on the child server are loosened there. Clang 14 defines neither __SANITIZE_ADDRESS__
// nor __SANITIZE_THREAD__, so the compilers' own macros cannot tell.
#ifdef STROKELAB_SANITIZED_BUILD
inline constexpr bool kSanitizedBuild = true;
#else
inline constexpr bool kSanitizedBuild = false;
#endif

inline std::string ReadAll(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// A fresh directory under $TMPDIR, deleted at the end unless the test failed (then kept and named).
class ScratchDirectory {
 public:
  explicit ScratchDirectory(const std::string& prefix) {
    std::string pattern = (fs::temp_directory_path() / (prefix + "-XXXXXX")).string();
    if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp " + pattern + " failed");
    path_ = pattern;
  }
  ~ScratchDirectory() {
    std::error_code ec;
    if (::testing::Test::HasFailure()) std::fprintf(stderr, "kept %s\n", path_.c_str());
    else fs::remove_all(path_, ec);
  }
  ScratchDirectory(const ScratchDirectory&) = delete;
  ScratchDirectory& operator=(const ScratchDirectory&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

class ServeChild {
 public:
  // `strokelab serve --port 0 --db DB EXTRA...`, stderr in `log`, this environment plus `env`
  // ("NAME=value"); returns once it serves.
  ServeChild(const fs::path& db, const fs::path& log, const std::vector<std::string>& extra,
             std::vector<std::string> env = {})
      : log_(log) {
    // STROKELAB_TEST_SERVE_BINARY runs a test against another build (an older one, for a before and
    // after figure); the default is this build's.
    const char* binary = std::getenv("STROKELAB_TEST_SERVE_BINARY");
    std::vector<std::string> argv = {binary ? binary : STROKELAB_BINARY, "serve", "--port", "0", "--db", db.string()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    for (char** e = environ; *e; ++e) env.emplace_back(*e);
    std::vector<char*> args, envp;  // built before fork: the child may only exec
    for (std::string& a : argv) args.push_back(a.data());
    args.push_back(nullptr);
    for (std::string& e : env) envp.push_back(e.data());
    envp.push_back(nullptr);
    pid_ = ::fork();
    if (pid_ < 0) throw std::runtime_error("fork failed");
    if (pid_ == 0) {  // the child: only async-signal-safe calls until exec
      const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd >= 0) ::dup2(fd, 2);
      ::execve(args[0], args.data(), envp.data());
      ::_exit(127);
    }
    WaitUntilServing();
  }
  ~ServeChild() { Stop(); }
  ServeChild(const ServeChild&) = delete;
  ServeChild& operator=(const ServeChild&) = delete;

  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  std::string Log() const { return ReadAll(log_); }
  // True while the process has not exited (reaps it when it has).
  bool Alive() { return !Reaped(); }

  // Resident set size [KiB] from /proc/PID/status (VmRSS).
  long RssKib() const {
    std::ifstream status("/proc/" + std::to_string(pid_) + "/status");
    for (std::string line; std::getline(status, line);)
      if (line.rfind("VmRSS:", 0) == 0) return std::strtol(line.c_str() + 6, nullptr, 10);
    throw std::runtime_error("no VmRSS for process " + std::to_string(pid_));
  }

  std::unique_ptr<httplib::Client> Client() const {
    auto client = std::make_unique<httplib::Client>("127.0.0.1", port_);
    client->set_connection_timeout(5);
    client->set_read_timeout(30);
    client->set_tcp_nodelay(true);  // else a POST (headers, then body) waits ~40 ms for a delayed ACK
    return client;
  }

  // SIGTERM (the server finishes its tasks in hand and exits), SIGKILL after 20 s; the exit code.
  int Stop() {
    if (!Reaped()) ::kill(pid_, SIGTERM);
    for (int waited_ms = 0; !Reaped(); waited_ms += 10) {
      if (waited_ms == 20000) ::kill(pid_, SIGKILL);
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return exit_code_;
  }

 private:
  bool Reaped() {
    int status = 0;
    if (exit_code_ < 0 && ::waitpid(pid_, &status, WNOHANG) == pid_)
      exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    return exit_code_ >= 0;
  }

  void WaitUntilServing() {
    const std::string marker = "serving http://127.0.0.1:";
    for (int waited_ms = 0; waited_ms < 20000; waited_ms += 10) {
      const std::string log = Log();
      if (const size_t at = log.find(marker); at != std::string::npos && log.find('\n', at) != std::string::npos) {
        port_ = std::atoi(log.c_str() + at + marker.size());
        return;
      }
      if (!Alive()) throw std::runtime_error("strokelab serve exited at start:\n" + log);
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    throw std::runtime_error("strokelab serve did not come up in 20 s:\n" + Log());
  }

  fs::path log_;
  pid_t pid_ = -1;
  int port_ = 0;
  int exit_code_ = -1;
};

}  // namespace strokelab::testing
