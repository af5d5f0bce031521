// Bad input, wide: every generated malformed request of bad_input_cases.cc against the real
// `strokelab serve` (tokens on, no workers of its own, so nothing changes under the requests). Each
// must get its 4xx with the documented error object; the server must answer /v1/health after each
// group, leave the two jobs it holds as they were, and not grow: its resident set is read after six
// warm-up rounds of the whole table (the HTTP threads' stacks and caches grow to their depth only
// once each thread has served the heaviest cases; with two, +50-90 KiB a round were still seen on
// 16 threads) and after each of kMeasuredRounds more.
//
// The memory bound: after the warm-up every code path has run (the server runs with fixed malloc
// thresholds, kSteadyMalloc), so what requests keep shows as growth round after round; the median
// growth per round must stay below kMaxGrowthPerRoundKib, 64 KiB. The median, not the total, because
// the allocator also moves in one-off steps that are no leak: seen without one, in 25 runs, a rise of
// 1.7 or 4.9 MB in one round that then stays flat, and a body still held when RSS is read (+5-7 MB,
// given back by the next round); either failed the former bound on the total over 8 rounds (512 KiB;
// 2 runs in 25, and once in a clean-clone CI run). Without them a round grows 0-16 KiB.
// What it catches, measured with a leak planted in the pre-routing handler: 4 KiB kept per request
// fails (+2.2 MB a round); 1 KiB or 128 B per request goes into heap the warm-up freed and is not
// seen in 8 rounds (nor was it by the total). Small unreachable leaks are LeakSanitizer's, which
// checks the server at its exit in the ASan stage.
// STROKELAB_RSS_TRACE=1 prints the RSS after every measured round.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bad_input_cases.h"
#include "serve_child.h"

namespace strokelab::testing {
namespace {

using nlohmann::json;

constexpr int kWarmUpRounds = 6;
constexpr int kMeasuredRounds = 8;
constexpr long kMaxGrowthPerRoundKib = 64;

// The median of the growths from one reading to the next [KiB].
long MedianGrowthKib(const std::vector<long>& readings_kib) {
  std::vector<long> growth;
  for (size_t i = 1; i < readings_kib.size(); ++i) growth.push_back(readings_kib[i] - readings_kib[i - 1]);
  std::sort(growth.begin(), growth.end());
  return growth[growth.size() / 2];
}

// glibc raises its mmap threshold after the first large free, after which the 1-2 MB bodies of the
// table land in the per-thread heaps and RSS wanders by +-15 MB with the order the threads serve
// them (measured). Fixed thresholds keep large blocks in mmap (returned on free) and one arena keeps
// fragmentation small, so that RSS follows what the server keeps rather than allocator history
// (with two, the second arena was sometimes first made during the measured rounds on a loaded
// machine: +12.5 MB once in six runs; with one, +20..40 KiB in ten runs).
const std::vector<std::string> kSteadyMalloc = {"MALLOC_ARENA_MAX=1", "MALLOC_MMAP_THRESHOLD_=65536",
                                                "MALLOC_TRIM_THRESHOLD_=131072"};

// What was wrong with one reply, or "" when it is the documented error.
std::string CheckReply(const BadRequest& b, const httplib::Result& result) {
  if (!result) return "no reply: " + httplib::to_string(result.error());
  const int status = result->status;
  if (status < 400 || status > 499) return "status " + std::to_string(status) + ": " + result->body.substr(0, 300);
  if (b.status != 0 && status != b.status)
    return "status " + std::to_string(status) + ", expected " + std::to_string(b.status) + ": " +
           result->body.substr(0, 300);
  if (result->get_header_value("Content-Type") != "application/json") return "not JSON: " + result->body.substr(0, 200);
  // Every refusal carries the security headers, the gate's own (408, 414, 429, 431) too (issue 15).
  for (const auto& [name, value] : {std::pair<const char*, const char*>{"X-Content-Type-Options", "nosniff"},
                                    {"X-Frame-Options", "DENY"}, {"Referrer-Policy", "no-referrer"}})
    if (result->get_header_value(name) != value) return std::string("no '") + name + ": " + value + "' header";
  json body;
  try {
    body = json::parse(result->body);
  } catch (const json::exception& e) {
    return std::string("body does not parse: ") + e.what();
  }
  if (!body.is_object() || body.size() != 1 || !body.contains("error") || !body["error"].is_object())
    return "not {\"error\": {...}}: " + body.dump();
  const json& error = body["error"];
  for (const auto& [key, value] : error.items()) {
    if (key != "code" && key != "message" && key != "field") return "unexpected key '" + key + "': " + body.dump();
    if (!value.is_string() || value.get<std::string>().empty()) return "'" + key + "' is not a non-empty string";
  }
  if (!error.contains("code") || !error.contains("message")) return "no code or message: " + body.dump();
  if (!b.code.empty() && error["code"] != b.code) return "code " + error["code"].dump() + ", expected " + b.code;
  const std::string field = error.value("field", "");
  if (b.field && field != *b.field)
    return "field '" + field + "', expected '" + *b.field + "' (" + error.value("message", "") + ")";
  return "";
}

class BadInputTest : public ::testing::Test {
 protected:
  void SetUp() override {
    tokens_ = {"submit-token-0123456789", "read-token-0123456789ab", "worker-token-0123456789"};
    const fs::path token_file = dir_.path() / "tokens";
    std::ofstream(token_file) << "submit " << tokens_.submit << "\nread " << tokens_.read << "\nworker "
                              << tokens_.worker << "\n";
    server_ = std::make_unique<ServeChild>(dir_.path() / "jobs.db", dir_.path() / "serve.log",
                                           std::vector<std::string>{"--workers", "0", "--token-file",
                                                                    token_file.string()},
                                           kSteadyMalloc);
    client_ = server_->Client();
    client_->set_keep_alive(true);
    client_->set_url_encode(false);  // the cases spell their paths byte for byte
    jobs_.sweep = Submit(ValidSweep());
    jobs_.simulate = Submit(ValidSimulate());
  }

  int64_t Submit(const json& job) {
    auto r = client_->Post("/v1/jobs", {{"Authorization", "Bearer " + tokens_.submit}}, job.dump(),
                           "application/json; charset=utf-8");
    if (!r || r->status != 201) throw std::runtime_error("valid job refused: " + (r ? r->body : std::string("no reply")));
    return json::parse(r->body).at("id").get<int64_t>();
  }

  std::string JobState(int64_t id) {
    auto r = client_->Get("/v1/jobs/" + std::to_string(id), {{"Authorization", "Bearer " + tokens_.read}});
    if (!r || r->status != 200) return "unreadable";
    const json job = json::parse(r->body);
    return job.at("status").get<std::string>() + " " + job.at("progress").dump();
  }

  bool Healthy() {
    auto r = client_->Get("/v1/health");
    return r && r->status == 200 && json::parse(r->body).value("status", "") == "ok";
  }

  // One round of the whole table; failures (with the case) are collected when `check` is set.
  void Round(const std::vector<BadRequest>& cases, bool check) {
    std::string group;
    for (const BadRequest& b : cases) {
      if (b.group != group) {
        if (!group.empty()) {
          ASSERT_TRUE(Healthy()) << "after the '" << group << "' requests";
        }
        group = b.group;
      }
      const httplib::Result result = client_->send(b.request);
      if (!check) continue;
      const std::string problem = CheckReply(b, result);
      EXPECT_EQ(problem, "") << "[" << b.group << "] " << b.name;
    }
    ASSERT_TRUE(Healthy()) << "after the '" << group << "' requests";
    ASSERT_TRUE(server_->Alive());
  }

  ScratchDirectory dir_{"strokelab-bad-input"};
  Tokens tokens_;
  KnownJobs jobs_;
  std::unique_ptr<ServeChild> server_;
  std::unique_ptr<httplib::Client> client_;
};

TEST_F(BadInputTest, EveryMalformedRequestGetsItsErrorAndTheServerNeitherFallsNorGrows) {
  const std::vector<BadRequest> cases = GenerateBadRequests(tokens_, jobs_);
  std::map<std::string, int> per_group;
  for (const BadRequest& b : cases) ++per_group[b.group];
  std::string counts;
  for (const auto& [group, n] : per_group) counts += " " + group + " " + std::to_string(n);
  std::printf("[          ] %zu malformed requests:%s\n", cases.size(), counts.c_str());
  EXPECT_GE(cases.size(), 200u);
  const std::string sweep_before = JobState(jobs_.sweep), simulate_before = JobState(jobs_.simulate);

  Round(cases, true);
  for (int i = 1; i < kWarmUpRounds; ++i) Round(cases, false);
  std::vector<long> readings_kib = {server_->RssKib()};
  for (int i = 0; i < kMeasuredRounds; ++i) {
    Round(cases, false);
    readings_kib.push_back(server_->RssKib());
    if (std::getenv("STROKELAB_RSS_TRACE")) std::printf("round %d: %ld KiB\n", i, readings_kib.back());
  }
  const long median_growth_kib = MedianGrowthKib(readings_kib);
  std::printf("[          ] server RSS %ld KiB after %d warm-up rounds, %ld KiB after %d more (%zu requests), "
              "median growth a round %+ld KiB\n",
              readings_kib.front(), kWarmUpRounds, readings_kib.back(), kMeasuredRounds,
              kMeasuredRounds * cases.size(), median_growth_kib);
  // Under AddressSanitizer freed memory sits in its quarantine (up to 256 MB) and under
  // ThreadSanitizer its shadow and history grow: RSS grows by design there (200 MB and 9.5 MB over
  // these rounds), and LeakSanitizer checks the server for leaks at its exit instead.
  if (!kSanitizedBuild) {
    EXPECT_LT(median_growth_kib, kMaxGrowthPerRoundKib);
  }

  EXPECT_EQ(JobState(jobs_.sweep), sweep_before) << "a refused request changed a job";
  EXPECT_EQ(JobState(jobs_.simulate), simulate_before);
  EXPECT_EQ(server_->Stop(), 0) << server_->Log().substr(0, 2000);
}

// The positive controls of the content-type rule: JSON with parameters, and a lease with no body.
TEST_F(BadInputTest, JsonWithACharsetAndEmptyLeaseBodiesAreAccepted) {
  EXPECT_GT(Submit(ValidSimulate()), 0);  // "application/json; charset=utf-8"
  auto r = client_->Post("/v1/tasks/lease", {{"Authorization", "Bearer " + tokens_.worker}}, "", "");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200) << r->body;  // the oldest queued task: the sweep's
  EXPECT_EQ(json::parse(r->body).at("job_id"), jobs_.sweep);
}

}  // namespace
}  // namespace strokelab::testing
