// Fit and diagnose tasks run by remote workers (issue 17): the real `strokelab serve --workers 0` and
// a `strokelab worker` process fit and diagnose a small synthesised campaign, the worker fetching it
// once by its SHA-256 and caching it; the campaign route serves only the worker holding a lease on a
// task over that campaign; a download changed on the way fails the worker's hash check; and the
// report the server serves is rendered by the server from the worker's data, so a worker's markup
// shows as text. SHA-256 against FIPS 180-4's examples, and the campaign bundle's strict unpacking.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "process/service.h"
#include "small_campaign.h"
#include "strokelab/jobs/campaign_bundle.h"
#include "strokelab/jobs/sha256.h"
#include "strokelab/report/diagnosis_data.h"
#include "strokelab/server/service.h"
#include "strokelab/worker/remote_worker.h"
#include "test_tokens.h"

namespace strokelab::server {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::strokelab::testing::kReadToken;
using ::strokelab::testing::kSubmitToken;
using ::strokelab::testing::kWorkerToken;
using ::testing::HasSubstr;
using ::testing::Not;

void WriteRemoteCampaign(const fs::path& dir) {
  ::strokelab::testing::WriteSmallCampaign(dir, dir.parent_path() / "truth.json", /*seed=*/11);
}

void WriteRemoteTokens(const fs::path& path) {
  std::ofstream(path) << "submit " << kSubmitToken << "\nread " << kReadToken << "\nworker " << kWorkerToken << "\n";
}

httplib::Headers BearerOf(const char* token) { return {{"Authorization", std::string("Bearer ") + token}}; }

size_t Occurrences(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// ---- The real processes ----------------------------------------------------------------------

TEST(RemoteCampaignProcess, AWorkerProcessFitsAndDiagnosesFetchingTheCampaignOnce) {
  namespace tp = ::strokelab::test_process;
  tp::ScratchDir dir("strokelab-remote-campaign");
  const fs::path campaign = dir.path() / "data" / "c";
  WriteRemoteCampaign(campaign);
  WriteRemoteTokens(dir.path() / "tokens");
  tp::Server server = tp::StartServer(dir.path(), "serve",
                              {"--workers", "0", "--db", (dir.path() / "jobs.db").string(), "--data-root",
                               (dir.path() / "data").string(), "--token-file", (dir.path() / "tokens").string()});
  const fs::path cache = dir.path() / "cache";
  auto worker = tp::StartWorker(dir.path(), server, "w", {"--token", kWorkerToken, "--cache-dir", cache.string()});
  auto client = tp::Client(server);
  client->set_read_timeout(60);
  const int64_t fit = tp::Submit(*client, {{"kind", "fit"}, {"campaign", {{"path", "c"}}}}, kSubmitToken);
  const int64_t diagnose = tp::Submit(*client,
                                  {{"kind", "diagnose"},
                                   {"campaign", {{"path", "c"}}},
                                   {"options", {{"heldout_every", 4}, {"pairs", false}, {"max_seconds", 3},
                                                {"map_frequency_points", 4}, {"map_amplitude_points", 2}}}},
                                  kSubmitToken);
  for (int64_t id : {fit, diagnose}) {
    const json job = tp::WaitForFinish(*client, id, 120, kReadToken);
    ASSERT_EQ(job["status"], "succeeded") << job.dump() << "\n" << worker->Log();
  }
  const std::string log = server.child->Log();
  // Both tasks went to the remote worker (the server has no workers of its own) ...
  EXPECT_EQ(Occurrences(log, "first task leased by remote:w-0"), 2u) << log;
  // ... which fetched the campaign once and found it in its cache the second time.
  const std::string sha = jobs::CampaignSha256(campaign);
  EXPECT_EQ(Occurrences(log, "\"path\":\"/v1/campaigns/" + sha + "\""), 1u) << log;
  EXPECT_TRUE(fs::is_directory(cache / sha));

  // (That a remote fit is the direct fit of the same files: CampaignJobsTest.WithoutInProcessWorkers...)
  EXPECT_TRUE(tp::GetJson(*client, "/v1/jobs/" + std::to_string(fit) + "/result", kReadToken).contains("parameters"));

  // The diagnosis: its result, and the report the server rendered from the worker's data.
  const std::string base = "/v1/jobs/" + std::to_string(diagnose);
  const json result = tp::GetJson(*client, base + "/result", kReadToken);
  ASSERT_TRUE(result.contains("conclusion")) << result.dump().substr(0, 300);
  auto page = client->Get(base + "/report", BearerOf(kReadToken));
  ASSERT_TRUE(page && page->status == 200) << (page ? page->body.substr(0, 300) : "no reply");
  EXPECT_THAT(page->get_header_value("Content-Type"), HasSubstr("text/html"));
  EXPECT_THAT(page->body, HasSubstr(result["conclusion"].get<std::string>().substr(0, 20)));
  EXPECT_THAT(page->body, HasSubstr("<h2 id=\"maps\">"));
  EXPECT_EQ(tp::GetJson(*client, base + "/report/model.json", kReadToken), result["model"]);
}

// ---- The campaign route and completions, in process --------------------------------------------

class RemoteCampaignTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = fs::path(::testing::TempDir()) / ("remote_campaign_test_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    WriteRemoteCampaign(root_ / "data" / "c");
  }
  static void TearDownTestSuite() { fs::remove_all(root_); }

  void SetUp() override {
    dir_ = root_ / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    WriteRemoteTokens(dir_ / "tokens");
    ServiceOptions options;
    options.port = 0;
    options.db_path = (dir_ / "jobs.db").string();
    options.workers = 0;
    options.token_file = (dir_ / "tokens").string();
    options.data_root = (root_ / "data").string();
    options.quiet = true;
    service_ = std::make_unique<Service>(options);
    port_ = service_->Start();
  }
  void TearDown() override {
    service_.reset();
    fs::remove_all(dir_);
  }

  httplib::Client Client() {
    httplib::Client c("127.0.0.1", port_);
    c.set_read_timeout(30);
    return c;
  }
  int64_t SubmitJob(const json& job) {
    auto r = Client().Post("/v1/jobs", BearerOf(kSubmitToken), job.dump(), "application/json");
    EXPECT_TRUE(r && r->status == 201) << (r ? r->body : "no reply");
    return r && r->status == 201 ? json::parse(r->body)["id"].get<int64_t>() : 0;
  }
  json Lease() {
    auto r = Client().Post("/v1/tasks/lease", BearerOf(kWorkerToken), json({{"worker", "t"}, {"fetches_campaigns", true}}).dump(),
                           "application/json");
    EXPECT_TRUE(r && r->status == 200) << (r ? std::to_string(r->status) + r->body : "no reply");
    return r && r->status == 200 ? json::parse(r->body) : json();
  }
  static httplib::Headers LeaseHeaders(const json& lease, const char* token = kWorkerToken) {
    httplib::Headers h = BearerOf(token);
    h.emplace("X-Strokelab-Task", std::to_string(lease["task_id"].get<int64_t>()));
    h.emplace("X-Strokelab-Job", std::to_string(lease["job_id"].get<int64_t>()));
    h.emplace("X-Strokelab-Lease", lease["lease_token"].get<std::string>());
    return h;
  }
  // The error code of a refused request (checking its status).
  static std::string Refusal(const httplib::Result& r, int status) {
    EXPECT_TRUE(r);
    if (!r) return "";
    EXPECT_EQ(r->status, status) << r->body;
    return json::parse(r->body, nullptr, false).value("error", json::object()).value("code", "");
  }
  httplib::Result Complete(const json& lease, const json& rows) {
    return Client().Post("/v1/tasks/" + std::to_string(lease["task_id"].get<int64_t>()) + "/complete",
                         BearerOf(kWorkerToken),
                         json({{"job_id", lease["job_id"]}, {"lease_token", lease["lease_token"]}, {"rows", rows}}).dump(),
                         "application/json");
  }

  static fs::path root_;
  fs::path dir_;
  std::unique_ptr<Service> service_;
  int port_ = 0;
};

fs::path RemoteCampaignTest::root_;

TEST_F(RemoteCampaignTest, TheCampaignIsSentOnlyToTheWorkerLeasingATaskOnIt) {
  const int64_t job = SubmitJob({{"kind", "diagnose"}, {"campaign", {{"path", "c"}}}});
  SubmitJob({{"kind", "simulate"}, {"model", "paper"}, {"frequency_hz", 8}, {"amplitude_v", 0.2}, {"duration_s", 0.2}});
  const json diagnose = Lease(), simulate = Lease();
  ASSERT_EQ(diagnose["job_id"], job);
  ASSERT_EQ(diagnose["kind"], "diagnose");
  ASSERT_EQ(simulate["kind"], "simulate");
  EXPECT_FALSE(diagnose["spec"].contains("campaign_dir"));  // the server's own path stays there
  const std::string sha = diagnose["spec"].value("campaign_sha256", "");
  const std::string path = "/v1/campaigns/" + sha;

  auto served = Client().Get(path, LeaseHeaders(diagnose));
  ASSERT_TRUE(served && served->status == 200) << (served ? served->body : "no reply");
  EXPECT_EQ(jobs::Sha256Hex(served->body), sha);
  EXPECT_EQ(served->body, jobs::CampaignBundle(root_ / "data" / "c"));

  // A hash the leased task does not work on; a lease on another task; no lease; a forged lease token.
  EXPECT_EQ(Refusal(Client().Get("/v1/campaigns/" + jobs::Sha256Hex("another campaign"), LeaseHeaders(diagnose)), 403),
            "no_task_for_campaign");
  EXPECT_EQ(Refusal(Client().Get(path, LeaseHeaders(simulate)), 403), "no_task_for_campaign");
  EXPECT_EQ(Refusal(Client().Get(path, BearerOf(kWorkerToken)), 403), "no_lease");
  json forged = diagnose;
  forged["lease_token"] = std::string(32, '0');
  EXPECT_EQ(Refusal(Client().Get(path, LeaseHeaders(forged)), 403), "no_lease");
  // Tokens of other roles and none at all, even with the lease's headers.
  EXPECT_EQ(Refusal(Client().Get(path, LeaseHeaders(diagnose, kSubmitToken)), 403), "forbidden");
  EXPECT_EQ(Refusal(Client().Get(path, LeaseHeaders(diagnose, kReadToken)), 403), "forbidden");
  httplib::Headers anonymous = LeaseHeaders(diagnose);
  anonymous.erase("Authorization");
  EXPECT_EQ(Refusal(Client().Get(path, anonymous), 401), "unauthorized");
  // Once the task is given up, its lease no longer opens the campaign.
  auto failed = Client().Post("/v1/tasks/" + std::to_string(diagnose["task_id"].get<int64_t>()) + "/fail",
                              BearerOf(kWorkerToken),
                              json({{"job_id", diagnose["job_id"]}, {"lease_token", diagnose["lease_token"]}}).dump(),
                              "application/json");
  ASSERT_TRUE(failed && failed->status == 200);
  EXPECT_EQ(Refusal(Client().Get(path, LeaseHeaders(diagnose)), 403), "no_lease");
}

TEST_F(RemoteCampaignTest, AWorkersMarkupNeverReachesTheServedReport) {
  const int64_t job = SubmitJob({{"kind", "diagnose"}, {"campaign", {{"path", "c"}}}});
  const json lease = Lease();
  const std::string script = "<script>alert(1)</script>";
  // A rendered page, the result row alone, or two rows: refused, nothing stored.
  EXPECT_EQ(Refusal(Complete(lease, {{{"table", "report_files"},
                                      {"values", {{"name", "index.html"}, {"content_type", "text/html"}, {"text", script}}}}}),
                    400),
            "invalid_rows");
  EXPECT_EQ(Refusal(Complete(lease, {{{"table", "diagnosis"}, {"values", {{"conclusion", script}}}}}), 400),
            "invalid_rows");
  // The data of a diagnosis whose texts carry markup: stored, and rendered by the server as text.
  Diagnosis d;
  d.base.model = d.model = PaperModel();
  d.conclusion = script + " Nothing missing.";
  d.model_note = "<img src=x onerror=alert(2)>";
  RecordMatch record;
  record.name = "<b onmouseover=alert(3)>rec</b>";
  record.frequency_hz = 8;
  record.amplitude_v = 0.3;
  record.measured = record.model = {{0.1, 0.2}, {0.01, 0.0}};
  d.before = d.after = {record};
  report::DiagnosisMaps maps;
  maps.note = script;
  // Broadband data (a campaign of broadband records only) whose base fit is markup, not its document.
  BroadbandDiagnosis broadband;
  broadband.model = PaperModel();
  json bad = report::BroadbandDiagnosisDataToJson(broadband, maps);
  bad["diagnosis"]["base"]["fit"] = script;
  EXPECT_EQ(Refusal(Complete(lease, {{{"table", "broadband_diagnosis_data"}, {"values", bad}}}), 400), "invalid_rows");
  const json data = report::DiagnosisDataToJson(d, maps);
  auto done = Complete(lease, {{{"table", "diagnosis_data"}, {"values", data}}});
  ASSERT_TRUE(done && done->status == 200) << (done ? done->body : "no reply");

  const std::string base = "/v1/jobs/" + std::to_string(job);
  auto status = Client().Get(base, BearerOf(kReadToken));
  ASSERT_TRUE(status && json::parse(status->body)["status"] == "succeeded") << (status ? status->body : "");
  auto page = Client().Get(base + "/report", BearerOf(kReadToken));
  ASSERT_TRUE(page && page->status == 200) << (page ? page->body.substr(0, 300) : "no reply");
  EXPECT_THAT(page->body, Not(HasSubstr("<script")));
  EXPECT_THAT(page->body, Not(HasSubstr("<img")));
  EXPECT_THAT(page->body, Not(HasSubstr("<b ")));
  EXPECT_THAT(page->body, HasSubstr("&lt;script&gt;alert(1)&lt;/script&gt;"));
  // The result document is the diagnosis as DiagnosisToJson writes it (served as JSON only).
  auto result = Client().Get(base + "/result", BearerOf(kReadToken));
  ASSERT_TRUE(result && result->status == 200);
  EXPECT_EQ(json::parse(result->body)["conclusion"], d.conclusion);
}

// ---- The worker against a server whose download is changed on the way ---------------------------

TEST(RemoteCampaignWorker, ATamperedDownloadFailsTheHashCheck) {
  const fs::path root = fs::path(::testing::TempDir()) / ("remote_campaign_tamper_" + std::to_string(::getpid()));
  fs::remove_all(root);
  WriteRemoteCampaign(root / "data" / "c");
  const std::string bundle = jobs::CampaignBundle(root / "data" / "c");
  const std::string sha = jobs::Sha256Hex(bundle);
  std::string tampered = bundle;
  tampered[tampered.size() / 2] ^= 1;  // one bit of one sample

  httplib::Server fake;
  std::mutex mutex;
  int leases = 0, downloads = 0;
  std::string failure;
  fake.Post("/v1/tasks/lease", [&](const httplib::Request&, httplib::Response& res) {
    std::lock_guard<std::mutex> lock(mutex);
    if (leases++ > 0) {
      res.status = 204;
      return;
    }
    const json spec = {{"type", "fit"}, {"job", {{"kind", "fit"}}}, {"campaign_digest", "0"}, {"campaign_sha256", sha}};
    res.set_content(json({{"task_id", 1}, {"job_id", 1}, {"index", 0}, {"kind", "fit"}, {"spec", spec},
                          {"lease_token", "t"}, {"expires_ms", 0}, {"lease_ms", 60000}})
                        .dump(),
                    "application/json");
  });
  fake.Get("/v1/campaigns/" + sha, [&](const httplib::Request& req, httplib::Response& res) {
    std::lock_guard<std::mutex> lock(mutex);
    ++downloads;
    EXPECT_EQ(req.get_header_value("X-Strokelab-Lease"), "t");
    res.set_content(tampered, "application/octet-stream");
  });
  fake.Post("/v1/tasks/1/fail", [&](const httplib::Request& req, httplib::Response& res) {
    std::lock_guard<std::mutex> lock(mutex);
    failure = json::parse(req.body).value("error", "");
    res.set_content("{\"accepted\": true}", "application/json");
  });
  fake.Post("/v1/tasks/1/complete", [&](const httplib::Request&, httplib::Response& res) {
    ADD_FAILURE() << "a tampered campaign was completed";
    res.set_content("{}", "application/json");
  });
  const int port = fake.bind_to_any_port("127.0.0.1");
  std::thread serving([&] { fake.listen_after_bind(); });

  worker::RemoteWorkerOptions options;
  options.server_url = "http://127.0.0.1:" + std::to_string(port);
  options.campaign_cache_dir = (root / "cache").string();
  options.idle_poll_ms = 20;
  options.exit_when_idle_ms = 300;
  std::atomic<bool> stop{false};
  EXPECT_EQ(worker::RunRemoteWorker(options, stop), 0);
  fake.stop();
  serving.join();

  EXPECT_EQ(downloads, 3);  // fetched again twice, then given up
  EXPECT_THAT(failure, HasSubstr("failed its hash check"));
  EXPECT_THAT(failure, HasSubstr(sha));
  EXPECT_FALSE(fs::exists(root / "cache" / sha));  // nothing cached
  fs::remove_all(root);
}

// ---- SHA-256 and the bundle ---------------------------------------------------------------------

TEST(CampaignHash, Sha256OfFips180Examples) {
  EXPECT_EQ(jobs::Sha256Hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(jobs::Sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(jobs::Sha256Hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  EXPECT_EQ(jobs::Sha256Hex(std::string(1'000'000, 'a')),
            "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
  // Lengths around the padding's block boundary (55, 56 and 64 bytes), against the system's sha256sum.
  EXPECT_EQ(jobs::Sha256Hex(std::string(55, 'x')), "d5e285683cd4efc02d021a5c62014694958901005d6f71e89e0989fac77e4072");
  EXPECT_EQ(jobs::Sha256Hex(std::string(56, 'x')), "04c26261370ee7541549d16dee320c723e3fd14671e66a099afe0a377c16888e");
  EXPECT_EQ(jobs::Sha256Hex(std::string(64, 'x')), "7ce100971f64e7001e8fe5a51973ecdfe1ced42befe7ee8d5fd6219506b5393c");
  EXPECT_TRUE(jobs::IsSha256Hex(jobs::Sha256Hex("x")));
  EXPECT_FALSE(jobs::IsSha256Hex(std::string(64, 'A')));
}

TEST(CampaignHash, BundleUnpacksToTheSameFilesAndRefusesBadNames) {
  const fs::path root = fs::path(::testing::TempDir()) / ("campaign_bundle_test_" + std::to_string(::getpid()));
  fs::remove_all(root);
  fs::create_directories(root / "in" / "sub");
  std::ofstream(root / "in" / "manifest.json")
      << R"({"format": "strokelab-recordings/1", "sample_rate_hz": 1000,
             "records": [{"file": "sub/rec.csv", "drive_frequency_hz": 6, "drive_amplitude_v": 0.1}]})";
  std::ofstream(root / "in" / "sub" / "rec.csv", std::ios::binary) << std::string("t,v\n0,1\n\0\n", 11);
  std::ofstream(root / "in" / "unlisted.bin") << "private";  // beside the campaign, not in its manifest
  const std::string bundle = jobs::CampaignBundle(root / "in");
  EXPECT_EQ(bundle.find("unlisted.bin"), std::string::npos) << "a file the manifest does not list was bundled";
  EXPECT_NE(bundle.find("sub/rec.csv"), std::string::npos);
  jobs::UnpackCampaignBundle(bundle, root / "out");
  EXPECT_EQ(jobs::CampaignSha256(root / "out"), jobs::Sha256Hex(bundle));
  EXPECT_EQ(jobs::CampaignBundle(root / "out"), bundle);

  const auto refusal = [&](const std::string& bad) {
    try {
      jobs::UnpackCampaignBundle(bad, root / "bad");
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("(accepted)");
  };
  const std::string header = "strokelab-campaign 1\n";
  const auto file = [](const std::string& name, const std::string& bytes) {
    return name + std::string(1, '\0') + std::to_string(bytes.size()) + "\n" + bytes;
  };
  EXPECT_THAT(refusal(header + file("../escape.csv", "x")), HasSubstr("'..' component"));
  EXPECT_THAT(refusal(header + file("/etc/x", "x")), HasSubstr("absolute"));
  EXPECT_THAT(refusal(header + file("a//b", "x")), HasSubstr("empty"));
  EXPECT_THAT(refusal(header + file("a\\b", "x")), HasSubstr("backslash"));
  EXPECT_THAT(refusal(header + file("a.csv", "x") + file("a.csv", "y")), HasSubstr("given twice"));
  EXPECT_THAT(refusal((header + file("a.csv", "xyz")).substr(0, header.size() + 8)), HasSubstr("truncated"));
  EXPECT_THAT(refusal("tar\n" + file("a.csv", "x")), HasSubstr("header"));
  EXPECT_FALSE(fs::exists(root / "escape.csv"));
  fs::remove_all(root);
}

}  // namespace
}  // namespace strokelab::server
