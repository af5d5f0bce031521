// What the service's load programs (service_load.cc, remote_load.cc) share: a `strokelab serve` child
// on a scratch database, started on a free port, stopped (SIGTERM, then SIGKILL) and its directory
// removed when it goes out of scope; the server to load (that child, or --server URL); a flag's
// value; latency percentiles.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace strokelab::bench {

class ServerProcess {
 public:
  ServerProcess() = default;
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;
  ~ServerProcess() {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      int status = 0;
      for (int i = 0; i < 200 && waitpid(pid_, &status, WNOHANG) == 0; ++i) usleep(50000);
      kill(pid_, SIGKILL);
      waitpid(pid_, &status, 0);
    }
    if (!dir_.empty()) std::filesystem::remove_all(dir_);
  }

  // Runs `binary serve --port 0 --db SCRATCH/load.db --quiet EXTRA...` (stderr to SCRATCH/serve.log)
  // and returns its port once it prints "strokelab serving".
  int Start(const std::string& binary, const std::vector<std::string>& extra_args) {
    std::string pattern = (std::filesystem::temp_directory_path() / "strokelab-load-XXXXXX").string();
    if (!mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
    dir_ = pattern;
    const std::string log = (dir_ / "serve.log").string(), db = (dir_ / "load.db").string();
    std::vector<std::string> args = {binary, "serve", "--port", "0", "--db", db, "--quiet"};
    args.insert(args.end(), extra_args.begin(), extra_args.end());
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 2, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int rc = posix_spawn(&pid_, binary.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (rc != 0) throw std::runtime_error("cannot start " + binary + ": " + std::strerror(rc));
    const std::string marker = "strokelab serving http://127.0.0.1:";
    for (const auto start = std::chrono::steady_clock::now();
         std::chrono::steady_clock::now() - start < std::chrono::seconds(15);) {
      std::ifstream in(log);
      std::stringstream s;
      s << in.rdbuf();
      if (const size_t at = s.str().find(marker); at != std::string::npos)
        return std::atoi(s.str().c_str() + at + marker.size());
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    throw std::runtime_error("the server did not come up (see " + log + ")");
  }

 private:
  pid_t pid_ = 0;
  std::filesystem::path dir_;
};

struct ServerAddress {
  std::string host = "127.0.0.1";
  int port = 0;
};

// `server_url` (http://HOST:PORT), or else `owned` started from `binary` with `extra_args`.
inline ServerAddress ServerToLoad(const std::string& server_url, ServerProcess& owned, const std::string& binary,
                                  const std::vector<std::string>& extra_args) {
  ServerAddress a;
  if (server_url.empty()) {
    a.port = owned.Start(binary, extra_args);
  } else {
    const std::string rest = server_url.substr(server_url.find("//") + 2);
    a.host = rest.substr(0, rest.rfind(':'));
    a.port = std::stoi(rest.substr(rest.rfind(':') + 1));
  }
  return a;
}

// The value after flag argv[i] (i moves on to it); throws when there is none.
inline std::string FlagValue(int argc, char** argv, int& i) {
  if (i + 1 >= argc) throw std::runtime_error(std::string(argv[i]) + ": needs a value");
  return argv[++i];
}

// The options both load programs take: the server (a binary to start, or --server URL), the
// sweep's grid, how long to measure, and the output format.
struct LoadOptions {
  std::string binary;  // the program's default: the strokelab built beside it
  std::string server;  // empty: start one
  int frequency_points = 1000, amplitude_points = 200;
  double seconds = 5;
  bool json_out = false;
};

// Takes argv[i] (and its value, moving i on) when it is one of LoadOptions' flags.
inline bool TakeLoadFlag(int argc, char** argv, int& i, LoadOptions& o) {
  const std::string a = argv[i];
  if (a == "--binary") o.binary = FlagValue(argc, argv, i);
  else if (a == "--server") o.server = FlagValue(argc, argv, i);
  else if (a == "--seconds") o.seconds = std::stod(FlagValue(argc, argv, i));
  else if (a == "--frequency-points") o.frequency_points = std::stoi(FlagValue(argc, argv, i));
  else if (a == "--amplitude-points") o.amplitude_points = std::stoi(FlagValue(argc, argv, i));
  else if (a == "--json") o.json_out = true;
  else return false;
  return true;
}

// The q-quantile (0..1) of `v`, nearest rank; 0 for none.
inline double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

}  // namespace strokelab::bench
