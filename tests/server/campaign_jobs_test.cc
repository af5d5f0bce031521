// Fit and diagnose jobs over REST: a synthetic campaign (synth.h) is uploaded as a tar or a zip
// built here, or named under the data root; the service's fit must be the direct FitCampaign on the
// same files, and a zip upload's fit the tar upload's;
// every way out of the upload area or the data root, and every malformed archive, is refused with a
// 400 naming the field or the archive member; a bad CSV is refused naming its file and line; a fit
// survives a restart of the service (its task is leased again) and can be cancelled.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <sys/inotify.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>
#include <vector>

#include "strokelab/diagnose/diagnose.h"
#include "strokelab/identify/fit.h"
#include "strokelab/data/mapping.h"
#include "strokelab/data/recordings.h"
#include "strokelab/server/service.h"
#include "strokelab/worker/remote_worker.h"
#include "strokelab/data/synth.h"
#include "campaign_upload.h"
#include "ustar.h"
#include "zip_writer.h"
#include "quiet_multisines.h"
#include "small_campaign.h"
#include "test_tokens.h"

namespace strokelab::server {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using nlohmann::json;

using ::strokelab::testing::kReadToken;
using ::strokelab::testing::kSubmitToken;
using ::strokelab::testing::kWorkerToken;
using ::strokelab::testing::QuietMultisines;

// Parameters of the service's fit and of the direct fit agree to this relative difference: the same
// files, options and code (dimensionless; the fit runs Ceres on one thread per record set).
constexpr double kSameFitTolerance = 1e-9;

// ---- A ustar writer for the tests (independent of the reader under test) ------------------------

struct TarEntry {
  std::string name;
  std::string data;
  char type = '0';
};

void PutOctal(std::string& block, size_t offset, size_t width, uint64_t value) {
  char text[32];
  std::snprintf(text, sizeof text, "%0*llo", static_cast<int>(width - 1), static_cast<unsigned long long>(value));
  block.replace(offset, width - 1, text, width - 1);  // the last byte stays NUL
}

std::string Header(const TarEntry& e) {
  std::string block(512, '\0');
  block.replace(0, std::min<size_t>(100, e.name.size()), e.name.substr(0, 100));
  PutOctal(block, 100, 8, 0644);
  PutOctal(block, 108, 8, 0);
  PutOctal(block, 116, 8, 0);
  PutOctal(block, 124, 12, e.data.size());
  PutOctal(block, 136, 12, 0);
  block[156] = e.type;
  block.replace(257, 6, std::string("ustar\0", 6));
  block.replace(263, 2, "00");
  block.replace(148, 8, "        ");
  unsigned sum = 0;
  for (unsigned char c : block) sum += c;
  char checksum[8];
  std::snprintf(checksum, sizeof checksum, "%06o", sum);
  block.replace(148, 7, checksum, 7);  // six digits, NUL, and the space left from above
  return block;
}

std::string Tar(const std::vector<TarEntry>& entries) {
  std::string out;
  for (const TarEntry& e : entries) {
    out += Header(e);
    out += e.data;
    out.append((512 - e.data.size() % 512) % 512, '\0');
  }
  out.append(1024, '\0');
  return out;
}

// The same entries as a zip (zip_writer.h): files deflated, directories as "NAME/" entries.
std::string ZipOf(const std::vector<TarEntry>& entries) {
  std::vector<zip_writer::ZipEntry> zip;
  for (const TarEntry& e : entries) {
    zip.emplace_back(e.name, e.data);
    if (e.type == '5') zip.back().mode = 040755;
  }
  return zip_writer::Zip(zip);
}

std::string ReadBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream out;
  out << in.rdbuf();
  return out.str();
}

// The files of a campaign directory as tar entries under `prefix` ("" or "campaign-a/").
std::vector<TarEntry> EntriesOf(const fs::path& dir, const std::string& prefix) {
  std::vector<TarEntry> entries;
  if (!prefix.empty()) entries.push_back({prefix, "", '5'});
  std::vector<fs::path> files;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  for (const fs::path& f : files) entries.push_back({prefix + f.filename().string(), ReadBytes(f)});
  return entries;
}

// ---- The fixture: one campaign for all tests, a service per test -------------------------------

class CampaignJobsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = fs::path(::testing::TempDir()) / ("campaign_jobs_test_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    fs::create_directories(root_ / "data");
    ::strokelab::testing::WriteSmallCampaign(campaign_dir(), root_ / "truth.json", /*seed=*/7);  // a fit of ~1 s
  }
  static void TearDownTestSuite() {
    delete direct_fit_;
    fs::remove_all(root_);
  }
  static fs::path campaign_dir() { return root_ / "data" / "campaign-a"; }
  // The campaign fitted in process, made when a test first asks: each test runs in a process of its
  // own, and most never compare fits (under ASan BadOptionsNameTheirField took 15 s with it, 3 s without).
  static const json& DirectFit() {
    if (!direct_fit_) direct_fit_ = new json(FitResultToJson(FitCampaign(ReadCampaign(campaign_dir()))));
    return *direct_fit_;
  }

  void SetUp() override {
    dir_ = root_ / ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    std::ofstream(dir_ / "tokens") << "submit " << kSubmitToken << "\nread " << kReadToken << "\nworker " << kWorkerToken
                                   << "\n";
    options_.port = 0;
    options_.db_path = (dir_ / "jobs.db").string();
    options_.workers = 1;
    options_.token_file = (dir_ / "tokens").string();
    options_.max_body_bytes = 64 * 1024;
    options_.max_campaign_bytes = 64 << 20;
    options_.data_root = (root_ / "data").string();
    options_.lease_ms = 1500;  // fits outlast it: the worker must renew
    options_.quiet = true;
    Restart();
  }
  void TearDown() override {
    service_.reset();
    fs::remove_all(dir_);
  }
  void Restart() {
    service_.reset();
    service_ = std::make_unique<Service>(options_);
    port_ = service_->Start();
  }

  httplib::Client Client() {
    httplib::Client c("127.0.0.1", port_);
    c.set_read_timeout(120);
    return c;
  }
  static httplib::Headers Auth(const char* token) { return {{"Authorization", std::string("Bearer ") + token}}; }

  httplib::Result Upload(const std::string& tar, const char* type = "application/x-tar") {
    return Client().Post("/v1/campaigns", Auth(kSubmitToken), tar, type);
  }
  std::string UploadOk(const std::string& archive, const char* type = "application/x-tar") {
    auto r = Upload(archive, type);
    EXPECT_TRUE(r && r->status == 201) << (r ? r->body : "no reply");
    return r ? json::parse(r->body).value("campaign_id", "") : "";
  }
  httplib::Result Post(const json& job) {
    return Client().Post("/v1/jobs", Auth(kSubmitToken), job.dump(), "application/json");
  }
  int64_t Submit(const json& job) {
    auto r = Post(job);
    EXPECT_TRUE(r && r->status == 201) << (r ? r->body : "no reply");
    return r && r->status == 201 ? json::parse(r->body)["id"].get<int64_t>() : 0;
  }
  json Get(const std::string& path, int status = 200) {
    auto r = Client().Get(path, Auth(kReadToken));
    EXPECT_TRUE(r && r->status == status) << path << ": " << (r ? r->body : "no reply");
    return r ? json::parse(r->body, nullptr, false) : json();
  }
  json WaitFor(int64_t id, const std::function<bool(const json&)>& done, double seconds = 120) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    json job;
    while (std::chrono::steady_clock::now() < end) {
      job = Get("/v1/jobs/" + std::to_string(id));
      if (done(job)) return job;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    ADD_FAILURE() << "job " << id << " did not get there: " << job.dump();
    return job;
  }
  json WaitFinished(int64_t id) {
    return WaitFor(id, [](const json& j) { return j["status"] != "queued" && j["status"] != "running"; });
  }
  // Waits as WaitFinished, polling every 10 ms, and keeps the progress of each poll that saw the job
  // running in a stage.
  // Once a running job has shown a stage, every later running status shows one (between the
  // computation's end and its stored result the status once fell back to {done: 0, total: 1}).
  json WaitFinishedWatchingStages(int64_t id, std::vector<json>* stages) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(120);
    json job;
    while (std::chrono::steady_clock::now() < end) {
      job = Get("/v1/jobs/" + std::to_string(id));
      if (job["status"] != "queued" && job["status"] != "running") return job;
      if (job["progress"].contains("stage")) stages->push_back(job["progress"]);
      else if (!stages->empty()) ADD_FAILURE() << "a running job's status lost its stage: " << job.dump();
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    ADD_FAILURE() << "job " << id << " did not finish: " << job.dump();
    return job;
  }
  // The error object of a reply, checking its status.
  static json Error(const httplib::Result& r, int status) {
    EXPECT_TRUE(r) << httplib::to_string(r.error());
    if (!r) return {};
    EXPECT_EQ(r->status, status) << r->body;
    return json::parse(r->body, nullptr, false).value("error", json::object());
  }
  // A copy of the campaign under the data root, to be spoilt.
  static fs::path CopyCampaign(const std::string& name) {
    const fs::path copy = root_ / "data" / name;
    fs::remove_all(copy);
    fs::copy(campaign_dir(), copy);
    return copy;
  }
  static void ExpectSameFit(const json& served, const json& direct) {
    ASSERT_TRUE(served.contains("parameters")) << served.dump().substr(0, 500);
    ASSERT_EQ(served["parameters"].size(), direct["parameters"].size());
    for (const auto& [name, p] : direct["parameters"].items()) {
      ASSERT_TRUE(served["parameters"].contains(name)) << name;
      const double a = served["parameters"][name]["value"], b = p["value"];
      EXPECT_NEAR(a, b, kSameFitTolerance * std::abs(b)) << name;
    }
    EXPECT_EQ(served["model"], direct["model"]);
  }

  static fs::path root_;
  static json* direct_fit_;
  fs::path dir_;
  ServiceOptions options_;
  std::unique_ptr<Service> service_;
  int port_ = 0;
};

fs::path CampaignJobsTest::root_;
json* CampaignJobsTest::direct_fit_ = nullptr;

TEST_F(CampaignJobsTest, UploadedCampaignFitsAsTheDirectFit) {
  const std::string id = UploadOk(Tar(EntriesOf(campaign_dir(), "campaign-a/")));
  ASSERT_EQ(id.size(), 16u);
  EXPECT_TRUE(fs::is_regular_file(dir_ / "jobs.db.campaigns" / id / "manifest.json"));
  const int64_t job = Submit({{"kind", "fit"}, {"name", "upload"}, {"campaign", {{"id", id}}}});
  const json status = WaitFinished(job);
  ASSERT_EQ(status["status"], "succeeded") << status.dump();
  EXPECT_EQ(status["progress"]["total"], 1);
  ExpectSameFit(Get("/v1/jobs/" + std::to_string(job) + "/result"), DirectFit());
  // A fit has no HTML report; a sweep has no result document.
  EXPECT_EQ(Error(Client().Get("/v1/jobs/" + std::to_string(job) + "/report", Auth(kReadToken)), 400)["code"],
            "no_report");
}

// Issue 16 point 9: the model file of a fit (its fitted model) as a download of its own, for the web
// page; a sweep has none, and an unfinished job none yet.
TEST_F(CampaignJobsTest, AFitsModelFileIsADownload) {
  const int64_t job = Submit({{"kind", "fit"}, {"campaign", {{"path", "campaign-a"}}}});
  ASSERT_EQ(WaitFinished(job)["status"], "succeeded");
  const std::string base = "/v1/jobs/" + std::to_string(job);
  auto model = Client().Get(base + "/model", Auth(kReadToken));
  ASSERT_TRUE(model && model->status == 200) << (model ? model->body.substr(0, 300) : "");
  EXPECT_THAT(model->get_header_value("Content-Type"), HasSubstr("application/json"));
  EXPECT_EQ(model->get_header_value("Content-Disposition"),
            "attachment; filename=\"job-" + std::to_string(job) + "-model.json\"");
  EXPECT_EQ(json::parse(model->body), Get(base + "/result")["fitted_model"]);
  EXPECT_EQ(json::parse(model->body)["contact_law"], "linear") << "a model file, as ModelToJson writes it";
  const int64_t sweep = Submit({{"kind", "sweep"}, {"model", "paper"},
                                {"grid", {{"frequency_hz", {{"from", 5}, {"to", 6}, {"points", 2}}},
                                          {"amplitude_v", {{"from", 0.2}, {"to", 0.5}, {"points", 2}}}}}});
  EXPECT_EQ(Error(Client().Get("/v1/jobs/" + std::to_string(sweep) + "/model", Auth(kReadToken)), 400)["code"],
            "no_model_file");
  EXPECT_EQ(Error(Client().Get("/v1/jobs/999999/model", Auth(kReadToken)), 404)["code"], "unknown_job");
}

TEST_F(CampaignJobsTest, ZipUploadFitsAsTheTarUpload) {
  const std::vector<TarEntry> entries = EntriesOf(campaign_dir(), "campaign-a/");
  const std::string tar_id = UploadOk(Tar(entries));
  const std::string zip_id = UploadOk(ZipOf(entries), "application/zip");
  ASSERT_EQ(zip_id.size(), 16u);
  const fs::path uploads = dir_ / "jobs.db.campaigns";
  EXPECT_EQ(jobs::CampaignDigest(uploads / zip_id), jobs::CampaignDigest(uploads / tar_id));  // the same bytes
  // Each upload is its own task (the campaign directory is part of its key): both fits run.
  const int64_t tar_job = Submit({{"kind", "fit"}, {"campaign", {{"id", tar_id}}}});
  const int64_t zip_job = Submit({{"kind", "fit"}, {"campaign", {{"id", zip_id}}}});
  ASSERT_EQ(WaitFinished(tar_job)["status"], "succeeded");
  ASSERT_EQ(WaitFinished(zip_job)["status"], "succeeded");
  const json zip_fit = Get("/v1/jobs/" + std::to_string(zip_job) + "/result");
  ExpectSameFit(zip_fit, Get("/v1/jobs/" + std::to_string(tar_job) + "/result"));
  ExpectSameFit(zip_fit, DirectFit());
  // Windows' type name is accepted too; a bad zip is refused naming its member, and nothing is kept.
  UploadOk(ZipOf(EntriesOf(campaign_dir(), "")), "application/x-zip-compressed");
  std::vector<zip_writer::ZipEntry> with_link = {{"campaign-a/manifest.json", "{}"}, {"campaign-a/evil", "/etc"}};
  with_link.back().mode = 0120777;
  const json error = Error(Upload(zip_writer::Zip(with_link), "application/zip"), 400);
  EXPECT_EQ(error["code"], "bad_archive");
  EXPECT_EQ(error["field"], "archive");
  EXPECT_THAT(error.value("message", ""), HasSubstr("member 2 'campaign-a/evil': is a symbolic link"));
  size_t kept = 0;
  for (const fs::directory_entry& e : fs::directory_iterator(uploads)) kept += e.path().filename().string()[0] != '.';
  EXPECT_EQ(kept, 3u);  // the three good uploads, no scratch directory either
}

// Issue 14 point 4: a campaign of UFF 58b files with mapping.json (its records the CSV campaign's
// very doubles, so that it fits as the CSV: ForeignFormats.SteppedSineCampaignInUff58FitsAsItsCsvTwin)
// is taken by the upload, read, and hashed by the files its mapping names. No fit here: through the
// service it would take 30-100 s under ASan.
TEST_F(CampaignJobsTest, AnUffCampaignUploadIsTakenAndHashedByItsMapping) {
  const Campaign csv = ReadCampaign(campaign_dir());
  const fs::path uff = root_ / "uff58b";
  MappedWriteOptions write;
  write.format = CampaignFormat::kUff58Binary;
  WriteMappedCampaign(csv, uff, write);
  std::ofstream(uff / "notes.txt") << "not part of the campaign";
  auto r = Upload(Tar(EntriesOf(uff, "run/")), "application/x-tar");
  ASSERT_TRUE(r && r->status == 201) << (r ? r->body : "no reply");
  const json reply = json::parse(r->body);
  const std::string id = reply.value("campaign_id", "");
  EXPECT_EQ(reply["campaign"]["records"], csv.records.size());
  EXPECT_EQ(reply["campaign"]["response"], ToString(csv.response));
  const fs::path stored = dir_ / "jobs.db.campaigns" / id;
  EXPECT_TRUE(fs::is_regular_file(stored / "mapping.json"));
  const std::string digest = jobs::CampaignDigest(stored);
  std::ofstream(stored / "notes.txt") << "changed, and still not part of the campaign";
  EXPECT_EQ(jobs::CampaignDigest(stored), digest);
  std::ofstream(stored / "rec_002.uff", std::ios::app) << "\n";
  EXPECT_NE(jobs::CampaignDigest(stored), digest);
}

TEST_F(CampaignJobsTest, CampaignAtTheArchiveTopAndUnderTheDataRoot) {
  const std::string id = UploadOk(Tar(EntriesOf(campaign_dir(), "")));
  EXPECT_TRUE(fs::is_regular_file(dir_ / "jobs.db.campaigns" / id / "manifest.json"));
  const int64_t job = Submit({{"kind", "fit"}, {"campaign", {{"path", "campaign-a"}}}});
  ASSERT_EQ(WaitFinished(job)["status"], "succeeded");
  ExpectSameFit(Get("/v1/jobs/" + std::to_string(job) + "/result"), DirectFit());
}

TEST_F(CampaignJobsTest, PathsOutOfTheDataRootAreRefused) {
  fs::create_directories(root_ / "outside");
  fs::copy(campaign_dir(), root_ / "outside" / "campaign-b");
  fs::create_directory_symlink(root_ / "outside" / "campaign-b", root_ / "data" / "link-out");
  // A file the manifest lists, leading out (an unlisted one is never opened: OnlyTheFilesTheManifestListsAreRead).
  const fs::path leaky = CopyCampaign("leaky");
  const std::string listed = ReadCampaign(leaky).records.front().name;
  fs::copy_file(leaky / listed, root_ / "outside-record.csv", fs::copy_options::overwrite_existing);
  fs::remove(leaky / listed);
  fs::create_symlink(root_ / "outside-record.csv", leaky / listed);
  struct Case {
    json campaign;
    std::string field, message;
  } cases[] = {
      {{{"path", (root_ / "data" / "campaign-a").string()}}, "/campaign/path", "not absolute"},
      {{{"path", "../outside/campaign-b"}}, "/campaign/path", "'..'"},
      {{{"path", "campaign-a/../../outside/campaign-b"}}, "/campaign/path", "'..'"},
      {{{"path", "link-out"}}, "/campaign/path", "outside the data root"},
      {{{"path", "leaky"}}, "/campaign/path", "is a symbolic link leading outside"},
      {{{"path", "no-such-campaign"}}, "/campaign/path", "no campaign directory"},
      {{{"id", "../../outside/campaign-b"}}, "/campaign/id", "is not a campaign id"},
      {{{"id", "0123456789abcdef"}}, "/campaign/id", "no uploaded campaign"},
      {{{"id", "0123456789abcdef"}, {"path", "campaign-a"}}, "/campaign", "exactly one of path"},
      {json::object(), "/campaign", "exactly one of path"},
  };
  for (const Case& c : cases) {
    const json error = Error(Post({{"kind", "fit"}, {"campaign", c.campaign}}), 400);
    EXPECT_EQ(error["code"], "invalid_job") << c.campaign.dump();
    EXPECT_EQ(error["field"], c.field) << c.campaign.dump();
    EXPECT_THAT(error.value("message", ""), HasSubstr(c.message)) << c.campaign.dump();
  }
  // Without a data root, paths are refused outright.
  options_.data_root.clear();
  Restart();
  const json error = Error(Post({{"kind", "fit"}, {"campaign", {{"path", "campaign-a"}}}}), 400);
  EXPECT_EQ(error["field"], "/campaign/path");
  EXPECT_THAT(error.value("message", ""), HasSubstr("no data root"));
  fs::remove_all(root_ / "outside");
  fs::remove(root_ / "data" / "link-out");
  fs::remove_all(leaky);
  fs::remove(root_ / "outside-record.csv");
}

TEST_F(CampaignJobsTest, BadOptionsNameTheirField) {
  const json cases[] = {
      {{"kind", "fit"}, {"campaign", {{"path", "campaign-a"}}}, {"model", "cubic"}},
      {{"kind", "fit"}, {"campaign", {{"path", "campaign-a"}}}, {"options", {{"harmonics", 0}}}},
      {{"kind", "fit"}, {"campaign", {{"path", "campaign-a"}}}, {"options", {{"heldout_every", 3}}}},
      {{"kind", "diagnose"}, {"campaign", {{"path", "campaign-a"}}}, {"options", {{"heldout_every", 1}}}},
      {{"kind", "fit"}, {"campaign", {{"path", 3}}}},
      {{"kind", "diagnose"}, {"campaign", {{"path", "campaign-a"}}}, {"options", {{"map_frequency_points", 1}}}},
  };
  const char* fields[] = {"/model", "/options/harmonics", "/options/heldout_every", "/options/heldout_every",
                          "/campaign/path", "/options/map_frequency_points"};
  for (size_t i = 0; i < std::size(cases); ++i)
    EXPECT_EQ(Error(Post(cases[i]), 400)["field"], fields[i]) << cases[i].dump();
}

TEST_F(CampaignJobsTest, BadArchivesAreRefusedNamingTheMember) {
  const std::vector<TarEntry> good = EntriesOf(campaign_dir(), "campaign-a/");
  const std::string tar = Tar(good);
  std::string bad_checksum = tar;
  bad_checksum[512 * 1 + 3] ^= 1;  // a byte of the second header's name
  std::vector<TarEntry> dotdot = good, absolute = good, link = good;
  dotdot.push_back({"campaign-a/../escape.csv", "x"});
  absolute.push_back({"/tmp/escape.csv", "x"});
  link.push_back({"campaign-a/evil", "", '2'});
  struct Case {
    std::string name, body, message;
  } cases[] = {
      {"truncated in a member's data", tar.substr(0, 512 * 3 + 100), "truncated"},
      {"truncated before the end block", tar.substr(0, tar.size() - 1024), "end-of-archive"},
      {"bad checksum", bad_checksum, "checksum mismatch"},
      {"'..' member", Tar(dotdot), "'..' in the name"},
      {"absolute member", Tar(absolute), "absolute name"},
      {"symbolic link", Tar(link), "symbolic link (only regular files"},
      {"twice the same name", Tar({{"a.csv", "1"}, {"a.csv", "2"}}), "appears twice"},
      {"not a tar", std::string(2048, 'x'), "no ustar magic"},
      {"no campaign", Tar({{"notes.txt", "hello"}}), "no manifest.json or mapping.json"},
  };
  for (const Case& c : cases) {
    const json error = Error(Upload(c.body), 400);
    EXPECT_EQ(error["code"], "bad_archive") << c.name;
    EXPECT_EQ(error["field"], "archive") << c.name;
    EXPECT_THAT(error.value("message", ""), HasSubstr(c.message)) << c.name;
  }
  const json wrong_type = Error(Upload(tar, "application/gzip"), 415);
  EXPECT_EQ(wrong_type["code"], "unsupported_media_type");
  EXPECT_THAT(wrong_type.value("message", ""), HasSubstr("'Content-Type: application/x-tar'"));
  EXPECT_THAT(wrong_type.value("message", ""), HasSubstr("'Content-Type: application/zip'"));
  // Nothing is left behind by the refused uploads.
  const fs::path uploads = dir_ / "jobs.db.campaigns";
  EXPECT_TRUE(!fs::exists(uploads) || fs::is_empty(uploads));
  // Over the upload limit: 413 before anything is read; the JSON limit does not apply to uploads.
  options_.max_campaign_bytes = tar.size() - 1;
  Restart();
  EXPECT_EQ(Error(Upload(tar), 413)["code"], "body_too_large");
  options_.max_campaign_bytes = tar.size();
  Restart();
  UploadOk(tar);
}

// `curl --data-binary @campaign.tar` without -H sends the tar as a form (and httplib refused form
// bodies over 8 KiB as 413 body_too_large): 415 naming the header to add, as with no type at all.
TEST_F(CampaignJobsTest, AnUploadWithoutItsTypeIsToldWhichHeaderToAdd) {
  const std::string tar = Tar(EntriesOf(campaign_dir(), "campaign-a/"));
  ASSERT_GT(tar.size(), 8192u);
  for (const char* type : {"application/x-www-form-urlencoded", ""}) {
    for (const std::string& body : {tar, tar.substr(0, 4096)}) {
      const json error = Error(Upload(body, type), 415);
      EXPECT_EQ(error["code"], "unsupported_media_type") << "'" << type << "', " << body.size() << " bytes";
      EXPECT_THAT(error.value("message", ""), HasSubstr("-H 'Content-Type: application/x-tar'")) << type;
    }
  }
  UploadOk(tar);
}

TEST_F(CampaignJobsTest, BadCsvIsRefusedNamingFileAndLine) {
  const fs::path spoilt = CopyCampaign("spoilt");
  const std::string csv = json::parse(ReadBytes(spoilt / "manifest.json"))["records"][1]["file"];
  std::string text = ReadBytes(spoilt / csv);
  size_t at = 0;
  for (int line = 1; line < 7; ++line) at = text.find('\n', at) + 1;  // the start of line 7
  text.replace(at, text.find(',', at) - at, "abc");
  std::ofstream(spoilt / csv, std::ios::binary) << text;
  for (const bool upload : {true, false}) {
    const json error = upload ? Error(Upload(Tar(EntriesOf(spoilt, ""))), 400)
                              : Error(Post({{"kind", "fit"}, {"campaign", {{"path", "spoilt"}}}}), 400);
    EXPECT_EQ(error["code"], "invalid_campaign") << upload;
    EXPECT_EQ(error["field"], csv + ":7") << upload << " " << error.dump();
  }
  fs::remove_all(spoilt);
}

TEST_F(CampaignJobsTest, AFitSurvivesARestartAndCanBeCancelled) {
  const int64_t job = Submit({{"kind", "fit"}, {"campaign", {{"path", "campaign-a"}}}});
  WaitFor(job, [](const json& j) { return j["status"] == "running"; });
  Restart();  // the in-process worker gives the task up; the new service leases it again at once
  ASSERT_EQ(WaitFinished(job)["status"], "succeeded");
  ExpectSameFit(Get("/v1/jobs/" + std::to_string(job) + "/result"), DirectFit());

  // Cancelled while it runs: the job stays cancelled and the worker is free at once.
  const int64_t cancelled = Submit({{"kind", "fit"}, {"campaign", {{"path", "campaign-a"}}}, {"options", {{"harmonics", 8}}}});
  WaitFor(cancelled, [](const json& j) { return j["status"] == "running"; });
  auto r = Client().Delete("/v1/jobs/" + std::to_string(cancelled), Auth(kSubmitToken));
  ASSERT_TRUE(r && r->status == 200) << (r ? r->body : "");
  const int64_t next = Submit({{"kind", "simulate"}, {"model", "paper"}, {"frequency_hz", 10}, {"amplitude_v", 0.2},
                               {"duration_s", 0.5}});
  WaitFor(next, [](const json& j) { return j["status"] == "succeeded"; }, 10);
  EXPECT_EQ(Get("/v1/jobs/" + std::to_string(cancelled))["status"], "cancelled");
  EXPECT_EQ(Error(Client().Get("/v1/jobs/" + std::to_string(cancelled) + "/result", Auth(kReadToken)), 409)["code"],
            "not_finished");
}

// Issue 15, item 6: cancelled diagnoses ran on to their end on threads of their own, so on
// --workers 1 six ran at once. Now each ends when its job is cancelled: after three cancelled
// diagnoses the process has the threads it had before them.
TEST_F(CampaignJobsTest, CancelledDiagnosesDoNotRunBeyondTheWorkerCount) {
  const auto threads = [] {
    std::ifstream status("/proc/self/status");
    for (std::string line; std::getline(status, line);)
      if (line.rfind("Threads:", 0) == 0) return std::stoi(line.substr(8));
    return -1;
  };
  Get("/v1/jobs");  // the HTTP threads start with the first request
  const int before = threads();
  for (int i = 0; i < 3; ++i) {
    const int64_t job = Submit({{"kind", "diagnose"},
                                {"campaign", {{"path", "campaign-a"}}},
                                {"options", {{"max_seconds", 60}, {"min_heldout_gain", 10 + i}}}});
    WaitFor(job, [](const json& j) { return j["status"] == "running"; }, 20);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    auto r = Client().Delete("/v1/jobs/" + std::to_string(job), Auth(kSubmitToken));
    ASSERT_TRUE(r && r->status == 200) << (r ? r->body : "");
  }
  const auto cancelled = std::chrono::steady_clock::now();
  int now = threads();
  while (now > before && std::chrono::steady_clock::now() - cancelled < std::chrono::seconds(3)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    now = threads();
  }
  EXPECT_LE(now, before) << "threads still running 3 s after the last cancel (before the diagnoses: " << before << ")";
}

// Issue 15, item 6: a job naming a directory under the data root read and hashed every file in it
// (1 GiB: 16 s, 2.1 GB RSS) before finding whether it was a campaign. Now the manifest is read
// first and only the files it lists are opened: inotify sees no open of a large file beside them.
TEST_F(CampaignJobsTest, OnlyTheFilesTheManifestListsAreRead) {
  const fs::path copy = CopyCampaign("bigdir");
  const fs::path junk = copy / "junk.bin";
  std::ofstream(junk).put('x');
  fs::resize_file(junk, 64u << 20);  // sparse: no disk used
  const int watch = inotify_init1(IN_NONBLOCK);
  ASSERT_GE(watch, 0);
  ASSERT_GE(inotify_add_watch(watch, junk.c_str(), IN_OPEN | IN_ACCESS), 0);
  const int64_t job = Submit({{"kind", "fit"}, {"campaign", {{"path", "bigdir"}}}});
  EXPECT_GT(job, 0);
  char events[4096];
  EXPECT_LT(::read(watch, events, sizeof events), 0) << "junk.bin, which the manifest does not list, was opened";
  ::close(watch);
  Client().Delete("/v1/jobs/" + std::to_string(job), Auth(kSubmitToken));
  // The listed files count against --max-campaign-bytes before any is read.
  options_.max_campaign_bytes = 100'000;
  Restart();
  const json error = Error(Post({{"kind", "fit"}, {"campaign", {{"path", "bigdir"}}}}), 400);
  EXPECT_EQ(error["field"], "/campaign");
  EXPECT_THAT(error["message"].get<std::string>(), HasSubstr("more than the server's limit of 100000 bytes"));
}

// Issue 15, item 6: uploads had no quota; 252 MB of one stayed on disk for good.
TEST_F(CampaignJobsTest, UploadsAreHeldToTheirQuotas) {
  const std::string tar = Tar(EntriesOf(campaign_dir(), "campaign-a/"));
  uint64_t campaign_bytes = 0;
  for (const fs::directory_entry& e : fs::directory_iterator(campaign_dir())) campaign_bytes += e.file_size();
  options_.upload_quota_bytes = campaign_bytes - 1;  // per upload: one byte short
  Restart();
  EXPECT_THAT(Error(Upload(tar), 400)["message"].get<std::string>(), HasSubstr("the members hold more than"));
  options_.upload_quota_bytes = campaign_bytes;
  options_.uploads_total_quota_bytes = campaign_bytes * 3 / 2;  // all uploads: room for one
  Restart();
  UploadOk(tar);
  const json error = Error(Upload(tar), 507);
  EXPECT_EQ(error["code"], "storage_quota");
  EXPECT_THAT(error["message"].get<std::string>(), HasSubstr("--uploads-total-quota-bytes"));
  size_t kept = 0;
  for (const fs::directory_entry& e : fs::directory_iterator(options_.db_path + ".campaigns")) kept += e.is_directory();
  EXPECT_EQ(kept, 1u) << "the refused upload left a directory";
}

// Issue 15, item 6: max_seconds up to 3600 per job was accepted; the server caps it.
TEST_F(CampaignJobsTest, AJobsSecondsAreHeldToTheServersCap) {
  options_.max_job_seconds = 30;
  Restart();
  const json error =
      Error(Post({{"kind", "diagnose"}, {"campaign", {{"path", "campaign-a"}}}, {"options", {{"max_seconds", 3600}}}}), 400);
  EXPECT_EQ(error["field"], "/options/max_seconds");
  EXPECT_THAT(error["message"].get<std::string>(), HasSubstr("at most 30"));
  EXPECT_EQ(Error(Post({{"kind", "fit"}, {"campaign", {{"path", "campaign-a"}}},
                        {"options", {{"max_refinement_seconds", 31}}}}), 400)["field"],
            "/options/max_refinement_seconds");
  const int64_t job = Submit({{"kind", "diagnose"}, {"campaign", {{"path", "campaign-a"}}}});
  Client().Delete("/v1/jobs/" + std::to_string(job), Auth(kSubmitToken));
  EXPECT_EQ(Get("/v1/jobs/" + std::to_string(job))["spec"]["options"]["max_seconds"], 30);
}

// Issue 16, point 5: a fit that did not converge showed as a plain "succeeded". The job succeeds as a
// computation, and its status warns (the web page shows the warnings in amber); while it runs, its
// progress names the stage (point 11).
TEST_F(CampaignJobsTest, AFitThatDidNotConvergeSucceedsWithAWarning) {
  const int64_t job = Submit({{"kind", "fit"}, {"campaign", {{"path", "campaign-a"}}}, {"options", {{"max_iterations", 1}}}});
  std::vector<json> stages;
  const json status = WaitFinishedWatchingStages(job, &stages);
  ASSERT_EQ(status["status"], "succeeded") << status.dump();
  EXPECT_THAT(status["warnings"].get<std::vector<std::string>>(), ::testing::Contains("fit did not converge"))
      << status.dump();
  json listed;
  const json list = Get("/v1/jobs");
  for (const json& j : list["jobs"])
    if (j["id"] == job) listed = j;
  EXPECT_EQ(listed["warnings"], status["warnings"]) << "the job list shows them too";
  const json result = Get("/v1/jobs/" + std::to_string(job) + "/result");
  EXPECT_FALSE(result["stages"]["refinement"]["converged"].get<bool>());
  EXPECT_TRUE(result["parameters"]["m_p"]["standard_error"].is_null()) << result["parameters"].dump();
  ASSERT_FALSE(stages.empty()) << "no poll saw the fit running in its stage";
  EXPECT_EQ(stages.front()["stage"], 1);
  EXPECT_EQ(stages.front()["stages"], 1);
  EXPECT_THAT(stages.front()["stage_name"].get<std::string>(), HasSubstr("fit on "));
  EXPECT_GE(stages.front()["elapsed_s"].get<double>(), 0.0);
  // A fit that converges has no warnings.
  const int64_t converged = Submit({{"kind", "fit"}, {"campaign", {{"path", "campaign-a"}}}});
  const json fine = WaitFinished(converged);
  ASSERT_EQ(fine["status"], "succeeded");
  ASSERT_TRUE(Get("/v1/jobs/" + std::to_string(converged) + "/result")["stages"]["refinement"]["converged"].get<bool>());
  EXPECT_EQ(fine["warnings"], json::array()) << fine.dump();
}

// Issue 14: a fit job on a broadband campaign, and on one of stepped sines and multisines, fits it as
// `strokelab fit` does (its records' time series; identify/mixed_campaign.h): the result's kind, the
// parameters, the fitted model as a download, and no warnings for fits the records accept.
// The multisines stay clear of the stop (two short quiet records: their fits take seconds under ASan,
// where records with impacts take minutes); campaign-a's stepped sines reach it.
TEST_F(CampaignJobsTest, BroadbandAndMixedCampaignsAreFitted) {
  Synthesis broadband = QuietMultisines(13);
  for (Recording& r : broadband.campaign.records) r.name = "bb_" + r.name;
  WriteSynthesis(broadband, root_ / "data" / "broadband", root_ / "broadband-truth.json");
  Campaign mixed = ReadCampaign(campaign_dir());
  mixed.records.insert(mixed.records.end(), broadband.campaign.records.begin(), broadband.campaign.records.end());
  WriteCampaign(mixed, root_ / "data" / "mixed", broadband.write);
  for (const std::string kind : {"broadband", "mixed"}) {
    const int64_t job = Submit({{"kind", "fit"}, {"campaign", {{"path", kind}}}});
    const json status = WaitFor(job, [](const json& j) { return j["status"] != "queued" && j["status"] != "running"; }, 600);
    ASSERT_EQ(status["status"], "succeeded") << status.dump();
    const std::string base = "/v1/jobs/" + std::to_string(job);
    const json result = Get(base + "/result");
    EXPECT_EQ(result["kind"], kind);
    EXPECT_TRUE(result["converged"].get<bool>()) << result["report"];
    EXPECT_FALSE(result["rejected"].get<bool>()) << result["report"];
    EXPECT_EQ(status["warnings"], json::array()) << status.dump();
    EXPECT_NEAR(result["parameters"]["k_p"]["value"].get<double>(), PaperModel().stiffness_n_per_m,
                4.0 * result["parameters"]["k_p"]["standard_error"].get<double>())
        << kind;
    EXPECT_EQ(result["records"].size(), 2u) << kind;
    if (kind == "mixed") {
      EXPECT_GE(result["stepped_records"].size(), 10u);  // of campaign-a's 12
    }
    auto model = Client().Get(base + "/model", Auth(kReadToken));
    ASSERT_TRUE(model && model->status == 200) << (model ? model->body.substr(0, 300) : "");
    EXPECT_EQ(json::parse(model->body), result["fitted_model"]);
  }
  // Without the refinement (staged estimates, which only the stepped fit has): the broadband campaign
  // is refused at submission, naming the option.
  const json refused =
      Error(Post({{"kind", "fit"}, {"campaign", {{"path", "broadband"}}}, {"options", {{"refine", false}}}}), 400);
  EXPECT_EQ(refused["field"], "/options/refine");
  EXPECT_THAT(refused["message"].get<std::string>(), HasSubstr("no staged estimates"));
}

// A diagnose job on broadband records only diagnoses them by their time series, as `strokelab diagnose`
// does: the result's kind, its conclusion, the report rendered by the server with both models' maps,
// and the diagnosed model as a download; run by the server's own workers, and by a remote worker,
// whose data the server renders (jobs/task_rows.h). Nothing is missing from the paper model's records.
TEST_F(CampaignJobsTest, BroadbandCampaignsAreDiagnosedByTheirTimeSeries) {
  WriteSynthesis(QuietMultisines(14), root_ / "data" / "broadband-quiet", root_ / "broadband-quiet-truth.json");
  const json job_spec = {{"kind", "diagnose"},
                         {"campaign", {{"path", "broadband-quiet"}}},
                         {"options", {{"map_frequency_points", 4}, {"map_amplitude_points", 3}}}};
  auto check = [&](int64_t job, const std::string& who) {
    const std::string base = "/v1/jobs/" + std::to_string(job);
    const json result = Get(base + "/result");
    EXPECT_EQ(result["kind"], "broadband") << who;
    EXPECT_EQ(result["missing_physics"], json::array()) << who << ": " << result["conclusion"];
    EXPECT_TRUE(result["unexplained"].is_null()) << who << ": " << result["conclusion"];
    EXPECT_EQ(result["records"].size(), 2u) << who;
    EXPECT_EQ(result["base"]["kind"], "broadband") << who;  // the base fit's whole document
    EXPECT_TRUE(result["base"]["parameters"].contains("k_p")) << who;
    auto page = Client().Get(base + "/report", Auth(kReadToken));
    ASSERT_TRUE(page && page->status == 200) << who;
    EXPECT_THAT(page->body, HasSubstr("<h1>strokelab diagnosis (broadband records)</h1>")) << who;
    EXPECT_THAT(page->body, HasSubstr("Base model = diagnosed model: stroke saturation")) << who;
    auto records = Client().Get(base + "/report/records.csv", Auth(kReadToken));
    ASSERT_TRUE(records && records->status == 200) << who;
    EXPECT_EQ(records->body.rfind("name,drive_rms_v,noise_rms,", 0), 0u) << who;
    auto model = Client().Get(base + "/model", Auth(kReadToken));
    ASSERT_TRUE(model && model->status == 200) << who;
    EXPECT_EQ(json::parse(model->body), result["model"]) << who;
  };
  const int64_t local = Submit(job_spec);
  const json status = WaitFor(local, [](const json& j) { return j["status"] != "queued" && j["status"] != "running"; }, 600);
  ASSERT_EQ(status["status"], "succeeded") << status.dump();
  EXPECT_EQ(status["warnings"], json::array()) << status.dump();
  check(local, "in-process worker");

  options_.workers = 0;
  Restart();
  json remote_spec = job_spec;  // another task (an identical one would be served from the cache)
  remote_spec["options"]["map_amplitude_points"] = 2;
  const int64_t remote_job = Submit(remote_spec);
  worker::RemoteWorkerOptions remote;
  remote.server_url = "http://127.0.0.1:" + std::to_string(port_);
  remote.token = kWorkerToken;
  remote.idle_poll_ms = 20;
  remote.exit_when_idle_ms = 300;
  remote.campaign_cache_dir = (dir_ / "cache").string();
  remote.max_tasks = 1;
  std::atomic<bool> stop{false};
  EXPECT_EQ(worker::RunRemoteWorker(remote, stop), 1);
  ASSERT_EQ(WaitFor(remote_job, [](const json& j) { return j["status"] != "queued" && j["status"] != "running"; }, 600)["status"],
            "succeeded");
  check(remote_job, "remote worker");
}

// A server without workers of its own takes fit jobs: a remote worker fetches the campaign and fits it
// as the direct fit; one that cannot fetch campaigns (no cache directory) leaves the task waiting for it.
TEST_F(CampaignJobsTest, WithoutInProcessWorkersARemoteWorkerRunsTheFit) {
  options_.workers = 0;
  Restart();
  const int64_t job = Submit({{"kind", "fit"}, {"campaign", {{"path", "campaign-a"}}}});
  worker::RemoteWorkerOptions remote;
  remote.server_url = "http://127.0.0.1:" + std::to_string(port_);
  remote.token = kWorkerToken;
  remote.idle_poll_ms = 20;
  remote.exit_when_idle_ms = 300;
  std::atomic<bool> stop{false};
  EXPECT_EQ(worker::RunRemoteWorker(remote, stop), 0);  // no cache directory: the fit is not its
  EXPECT_NE(Get("/v1/jobs/" + std::to_string(job))["status"], "failed");
  remote.campaign_cache_dir = (dir_ / "cache").string();
  remote.max_tasks = 1;
  EXPECT_EQ(worker::RunRemoteWorker(remote, stop), 1);
  ASSERT_EQ(WaitFinished(job)["status"], "succeeded");
  ExpectSameFit(Get("/v1/jobs/" + std::to_string(job) + "/result"), DirectFit());
}

TEST_F(CampaignJobsTest, DiagnoseJobHasAResultAndAnHtmlReport) {
  const std::string id = UploadOk(Tar(EntriesOf(campaign_dir(), "campaign-a/")));
  const int64_t job = Submit({{"kind", "diagnose"},
                              {"campaign", {{"id", id}}},
                              {"options", {{"heldout_every", 4}, {"pairs", false}, {"max_seconds", 15}}}});
  std::vector<json> stages;
  const json status = WaitFinishedWatchingStages(job, &stages);
  ASSERT_EQ(status["status"], "succeeded") << status.dump();
  EXPECT_TRUE(status["warnings"].is_array()) << status.dump();
  // While it ran: stage k of N (the analysis, the base fit, the signatures, the candidates, the two
  // maps), with the time and, once a stage has finished, an estimate of the time left.
  ASSERT_FALSE(stages.empty()) << "no poll saw the diagnosis running in a stage";
  bool candidate = false, estimate = false;
  for (const json& p : stages) {
    EXPECT_GE(p["stage"].get<int>(), 1) << p.dump();
    EXPECT_LE(p["stage"].get<int>(), p["stages"].get<int>()) << p.dump();
    EXPECT_GE(p["elapsed_s"].get<double>(), 0.0) << p.dump();
    candidate = candidate || p["stage_name"].get<std::string>().rfind("candidate ", 0) == 0;
    estimate = estimate || p["eta_s"].is_number();
  }
  const std::string base = "/v1/jobs/" + std::to_string(job);
  const json result = Get(base + "/result");
  // A candidate stage is seen only when the 15 s budget left time for one: under ASan on a loaded
  // machine the base fit took it all and every candidate was skipped (a clean-clone run).
  bool fitted = false;
  for (const json& c : result.value("candidates", json::array())) fitted = fitted || c.value("fitted", false);
  if (fitted) {
    EXPECT_TRUE(candidate) << stages.back().dump();
  }
  EXPECT_TRUE(estimate) << stages.back().dump();
  EXPECT_TRUE(result.contains("missing_physics")) << result.dump().substr(0, 300);
  EXPECT_TRUE(result.contains("conclusion"));
  auto page = Client().Get(base + "/report", Auth(kReadToken));
  ASSERT_TRUE(page && page->status == 200) << (page ? page->body.substr(0, 300) : "");
  EXPECT_THAT(page->get_header_value("Content-Type"), HasSubstr("text/html"));
  EXPECT_THAT(page->body, HasSubstr("<base href=\"" + base + "/report/\">"));  // its links reach the tables
  EXPECT_THAT(page->body, HasSubstr(result["conclusion"].get<std::string>().substr(0, 20)));
  auto table = Client().Get(base + "/report/records.csv", Auth(kReadToken));
  ASSERT_TRUE(table && table->status == 200);
  EXPECT_THAT(table->get_header_value("Content-Type"), HasSubstr("text/csv"));
  EXPECT_EQ(Error(Client().Get(base + "/report/nothing.csv", Auth(kReadToken)), 404)["code"], "no_report_file");
  // The diagnosed model: in the result and as the report's model file, the format of a job's "model".
  ASSERT_TRUE(result.contains("model"));
  auto model = Client().Get(base + "/report/model.json", Auth(kReadToken));
  ASSERT_TRUE(model && model->status == 200);
  EXPECT_THAT(model->get_header_value("Content-Type"), HasSubstr("application/json"));
  EXPECT_EQ(json::parse(model->body), result["model"]);
  auto download = Client().Get(base + "/model", Auth(kReadToken));  // the web page's download, the same file
  ASSERT_TRUE(download && download->status == 200);
  EXPECT_EQ(json::parse(download->body), result["model"]);
  EXPECT_THAT(page->body, HasSubstr("<h2 id=\"maps\">"));
  // The report is in the database: it is served after a restart.
  Restart();
  auto again = Client().Get(base + "/report", Auth(kReadToken));
  ASSERT_TRUE(again && again->status == 200);
  EXPECT_EQ(again->body, page->body);
}

// ---- The reader itself, on archives of the system's tar --------------------------------------

TEST(ReadUstar, ReadsPaxAndGnuArchivesOfTheSystemTar) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("ustar_test_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string long_name(120, 'n');
  fs::create_directories(dir / "c" / "sub");
  std::ofstream(dir / "c" / "manifest.json") << "{}";
  std::ofstream(dir / "c" / "sub" / long_name) << "long";
  for (const char* format : {"ustar", "pax", "gnu"}) {
    const fs::path tar = dir / (std::string(format) + ".tar");
    const std::string command = "tar --format=" + std::string(format) + " -C " + dir.string() + " -cf " + tar.string() +
                                (std::string(format) == "ustar" ? " c/manifest.json" : " c") + " 2>/dev/null";
    // tar is Essential in Debian (and listed in deploy/local.sh): a failure here is a real one.
    ASSERT_EQ(std::system(command.c_str()), 0) << command;
    const std::string bytes = ReadBytes(tar);
    const std::vector<TarMember> members = ReadUstar(bytes);
    std::vector<std::string> files;
    for (const TarMember& m : members)
      if (!m.directory) files.push_back(m.path + "=" + std::string(m.data));
    std::sort(files.begin(), files.end());
    if (std::string(format) == "ustar")
      EXPECT_THAT(files, ::testing::ElementsAre("c/manifest.json={}")) << format;
    else
      EXPECT_THAT(files, ::testing::ElementsAre("c/manifest.json={}", "c/sub/" + long_name + "=long")) << format;
  }
  fs::remove_all(dir);
}

TEST(ReadUstar, LimitsAreEnforced) {
  const std::string tar = Tar({{"a.csv", std::string(1000, 'x')}, {"b.csv", "y"}});
  ArchiveLimits limits;
  limits.max_file_bytes = 999;
  try {
    ReadUstar(tar, limits);
    ADD_FAILURE() << "no error";
  } catch (const ArchiveError& e) {
    EXPECT_THAT(e.bare_message(), HasSubstr("member 1 'a.csv': 1000 bytes, over the limit of 999"));
  }
  limits = {};
  limits.max_members = 1;
  EXPECT_THROW(ReadUstar(tar, limits), ArchiveError);
  limits = {};
  limits.max_total_bytes = 1000;
  EXPECT_THROW(ReadUstar(tar, limits), ArchiveError);
  EXPECT_EQ(ReadUstar(tar).size(), 2u);
}

}  // namespace
}  // namespace strokelab::server
