// A finished sweep's result routes as a client reads them: CSV pages that end, whole tables in one
// request (`?format=csv`), CSV of thresholds and jumps, the job's spec and grid, off-grid queries.
#include "strokelab/server/service.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

namespace strokelab::server {
namespace {

using ::testing::HasSubstr;
using nlohmann::json;

// 60 x 11 grid points with thresholds: over 1,000 point rows (up, down and unstable), so that the
// default page size of 1,000 would cut the table.
const json kResultRoutesSweep = {{"kind", "sweep"},
                                 {"model", "paper"},
                                 {"thresholds", true},
                                 {"grid",
                                  {{"frequency_hz", {{"from", 6}, {"to", 18}, {"points", 60}}},
                                   {"amplitude_v", {{"from", 0.1}, {"to", 0.6}, {"points", 11}}}}}};

// One service and one finished sweep for the whole suite (the routes only read).
class ResultRoutesTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::filesystem::path(std::filesystem::path(::testing::TempDir()) /
                                     ("result_routes_test_" + std::to_string(::getpid())));
    std::filesystem::remove_all(*dir_);
    std::filesystem::create_directories(*dir_);
    ServiceOptions options;
    options.port = 0;
    options.db_path = (*dir_ / "jobs.db").string();
    options.workers = 1;
    options.quiet = true;
    service_ = new Service(options);
    port_ = service_->Start();
    httplib::Client c("127.0.0.1", port_);
    auto r = c.Post("/v1/jobs", kResultRoutesSweep.dump(), "application/json");
    ASSERT_TRUE(r && r->status == 201) << (r ? r->body : "no reply");
    job_ = json::parse(r->body)["id"];
    for (int i = 0; i < 1200; ++i) {  // a bound on the wait, not a timed assertion
      const json job = json::parse(c.Get("/v1/jobs/" + std::to_string(job_))->body);
      if (job["status"] != "queued" && job["status"] != "running") {
        ASSERT_EQ(job["status"], "succeeded") << job.dump();
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    FAIL() << "the sweep did not finish";
  }
  static void TearDownTestSuite() {
    service_->Stop();
    delete service_;
    std::filesystem::remove_all(*dir_);
    delete dir_;
  }

  static httplib::Client Client() { return httplib::Client("127.0.0.1", port_); }
  static std::string JobPath(const std::string& tail) { return "/v1/jobs/" + std::to_string(job_) + tail; }
  // Every row of the points table, by the JSON pages.
  static size_t PointRowCount() {
    auto c = Client();
    size_t rows = 0;
    std::string cursor = "0";
    for (int page = 0; page < 100; ++page) {
      const json body = json::parse(c.Get(JobPath("/points?limit=10000&cursor=" + cursor))->body);
      rows += body["points"].size();
      if (body["next_cursor"].is_null()) return rows;
      cursor = std::to_string(body["next_cursor"].get<int64_t>());
    }
    ADD_FAILURE() << "the JSON pages do not end";
    return rows;
  }

  static inline std::filesystem::path* dir_ = nullptr;
  static inline Service* service_ = nullptr;
  static inline int port_ = 0;
  static inline int64_t job_ = 0;
};

size_t LineCount(const std::string& text) { return static_cast<size_t>(std::count(text.begin(), text.end(), '\n')); }

// A client that follows X-Next-Cursor reads the table once and stops: the last page carries no
// cursor (a cursor of 0 would start again from the first row, forever).
TEST_F(ResultRoutesTest, CsvPagesFollowedByTheirCursorReadTheTableOnce) {
  const size_t total = PointRowCount();
  ASSERT_GT(total, 1000u);
  auto c = Client();
  size_t rows = 0;
  std::string cursor = "0";
  int pages = 0;
  for (; pages < 20; ++pages) {
    auto r = c.Get(JobPath("/points?limit=400&cursor=" + cursor), {{"Accept", "text/csv"}});
    ASSERT_TRUE(r && r->status == 200);
    rows += LineCount(r->body) - 1;  // less the header
    if (!r->has_header("X-Next-Cursor")) break;
    cursor = r->get_header_value("X-Next-Cursor");
    ASSERT_NE(cursor, "0") << "a cursor back to the first page after " << rows << " rows";
  }
  EXPECT_LT(pages, 20);
  EXPECT_EQ(rows, total);
}

// pandas.read_csv(url): ?format=csv (or Accept: text/csv) without limit or cursor is the whole
// table in one body, past the 1,000 rows of a page; with filters, the rows that pass them.
TEST_F(ResultRoutesTest, FormatCsvIsTheWholeTableInOneBody) {
  const size_t total = PointRowCount();
  auto c = Client();
  auto by_query = c.Get(JobPath("/points?format=csv"));
  ASSERT_TRUE(by_query && by_query->status == 200);
  EXPECT_THAT(by_query->get_header_value("Content-Type"), HasSubstr("text/csv"));
  EXPECT_FALSE(by_query->has_header("X-Next-Cursor"));
  EXPECT_EQ(LineCount(by_query->body), total + 1);
  EXPECT_EQ(by_query->body.substr(0, by_query->body.find('\n')).substr(0, 25), "frequency_hz,amplitude_v,");
  auto by_accept = c.Get(JobPath("/points"), {{"Accept", "text/csv"}});
  ASSERT_TRUE(by_accept && by_accept->status == 200);
  EXPECT_EQ(by_accept->body, by_query->body);
  auto up = c.Get(JobPath("/points?format=csv&branch=up&amplitude_v=0.35"));
  ASSERT_TRUE(up && up->status == 200);
  EXPECT_EQ(LineCount(up->body), 61u);  // header + 60 frequencies
  // ?format=json wins over the Accept header; another format names the parameter.
  auto json_page = c.Get(JobPath("/points?format=json&limit=5"), {{"Accept", "text/csv"}});
  EXPECT_EQ(json::parse(json_page->body)["points"].size(), 5u);
  auto bad = c.Get(JobPath("/points?format=xml"));
  EXPECT_EQ(bad->status, 400);
  EXPECT_EQ(json::parse(bad->body)["error"]["field"], "format");
}

// The saturation thresholds and the jump intervals load as tables of their own, in CSV or JSON.
TEST_F(ResultRoutesTest, ThresholdsAndJumpsAreTablesInCsvAndJson) {
  auto c = Client();
  const json map = json::parse(c.Get(JobPath("/saturation-map"))->body);
  auto thresholds = c.Get(JobPath("/thresholds?format=csv"));
  ASSERT_TRUE(thresholds && thresholds->status == 200) << thresholds->body;
  EXPECT_THAT(thresholds->get_header_value("Content-Type"), HasSubstr("text/csv"));
  EXPECT_EQ(LineCount(thresholds->body), 61u);
  EXPECT_EQ(thresholds->body.substr(0, thresholds->body.find('\n')),
            "frequency_hz,grazing_amplitude_v,lowest_contact_amplitude_v");
  auto jumps = c.Get(JobPath("/jumps"), {{"Accept", "text/csv"}});
  ASSERT_TRUE(jumps && jumps->status == 200);
  ASSERT_FALSE(map["jump"].empty());
  EXPECT_EQ(LineCount(jumps->body), map["jump"].size() + 1);
  EXPECT_THAT(jumps->body, HasSubstr("amplitude_v,bistable_from_hz,bistable_to_hz,from_kind,to_kind\n"));
  EXPECT_EQ(json::parse(c.Get(JobPath("/thresholds"))->body)["saturation_threshold"], map["saturation_threshold"]);
  EXPECT_EQ(json::parse(c.Get(JobPath("/jumps?format=json"))->body)["jump"], map["jump"]);
}

// A job shows what it computed: the spec as submitted and as resolved, with every model parameter
// (the preset's spelled out), the grid's axes with their values as the axis defines them, and the
// options; in its status and in the saturation map.
TEST_F(ResultRoutesTest, TheJobShowsItsSpecModelAndGrid) {
  auto c = Client();
  const json job = json::parse(c.Get(JobPath(""))->body);
  EXPECT_EQ(job["spec"], kResultRoutesSweep);
  const json& resolved = job["resolved"];
  EXPECT_EQ(resolved["model"]["mass_kg"], 0.032);
  EXPECT_TRUE(resolved["model"].contains("stiffness_n_per_m")) << resolved["model"].dump();
  EXPECT_EQ(resolved["thresholds"], true);
  const json& amplitudes = resolved["grid"]["amplitude_v"];
  EXPECT_EQ(amplitudes["spacing"], "linear");
  EXPECT_EQ(amplitudes["values"].dump(), "[0.1,0.15,0.2,0.25,0.3,0.35,0.4,0.45,0.5,0.55,0.6]");
  EXPECT_EQ(resolved["grid"]["frequency_hz"]["values"].size(), 60u);
  EXPECT_EQ(resolved["grid"]["frequency_hz"]["values"][0], 6.0);
  const json map = json::parse(c.Get(JobPath("/saturation-map"))->body);
  EXPECT_EQ(map["job"]["resolved"], resolved);
  // The amplitudes the results carry are the grid's, printed as such.
  auto csv = c.Get(JobPath("/points?format=csv&branch=up&frequency_max_hz=6"));
  EXPECT_THAT(csv->body, HasSubstr("\n6,0.3,up,"));
  EXPECT_THAT(csv->body, ::testing::Not(HasSubstr("0000000")));
}

// An amplitude off the grid is a 400 naming the nearest grid values, not an empty table; one a hair
// from a grid value (as a float printed long) is that value.
TEST_F(ResultRoutesTest, OffGridAmplitudesNameTheGridAndNearOnesSnap) {
  auto c = Client();
  for (const std::string query : {"/points?amplitude_v=0.33", "/frf?amplitude_v=0.51", "/points?format=csv&amplitude_v=0.33"}) {
    auto r = c.Get(JobPath(query));
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 400) << query;
    const json error = json::parse(r->body)["error"];
    EXPECT_EQ(error["code"], "off_grid");
    EXPECT_EQ(error["field"], "amplitude_v");
    EXPECT_THAT(error["message"].get<std::string>(), HasSubstr(query.find("0.33") != std::string::npos ? "nearest: 0.3 and 0.35 V" : "nearest: 0.5 and 0.55 V"));
    EXPECT_THAT(error["message"].get<std::string>(), HasSubstr("0.1, 0.15, 0.2,"));
  }
  const json frf = json::parse(c.Get(JobPath("/frf?amplitude_v=0.30000000000000004"))->body);
  EXPECT_EQ(frf["amplitude_v"].dump(), "0.3");
  EXPECT_EQ(frf["branches"]["up"].size(), 60u);
  EXPECT_EQ(json::parse(c.Get(JobPath("/points?branch=down&amplitude_v=0.2999999999"))->body)["points"].size(), 60u);
}

}  // namespace
}  // namespace strokelab::server
