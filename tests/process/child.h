// Child processes for tests that run the real strokelab binaries: a spawned process with its
// stdout and stderr in files, killed and reaped when its guard goes out of scope, and a scratch
// directory kept when the test failed.
#pragma once

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace strokelab::test_process {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

inline double SecondsSince(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

inline void SleepMs(int ms) { std::this_thread::sleep_for(std::chrono::milliseconds(ms)); }

inline std::string ReadFile(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// A child process with stdout and stderr in files. SIGKILLed and reaped on destruction unless it
// has already been reaped.
class Child {
 public:
  Child(const std::vector<std::string>& argv, const fs::path& log_path) : log_path_(log_path) {
    const std::string out_path = log_path.string() + ".out";
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 1, out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&actions, 2, log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    const int rc = posix_spawn(&pid_, argv[0].c_str(), &actions, nullptr, args.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (rc != 0) throw std::runtime_error("cannot start " + argv[0] + ": " + std::strerror(rc));
  }
  ~Child() {
    if (!status_) {
      kill(pid_, SIGKILL);
      int status = 0;
      waitpid(pid_, &status, 0);
    }
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  pid_t pid() const { return pid_; }
  void Signal(int sig) {
    if (!status_) kill(pid_, sig);
  }
  // The exit code (128 + signal when killed) once the process has ended; nullopt while it runs.
  std::optional<int> Poll() {
    if (status_) return status_;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_)
      status_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    return status_;
  }
  int WaitExit(double timeout_s) {
    const auto start = Clock::now();
    while (!Poll()) {
      if (SecondsSince(start) > timeout_s) {
        throw std::runtime_error("process " + std::to_string(pid_) + " did not exit within " +
                                 std::to_string(timeout_s) + " s; its stderr:\n" + Log());
      }
      SleepMs(5);
    }
    return *status_;
  }
  void Kill() {
    Signal(SIGKILL);
    WaitExit(10);
  }
  std::string Log() const { return ReadFile(log_path_); }
  std::string Out() const { return ReadFile(log_path_.string() + ".out"); }

 private:
  fs::path log_path_;
  pid_t pid_ = 0;
  std::optional<int> status_;
};

// A scratch directory, removed at the end unless the test failed (then its path is printed).
class ScratchDir {
 public:
  explicit ScratchDir(const std::string& prefix = "strokelab-svcproc") {
    std::string pattern = (fs::temp_directory_path() / (prefix + "-XXXXXX")).string();
    if (!mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~ScratchDir() {
    if (::testing::Test::HasFailure()) {
      std::fprintf(stderr, "scratch directory kept: %s\n", path_.c_str());
      return;
    }
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

}  // namespace strokelab::test_process
