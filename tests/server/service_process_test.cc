// The service as separate processes on loopback: the real `strokelab serve` and `strokelab worker`
// binaries started as children, talked to over HTTP on 127.0.0.1, killed with SIGKILL mid-run.
//
//   CrashAndResume: a 2,000-point sweep on one in-process worker; the server is SIGKILLed three
//     times at different progress levels and restarted on the same file; the job finishes with
//     every point exactly once and bitwise equal to a single-process CLI sweep.
//   RemoteWorkerKilledMidLease: a server with no workers of its own and 2 s leases, three remote
//     worker processes, one SIGKILLed while it holds a lease; its task is leased again after expiry
//     and every task's rows are stored exactly once.
//   WorkerTokens: a worker with a read token is refused (exits non-zero saying so); with a worker
//     token it completes the job.
//
// Every child is SIGKILLed and reaped when its guard goes out of scope, so a failing test leaves no
// process behind; ports are chosen by the server (--port 0) and read from its "serving" line.
#include <fcntl.h>
#include <gtest/gtest.h>

#include "strokelab/server/jobs.h"
#include <httplib.h>
#include <signal.h>
#include <spawn.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "strokelab/model.h"
#include "strokelab/sweep.h"

extern char** environ;

namespace {

using nlohmann::json;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

void SleepMs(int ms) { std::this_thread::sleep_for(std::chrono::milliseconds(ms)); }

std::string ReadFile(const fs::path& path) {
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

// A `strokelab serve --port 0` process and the port it reported.
struct Server {
  std::unique_ptr<Child> child;
  int port = 0;
  std::string Url() const { return "http://127.0.0.1:" + std::to_string(port); }
};

Server StartServer(const fs::path& dir, const std::string& name, const std::vector<std::string>& extra) {
  std::vector<std::string> argv = {STROKELAB_BINARY, "serve", "--port", "0"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  Server s;
  s.child = std::make_unique<Child>(argv, dir / (name + ".log"));
  const std::string marker = "strokelab serving http://127.0.0.1:";
  const auto start = Clock::now();
  for (;;) {
    const std::string log = s.child->Log();
    if (const size_t at = log.find(marker); at != std::string::npos) {
      s.port = std::atoi(log.c_str() + at + marker.size());
      if (s.port > 0) return s;
    }
    if (const auto code = s.child->Poll())
      throw std::runtime_error("server " + name + " exited with " + std::to_string(*code) + ":\n" + log);
    if (SecondsSince(start) > 15) throw std::runtime_error("server " + name + " did not come up in 15 s:\n" + log);
    SleepMs(5);
  }
}

std::unique_ptr<Child> StartWorker(const fs::path& dir, const Server& server, const std::string& name,
                                   const std::vector<std::string>& extra) {
  std::vector<std::string> argv = {STROKELAB_BINARY, "worker", "--server", server.Url(), "--name", name};
  argv.insert(argv.end(), extra.begin(), extra.end());
  return std::make_unique<Child>(argv, dir / (name + ".log"));
}

// A scratch directory, removed at the end unless the test failed (then its path is printed).
class ScratchDir {
 public:
  ScratchDir() {
    std::string pattern = (fs::temp_directory_path() / "strokelab-svcproc-XXXXXX").string();
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

httplib::Headers Bearer(const std::string& token) {
  if (token.empty()) return {};
  return {{"Authorization", "Bearer " + token}};
}

std::unique_ptr<httplib::Client> Client(const Server& s) {
  auto c = std::make_unique<httplib::Client>("127.0.0.1", s.port);
  c->set_connection_timeout(5);
  c->set_read_timeout(30);
  return c;
}

json GetJson(httplib::Client& c, const std::string& path, const std::string& token = "") {
  auto r = c.Get(path, Bearer(token));
  if (!r) throw std::runtime_error("GET " + path + ": " + httplib::to_string(r.error()));
  if (r->status != 200) throw std::runtime_error("GET " + path + ": HTTP " + std::to_string(r->status) + " " + r->body);
  return json::parse(r->body);
}

int64_t Submit(httplib::Client& c, const json& job, const std::string& token = "") {
  auto r = c.Post("/v1/jobs", Bearer(token), job.dump(), "application/json");
  if (!r) throw std::runtime_error("POST /v1/jobs: " + httplib::to_string(r.error()));
  if (r->status != 201) throw std::runtime_error("POST /v1/jobs: HTTP " + std::to_string(r->status) + " " + r->body);
  return json::parse(r->body).at("id").get<int64_t>();
}

json SweepJob(int frequency_points, int amplitude_points, bool thresholds) {
  return {{"kind", "sweep"},
          {"model", "paper"},
          {"thresholds", thresholds},
          {"grid", {{"frequency_hz", {{"from", 5}, {"to", 50}, {"points", frequency_points}}},
                    {"amplitude_v", {{"from", 0.1}, {"to", 0.6}, {"points", amplitude_points}}}}}};
}

// Polls GET /v1/jobs/{id} every `poll_ms` until it is no longer queued or running.
json WaitForFinish(httplib::Client& c, int64_t id, double timeout_s, const std::string& token = "", int poll_ms = 20) {
  const auto start = Clock::now();
  for (;;) {
    const json job = GetJson(c, "/v1/jobs/" + std::to_string(id), token);
    const std::string status = job.at("status");
    if (status != "queued" && status != "running") return job;
    if (SecondsSince(start) > timeout_s)
      throw std::runtime_error("job " + std::to_string(id) + " not finished after " + std::to_string(timeout_s) +
                               " s: " + job.dump());
    SleepMs(poll_ms);
  }
}

// Every row of a job's points (optionally one branch), following the cursors, pages of 1000.
std::vector<json> FetchPoints(httplib::Client& c, int64_t id, const std::string& branch = "",
                              const std::string& token = "") {
  std::vector<json> rows;
  std::string cursor = "0";
  for (int pages = 0; pages < 100000; ++pages) {
    std::string path = "/v1/jobs/" + std::to_string(id) + "/points?limit=1000&cursor=" + cursor;
    if (!branch.empty()) path += "&branch=" + branch;
    const json page = GetJson(c, path, token);
    for (const json& p : page.at("points")) rows.push_back(p);
    if (page.at("next_cursor").is_null()) return rows;
    cursor = std::to_string(page.at("next_cursor").get<int64_t>());
  }
  throw std::runtime_error("points: cursor does not end");
}

// Equality of two JSON values with numbers compared bit for bit (and by JSON number type), so
// that 0.1 and 0.1 + 1 ulp, or -0.0 and 0.0, differ.
bool BitwiseEqual(const json& a, const json& b) {
  if (a.type() != b.type()) return false;
  switch (a.type()) {
    case json::value_t::number_float: {
      const double x = a.get<double>(), y = b.get<double>();
      return std::memcmp(&x, &y, sizeof x) == 0;
    }
    case json::value_t::object: {
      if (a.size() != b.size()) return false;
      for (auto it = a.begin(); it != a.end(); ++it)
        if (!b.contains(it.key()) || !BitwiseEqual(it.value(), b.at(it.key()))) return false;
      return true;
    }
    case json::value_t::array: {
      if (a.size() != b.size()) return false;
      for (size_t i = 0; i < a.size(); ++i)
        if (!BitwiseEqual(a[i], b[i])) return false;
      return true;
    }
    default: return a == b;
  }
}

// Checks that `got` is `want` row for row (the store pages rows in task order, tasks are planned
// in amplitude order, and a task's rows are in the core's order: the CLI's order). Reports the
// first difference.
void ExpectSameRows(const std::vector<json>& got, const json& want, const std::string& what) {
  EXPECT_EQ(got.size(), want.size()) << what << ": row count";
  const size_t n = std::min(got.size(), want.size());
  size_t differing = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!BitwiseEqual(got[i], want[i])) {
      if (differing++ == 0)
        ADD_FAILURE() << what << ": first difference at row " << i << ":\n  service: " << got[i].dump()
                      << "\n  single process: " << want[i].dump();
    }
  }
  EXPECT_EQ(differing, 0u) << what << ": rows that differ";
}

// Up and down rows: exactly one per grid point and branch; no row (with all its values) twice.
void ExpectEachGridPointOnce(const std::vector<json>& rows, size_t grid_points) {
  std::map<std::string, std::set<std::pair<double, double>>> by_branch;
  std::map<std::tuple<double, double, std::string>, int> count;
  std::set<std::string> distinct_rows;
  for (const json& p : rows) {
    const double f = p.at("frequency_hz"), a = p.at("amplitude_v");
    const std::string branch = p.at("branch");
    by_branch[branch].insert({f, a});
    ++count[{f, a, branch}];
    distinct_rows.insert(p.dump());
  }
  EXPECT_EQ(by_branch["up"].size(), grid_points);
  EXPECT_EQ(by_branch["down"].size(), grid_points);
  for (const auto& [key, n] : count) {
    if (std::get<2>(key) != "unstable") {
      EXPECT_EQ(n, 1) << std::get<2>(key) << " at " << std::get<0>(key) << " Hz, " << std::get<1>(key) << " V";
    }
  }
  EXPECT_EQ(distinct_rows.size(), rows.size()) << "some rows are stored twice";
}

// The single-process reference: `strokelab sweep ... --json` on the same grid.
json CliSweep(const fs::path& dir, int frequency_points, int amplitude_points) {
  Child cli({STROKELAB_BINARY, "sweep", "--model", "paper", "--frequency-hz", "5:50", "--frequency-points",
             std::to_string(frequency_points), "--amplitude-v", "0.1:0.6", "--amplitude-points",
             std::to_string(amplitude_points), "--threads", "2", "--json"},
            dir / "cli-sweep.log");
  const int code = cli.WaitExit(60);
  if (code != 0) throw std::runtime_error("strokelab sweep exited with " + std::to_string(code) + ":\n" + cli.Log());
  return json::parse(cli.Out());
}

// Checks the saturation map (thresholds per frequency, jump intervals) against the reference.
void ExpectSameMap(httplib::Client& c, int64_t id, const json& reference) {
  const json map = GetJson(c, "/v1/jobs/" + std::to_string(id) + "/saturation-map");
  const json& thresholds = map.at("saturation_threshold");
  std::vector<json> got(thresholds.begin(), thresholds.end());
  ExpectSameRows(got, reference.at("saturation_threshold"), "saturation thresholds");
  std::vector<json> jumps(map.at("jump").begin(), map.at("jump").end());
  ExpectSameRows(jumps, reference.at("jump"), "jump intervals");
}

// Read-only looks at the server's database file from the test (another connection; WAL allows it
// while the server writes). Never checkpoints on close, so a crashed server's file stays as it was.
class Db {
 public:
  explicit Db(const fs::path& path) {
    if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READWRITE, nullptr) != SQLITE_OK)
      throw std::runtime_error("cannot open " + path.string());
    sqlite3_busy_timeout(db_, 5000);
    sqlite3_db_config(db_, SQLITE_DBCONFIG_NO_CKPT_ON_CLOSE, 1, nullptr);
  }
  ~Db() { sqlite3_close_v2(db_); }
  Db(const Db&) = delete;
  Db& operator=(const Db&) = delete;
  // Rows of a query as text ("" for NULL).
  std::vector<std::vector<std::string>> Query(const std::string& sql) {
    std::vector<std::vector<std::string>> rows;
    char* error = nullptr;
    auto collect = [](void* out, int n, char** values, char**) {
      auto& r = *static_cast<std::vector<std::vector<std::string>>*>(out);
      r.emplace_back();
      for (int i = 0; i < n; ++i) r.back().push_back(values[i] ? values[i] : "");
      return 0;
    };
    if (sqlite3_exec(db_, sql.c_str(), collect, &rows, &error) != SQLITE_OK) {
      const std::string what = error ? error : "?";
      sqlite3_free(error);
      throw std::runtime_error("query failed: " + what + " in " + sql);
    }
    return rows;
  }
  std::string One(const std::string& sql) {
    const auto rows = Query(sql);
    return rows.empty() || rows[0].empty() ? "" : rows[0][0];
  }

 private:
  sqlite3* db_ = nullptr;
};

// ---------------------------------------------------------------------------------------------

TEST(ServiceProcess, CrashAndResume) {
  const auto test_start = Clock::now();
  ScratchDir dir;
  const std::string db = (dir.path() / "jobs.db").string();
  const std::vector<std::string> serve_args = {"--workers", "1", "--db", db};
  constexpr int kFrequencies = 200, kAmplitudes = 10;

  Server server = StartServer(dir.path(), "serve-0", serve_args);
  const int64_t id = Submit(*Client(server), SweepJob(kFrequencies, kAmplitudes, true));
  const json first = GetJson(*Client(server), "/v1/jobs/" + std::to_string(id));
  const int total = first.at("progress").at("total");
  ASSERT_EQ(total, kAmplitudes + (kFrequencies + 15) / 16);  // rows + threshold column chunks

  // Kill at about 1/10, 2/5 and 3/4 of the tasks.
  const std::vector<int> targets = {2, total * 2 / 5, total * 3 / 4};
  int kills_with_lease = 0;
  for (size_t k = 0; k < targets.size(); ++k) {
    auto client = Client(server);
    int seen = 0;
    const auto wait_start = Clock::now();
    for (;;) {
      const json job = GetJson(*client, "/v1/jobs/" + std::to_string(id));
      seen = job.at("progress").at("done");
      ASSERT_TRUE(job.at("status") == "running" || job.at("status") == "queued")
          << "the job finished before kill " << k + 1 << " (make the grid heavier): " << job.dump();
      if (seen >= targets[k]) break;
      ASSERT_LT(SecondsSince(wait_start), 30) << job.dump();
      SleepMs(20);
    }
    server.child->Signal(SIGKILL);
    ASSERT_EQ(server.child->WaitExit(10), 128 + SIGKILL);

    // What the dead server left in the file: the job unfinished, a lease held by its worker.
    int done_at_kill = 0, leased_at_kill = 0;
    {
      Db file(db);
      done_at_kill = std::stoi(file.One("SELECT tasks_done FROM jobs WHERE id = " + std::to_string(id)));
      EXPECT_EQ(file.One("SELECT status FROM jobs WHERE id = " + std::to_string(id)), "running");
      leased_at_kill = std::stoi(file.One("SELECT count(*) FROM tasks WHERE status = 'leased' AND lease_owner LIKE 'local-%'"));
    }
    EXPECT_GE(done_at_kill, seen);
    kills_with_lease += leased_at_kill > 0;
    EXPECT_LT(done_at_kill, total) << "kill " << k + 1 << " came after the job had finished";

    const auto restart = Clock::now();
    server = StartServer(dir.path(), "serve-" + std::to_string(k + 1), serve_args);
    if (leased_at_kill > 0) {
      EXPECT_NE(server.child->Log().find("\"released_leases\":" + std::to_string(leased_at_kill)), std::string::npos)
          << server.child->Log();
    }
    // The restarted server resumes at once (its dead worker's lease is released, not waited out).
    auto c = Client(server);
    double resumed_s = -1;
    for (;;) {
      const json job = GetJson(*c, "/v1/jobs/" + std::to_string(id));
      if (job.at("progress").at("done").get<int>() > done_at_kill || job.at("status") == "succeeded") {
        resumed_s = SecondsSince(restart);
        break;
      }
      ASSERT_LT(SecondsSince(restart), 20) << "no progress after restart " << k + 1 << ": " << job.dump();
      SleepMs(5);
    }
    EXPECT_LT(resumed_s, 10);
    std::printf("kill %zu: at %d/%d tasks done (%d leased); restart to next task done: %.3f s\n", k + 1,
                done_at_kill, total, leased_at_kill, resumed_s);
  }

  // A kill between two tasks leaves no lease; the worker holds one nearly all the time.
  EXPECT_GE(kills_with_lease, 1) << "no kill caught a task in flight";

  auto client = Client(server);
  const json job = WaitForFinish(*client, id, 30);
  ASSERT_EQ(job.at("status"), "succeeded") << job.dump();
  EXPECT_EQ(job.at("progress").at("done"), total);

  const std::vector<json> points = FetchPoints(*client, id);
  ExpectEachGridPointOnce(points, kFrequencies * kAmplitudes);
  EXPECT_EQ(FetchPoints(*client, id, "up").size(), size_t{kFrequencies * kAmplitudes});
  EXPECT_EQ(FetchPoints(*client, id, "down").size(), size_t{kFrequencies * kAmplitudes});
  {
    Db file(db);
    // Leases granted beyond one per task: one per kill that caught a task in flight.
    std::printf("task leases granted: %s for %d tasks\n",
                file.One("SELECT sum(attempts) FROM tasks WHERE job_id = " + std::to_string(id)).c_str(), total);
  }

  const double service_s = SecondsSince(test_start);
  const json reference = CliSweep(dir.path(), kFrequencies, kAmplitudes);
  ExpectSameRows(points, reference.at("points"), "points");
  ExpectSameMap(*client, id, reference);
  std::printf("%zu point rows; service part %.2f s, whole test %.2f s\n", points.size(), service_s,
              SecondsSince(test_start));

  server.child->Signal(SIGTERM);
  EXPECT_EQ(server.child->WaitExit(20), 0) << server.child->Log();
}

TEST(ServiceProcess, RemoteWorkerKilledMidLease) {
  const auto test_start = Clock::now();
  ScratchDir dir;
  const std::string db = (dir.path() / "jobs.db").string();
  constexpr int kFrequencies = 200, kAmplitudes = 27;  // 27 rows + 13 column chunks = 40 tasks
  constexpr int64_t kLeaseMs = 2000;

  Server server = StartServer(dir.path(), "serve", {"--workers", "0", "--lease-s", "2", "--db", db, "--quiet"});
  auto client = Client(server);
  const int64_t id = Submit(*client, SweepJob(kFrequencies, kAmplitudes, true));
  const int total = GetJson(*client, "/v1/jobs/" + std::to_string(id)).at("progress").at("total");
  ASSERT_EQ(total, 40);

  std::vector<std::unique_ptr<Child>> survivors;
  auto victim = StartWorker(dir.path(), server, "victim", {"--threads", "1"});
  survivors.push_back(StartWorker(dir.path(), server, "w1", {"--threads", "1"}));
  survivors.push_back(StartWorker(dir.path(), server, "w2", {"--threads", "1"}));

  // Kill the victim while it holds a lease: freeze it (SIGSTOP) when the file shows it holding one,
  // let requests in flight settle, and kill it only if it still holds that lease; else thaw, retry.
  std::string victim_task;
  int64_t victim_expires_ms = 0;
  {
    Db file(db);
    const auto start = Clock::now();
    while (victim_task.empty()) {
      ASSERT_LT(SecondsSince(start), 20) << "the victim never held a lease:\n" << victim->Log();
      ASSERT_FALSE(victim->Poll()) << victim->Log();
      const auto held = file.Query(
          "SELECT id, lease_token, lease_expires_ms FROM tasks WHERE status = 'leased' AND lease_owner = 'remote:victim-0'");
      if (held.empty()) {
        SleepMs(2);
        continue;
      }
      victim->Signal(SIGSTOP);
      SleepMs(100);
      const auto still = file.Query("SELECT lease_token FROM tasks WHERE id = " + held[0][0] +
                                    " AND status = 'leased' AND lease_owner = 'remote:victim-0'");
      if (!still.empty() && still[0][0] == held[0][1]) {
        victim->Kill();
        victim_task = held[0][0];
        victim_expires_ms = std::stoll(held[0][2]);
      } else {
        victim->Signal(SIGCONT);
      }
    }
  }
  const double killed_at_s = SecondsSince(test_start);

  const json job = WaitForFinish(*client, id, 40);
  const double finished_at_s = SecondsSince(test_start);
  ASSERT_EQ(job.at("status"), "succeeded") << job.dump();

  // The victim's task: leased again after its lease expired, and completed by another worker.
  Db file(db);
  const auto task = file.Query("SELECT status, attempts, lease_owner, finished_ms FROM tasks WHERE id = " + victim_task);
  ASSERT_EQ(task.size(), 1u);
  EXPECT_EQ(task[0][0], "done");
  EXPECT_GE(std::stoi(task[0][1]), 2);
  EXPECT_NE(task[0][2], "remote:victim-0");
  EXPECT_GE(std::stoll(task[0][3]), victim_expires_ms) << "taken over before the lease expired";
  EXPECT_EQ(file.One("SELECT count(*) FROM tasks WHERE job_id = " + std::to_string(id) + " AND status != 'done'"), "0");

  // Each task's rows exactly once: row_idx 0..n-1 per task, and the same rows as a run without kills.
  const auto per_task = file.Query("SELECT task_idx, count(*), max(row_idx) FROM results WHERE job_id = " +
                                   std::to_string(id) + " GROUP BY task_idx ORDER BY task_idx");
  ASSERT_EQ(per_task.size(), size_t(total));
  for (const auto& t : per_task) EXPECT_EQ(std::stoll(t[1]), std::stoll(t[2]) + 1) << "task " << t[0];

  const std::vector<json> points = FetchPoints(*client, id);
  ExpectEachGridPointOnce(points, kFrequencies * kAmplitudes);
  const json reference = CliSweep(dir.path(), kFrequencies, kAmplitudes);
  ExpectSameRows(points, reference.at("points"), "points");
  ExpectSameMap(*client, id, reference);

  // Who did what: the survivors' own counts agree with the file; all tasks are accounted for.
  int by_workers = std::stoi(file.One("SELECT count(*) FROM tasks WHERE job_id = " + std::to_string(id) +
                                      " AND status = 'done' AND lease_owner = 'remote:victim-0'"));
  const int by_victim = by_workers;
  for (size_t i = 0; i < survivors.size(); ++i) {
    const std::string name = "w" + std::to_string(i + 1);
    survivors[i]->Signal(SIGTERM);
    EXPECT_EQ(survivors[i]->WaitExit(20), 0) << survivors[i]->Log();
    const int in_file = std::stoi(file.One("SELECT count(*) FROM tasks WHERE job_id = " + std::to_string(id) +
                                           " AND status = 'done' AND lease_owner = 'remote:" + name + "-0'"));
    EXPECT_NE(survivors[i]->Log().find("worker " + name + ": " + std::to_string(in_file) + " tasks completed"),
              std::string::npos)
        << survivors[i]->Log();
    by_workers += in_file;
  }
  EXPECT_EQ(by_workers, total);
  std::printf("victim killed holding task %s at %.2f s (had completed %d); job done at %.2f s (lease %lld ms); "
              "whole test %.2f s\n",
              victim_task.c_str(), killed_at_s, by_victim, finished_at_s, static_cast<long long>(kLeaseMs),
              SecondsSince(test_start));
}

TEST(ServiceProcess, WorkerTokens) {
  const auto test_start = Clock::now();
  ScratchDir dir;
  const std::string submit = "submit-token-0123456789abcdef", read = "read-token-0123456789abcdef",
                    worker = "worker-token-0123456789abcdef";
  {
    std::ofstream tokens(dir.path() / "tokens");
    tokens << "# roles and tokens\nsubmit " << submit << "\nread " << read << "\nworker " << worker << "\n";
  }
  Server server = StartServer(dir.path(), "serve",
                              {"--workers", "0", "--db", (dir.path() / "jobs.db").string(), "--token-file",
                               (dir.path() / "tokens").string(), "--quiet"});
  auto client = Client(server);
  constexpr int kFrequencies = 20, kAmplitudes = 2;
  const json job = SweepJob(kFrequencies, kAmplitudes, false);  // 2 tasks

  // Submitting: only the submit token.
  for (const auto& [token, status] : std::vector<std::pair<std::string, int>>{
           {"", 401}, {"wrong-token-0123456789abcdef", 401}, {read, 403}, {worker, 403}}) {
    auto r = client->Post("/v1/jobs", Bearer(token), job.dump(), "application/json");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, status) << "token '" << token << "': " << r->body;
  }
  const int64_t id = Submit(*client, job, submit);

  // A worker with a read token, or none, is refused and says so.
  for (const std::string& token : {read, std::string()}) {
    std::vector<std::string> args = {"--threads", "1"};
    if (!token.empty()) args.insert(args.end(), {"--token", token});
    auto refused = StartWorker(dir.path(), server, token.empty() ? "no-token" : "read-token", args);
    const int code = refused->WaitExit(10);
    EXPECT_NE(code, 0);
    EXPECT_LT(code, 128) << "killed by a signal";
    EXPECT_NE(refused->Log().find("refused the token"), std::string::npos) << refused->Log();
    EXPECT_NE(refused->Log().find(token.empty() ? "HTTP 401" : "HTTP 403"), std::string::npos) << refused->Log();
  }
  EXPECT_EQ(GetJson(*client, "/v1/jobs/" + std::to_string(id), read).at("progress").at("done"), 0);

  // With the worker token it leases and completes both tasks, then stops (--max-tasks 2).
  auto good = StartWorker(dir.path(), server, "good", {"--threads", "1", "--token", worker, "--max-tasks", "2"});
  EXPECT_EQ(good->WaitExit(20), 0) << good->Log();
  EXPECT_NE(good->Log().find("2 tasks completed"), std::string::npos) << good->Log();
  const json done = WaitForFinish(*client, id, 10, read);
  EXPECT_EQ(done.at("status"), "succeeded") << done.dump();

  // The rows equal core's SweepRow in this process, row by row.
  const std::vector<json> points = FetchPoints(*client, id, "", read);
  std::vector<json> want;
  const std::vector<double> frequencies = strokelab::GridAxis{5, 50, kFrequencies}.Values();
  for (double amplitude : strokelab::GridAxis{0.1, 0.6, kAmplitudes}.Values()) {
    for (const strokelab::SweepPoint& p : strokelab::SweepRow(strokelab::PaperModel(), amplitude, frequencies).points) {
      const json row = strokelab::server::SweepPointJson(p);
      want.push_back(json::parse(row.dump()));  // as stored: through JSON text
    }
  }
  ExpectSameRows(points, json(want), "points");
  ExpectEachGridPointOnce(points, kFrequencies * kAmplitudes);
  std::printf("whole test %.2f s\n", SecondsSince(test_start));
}

}  // namespace
