// The result routes of finished jobs: a sweep's points, thresholds and jumps (JSON or CSV), saturation
// map and FRFs (JSON or SVG); a fit's or diagnosis's result document and HTML report.
#include "service_impl.h"

#include <algorithm>
#include <cmath>
#include <memory>

#include "http_reply.h"
#include "request_params.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/json_number.h"
#include "strokelab/jobs/job_spec.h"
#include "strokelab/jobs/jobs.h"
#include "strokelab/report/sweep_report.h"
#include "strokelab/report/sweep_tables.h"

namespace strokelab::server {

using nlohmann::json;
using namespace internal;

namespace {

// A stored result row as its type. A row that does not read (written by a broken worker, or by a
// damaged store) is the service's fault, not the client's: a 500, never a 400 naming a column the
// client never sent.
template <class Row>
Row StoredRow(const json& row, int64_t job_id, const char* table) {
  try {
    return report::RowFromJson<Row>(row);
  } catch (const InputError& e) {
    throw std::runtime_error("job " + std::to_string(job_id) + ": a stored row of table " + table +
                             " does not read: " + e.what());
  }
}

// Stored point rows as CSV (sweep_tables.h: the columns and cells of the sweep folder's points.csv).
std::string PointsCsv(const std::vector<json>& rows, int64_t job_id) {
  std::string out = report::CsvHeader<SweepPoint>();
  for (const json& row : rows) out += report::CsvLine(StoredRow<SweepPoint>(row, job_id, "points"));
  return out;
}

// Stored rows of a small table (thresholds: one per frequency; jumps: a few per amplitude) as CSV,
// thresholds in order of frequency as the saturation map lists them.
template <class Row>
std::string TableCsv(const std::vector<json>& rows, int64_t job_id, const char* table) {
  std::string out = report::CsvHeader<Row>();
  for (const json& row : rows) out += report::CsvLine(StoredRow<Row>(row, job_id, table));
  return out;
}

// Points per chunk of a streamed CSV body.
constexpr int kCsvRowsPerChunk = 2000;

// Every point row that passes `filter`, as one CSV body written a page of the store at a time as
// the client reads it, so that a whole sweep never sits in memory as text. The headers are sent by
// then: a row that does not read cuts the body short (the client sees a broken transfer).
void StreamPointsCsv(Store& store, int64_t job_id, const Store::Filter& filter, httplib::Response& res) {
  struct Position {
    int64_t cursor = 0;
    bool header_sent = false;
  };
  auto at = std::make_shared<Position>();
  res.set_chunked_content_provider("text/csv", [&store, job_id, filter, at](size_t, httplib::DataSink& sink) {
    try {
      std::string text = at->header_sent ? std::string() : report::CsvHeader<SweepPoint>();
      at->header_sent = true;
      const Store::Page page = store.Results(job_id, "points", filter, at->cursor, kCsvRowsPerChunk);
      for (const json& row : page.rows) text += report::CsvLine(StoredRow<SweepPoint>(row, job_id, "points"));
      if (!sink.write(text.data(), text.size())) return false;
      if (page.next_cursor == 0) sink.done();
      at->cursor = page.next_cursor;
      return true;
    } catch (const std::exception&) {
      return false;
    }
  });
}

// A number as the service writes it in JSON (the shortest that reads back).
std::string NumberText(double value) { return json(value).dump(); }

// The amplitude of a sweep job's grid that `requested` names: one within a millionth of the grid's
// smallest step of it (0.30000000000000004 names 0.3). Off the grid, 400 naming the grid's
// amplitudes (the nearest below and above, and the axis; GET /v1/jobs/{id} lists them all), rather
// than an empty table that looks like a result.
double GridAmplitude(const JobRecord& job, double requested) {
  const std::vector<double> grid = jobs::SweepSpecFromJob(job.spec).amplitude_v.Values();
  double smallest_step = std::abs(grid.back());
  for (size_t i = 1; i < grid.size(); ++i) smallest_step = std::min(smallest_step, grid[i] - grid[i - 1]);
  const double tolerance = 1e-6 * std::max(smallest_step, 1e-300);
  const auto above = std::lower_bound(grid.begin(), grid.end(), requested);
  if (above != grid.end() && *above - requested <= tolerance) return *above;
  if (above != grid.begin() && requested - *(above - 1) <= tolerance) return *(above - 1);
  std::string nearest;
  if (above != grid.begin()) nearest += NumberText(*(above - 1));
  if (above != grid.end()) nearest += (nearest.empty() ? "" : " and ") + NumberText(*above);
  std::string all;
  if (grid.size() <= 30) {
    for (double v : grid) all += (all.empty() ? "" : ", ") + NumberText(v);
  } else {
    all = NumberText(grid.front()) + " .. " + NumberText(grid.back()) + " in " + std::to_string(grid.size()) + " values";
  }
  throw HttpError{400, "off_grid",
                  NumberText(requested) + " V is not an amplitude of job " + std::to_string(job.id) +
                      "'s grid; nearest: " + nearest + " V (the grid: " + all + " V; GET /v1/jobs/" +
                      std::to_string(job.id) + " lists them under resolved.grid)",
                  "amplitude_v"};
}

// The filters of /points and /frf that are query parameters; a sweep's amplitude snapped to its grid.
Store::Filter PointFilter(const httplib::Request& req, const JobRecord& job) {
  Store::Filter filter;
  if (req.has_param("frequency_min_hz")) filter.frequency_min_hz = QueryNumber(req, "frequency_min_hz");
  if (req.has_param("frequency_max_hz")) filter.frequency_max_hz = QueryNumber(req, "frequency_max_hz");
  if (req.has_param("amplitude_v")) {
    filter.amplitude_v = QueryNumber(req, "amplitude_v");
    if (job.kind == "sweep") filter.amplitude_v = GridAmplitude(job, *filter.amplitude_v);
  }
  if (req.has_param("branch")) {
    const std::string b = req.get_param_value("branch");
    if (b != "up" && b != "down" && b != "unstable")
      throw HttpError{400, "bad_query", "must be up, down or unstable", "branch"};
    filter.branch = b;
  }
  return filter;
}

}  // namespace

std::vector<json> Service::Impl::ThresholdRows(const JobRecord& job) {
  std::vector<json> rows = store->Results(job.id, "thresholds", {}, 0, 1000000).rows;
  std::sort(rows.begin(), rows.end(), [](const json& a, const json& b) { return a["frequency_hz"] < b["frequency_hz"]; });
  return rows;
}

SweepResult Service::Impl::SweepResultOf(const JobRecord& job) {
  SweepResult r;
  const SweepSpec spec = jobs::SweepSpecFromJob(job.spec);
  r.frequency_hz = spec.frequency_hz.Values();
  r.amplitude_v = spec.amplitude_v.Values();
  for (int64_t cursor = 0;;) {
    const Store::Page page = store->Results(job.id, "points", {}, cursor, 10000);
    for (const json& p : page.rows) r.points.push_back(StoredRow<SweepPoint>(p, job.id, "points"));
    if (page.next_cursor == 0) break;
    cursor = page.next_cursor;
  }
  for (const json& t : store->Results(job.id, "thresholds", {}, 0, 1000000).rows)
    r.saturation_threshold.push_back(StoredRow<SaturationThreshold>(t, job.id, "thresholds"));
  std::sort(r.saturation_threshold.begin(), r.saturation_threshold.end(),
            [](const auto& a, const auto& b) { return a.frequency_hz < b.frequency_hz; });
  for (const json& j : store->Results(job.id, "jumps", {}, 0, 1000000).rows)
    r.jump.push_back(StoredRow<JumpInterval>(j, job.id, "jumps"));
  return r;
}

std::vector<json> Service::Impl::CampaignJobRows(const JobRecord& job, const std::string& table) {
  if (!jobs::IsCampaignKind(job.kind))
    throw HttpError{400, "no_result_document",
                    "only fit and diagnose jobs have a result document (a sweep's results are at /points, "
                    "/saturation-map and /frf)", ""};
  if (job.status != JobStatus::kSucceeded)
    throw HttpError{409, "not_finished", "job " + std::to_string(job.id) + " is " + ToString(job.status) +
                                             (job.error.empty() ? "" : ": " + job.error), ""};
  return store->Results(job.id, table, {}, 0, 100000).rows;
}

void Service::Impl::AddResultRoutes() {
  On("GET", R"(/v1/jobs/(\d+)/points)", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const JobRecord job = RequireJob(req.matches[1]);
             const Store::Filter filter = PointFilter(req, job);
             const bool csv = WantsCsv(req);
             // CSV without limit or cursor: the whole table in one body (pandas.read_csv(url)).
             if (csv && !req.has_param("limit") && !req.has_param("cursor")) {
               StreamPointsCsv(*store, job.id, filter, res);
               return;
             }
             const int limit = QueryLimit(req, 1000, 10000);
             const int64_t cursor = req.has_param("cursor") ? QueryInteger(req, "cursor") : 0;
             const Store::Page page = store->Results(job.id, "points", filter, cursor, limit);
             if (csv) {
               // No header on the last page: a client that follows the header stops there (a
               // cursor of 0 would start again from the first row).
               if (page.next_cursor != 0) res.set_header("X-Next-Cursor", std::to_string(page.next_cursor));
               res.set_content(PointsCsv(page.rows, job.id), "text/csv");
               return;
             }
             SendJson(res, {{"points", page.rows},
                            {"next_cursor", page.next_cursor ? json(page.next_cursor) : json(nullptr)}});
           }));
  // The saturation thresholds and jump intervals as tables of their own (JSON or CSV).
  On("GET", R"(/v1/jobs/(\d+)/(thresholds|jumps))",
     Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
       const JobRecord job = RequireJob(req.matches[1]);
       if (job.kind != "sweep") throw HttpError{400, "not_a_sweep", "only sweep jobs have these tables", ""};
       const bool thresholds = req.matches[2] == "thresholds";
       const std::vector<json> rows =
           thresholds ? ThresholdRows(job) : store->Results(job.id, "jumps", {}, 0, 1000000).rows;
       if (WantsCsv(req)) {
         res.set_content(thresholds ? TableCsv<SaturationThreshold>(rows, job.id, "thresholds")
                                    : TableCsv<JumpInterval>(rows, job.id, "jumps"),
                         "text/csv");
         return;
       }
       SendJson(res, {{thresholds ? "saturation_threshold" : "jump", rows}});
     }));
  On("GET", R"(/v1/jobs/(\d+)/saturation-map)",
           Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const JobRecord job = RequireJob(req.matches[1]);
             if (job.kind != "sweep") throw HttpError{400, "not_a_sweep", "only sweep jobs have a saturation map", ""};
             if (WantsSvg(req)) {
               res.set_content(report::SaturationMapSvg(SweepResultOf(job), Branch::kUp), "image/svg+xml");
               return;
             }
             SendJson(res, {{"job", JobDetailJson(job)},
                            {"saturation_threshold", ThresholdRows(job)},
                            {"jump", store->Results(job.id, "jumps", {}, 0, 1000000).rows}});
           }));
  On("GET", R"(/v1/jobs/(\d+)/frf)", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const JobRecord job = RequireJob(req.matches[1]);
             if (job.kind != "sweep") throw HttpError{400, "not_a_sweep", "only sweep jobs have FRFs", ""};
             if (WantsSvg(req)) {
               const std::string branch = req.has_param("branch") ? req.get_param_value("branch") : "up";
               if (branch != "up" && branch != "down") throw HttpError{400, "bad_query", "must be up or down", "branch"};
               res.set_content(report::FrfMagnitudeSvg(SweepResultOf(job), branch == "down" ? Branch::kDown : Branch::kUp),
                               "image/svg+xml");
               return;
             }
             if (!req.has_param("amplitude_v"))
               throw HttpError{400, "bad_query", "is required (one of the job's amplitudes)", "amplitude_v"};
             Store::Filter filter;
             filter.amplitude_v = GridAmplitude(job, QueryNumber(req, "amplitude_v"));
             json branches = {{"up", json::array()}, {"down", json::array()}, {"unstable", json::array()}};
             for (const json& row : store->Results(job.id, "points", filter, 0, 1000000).rows) {
               const SweepPoint p = StoredRow<SweepPoint>(row, job.id, "points");
               branches[ToString(p.branch)].push_back({{"frequency_hz", JsonNumber(p.frequency_hz)},
                                                       {"h_re_n_per_v", JsonNumber(p.h.real())},
                                                       {"h_im_n_per_v", JsonNumber(p.h.imag())},
                                                       {"magnitude_n_per_v", JsonNumber(std::abs(p.h))}});
             }
             SendJson(res, {{"amplitude_v", *filter.amplitude_v}, {"branches", branches}});
           }));

  On("GET", R"(/v1/jobs/(\d+)/result)", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const JobRecord job = RequireJob(req.matches[1]);
             const std::vector<json> rows = CampaignJobRows(job, job.kind == "fit" ? "fit" : "diagnosis");
             if (rows.empty()) throw std::runtime_error("job " + std::to_string(job.id) + " has no stored result");
             SendJson(res, rows.front());
           }));
  // The model file a campaign job produced (ModelToJson: the format of a job's "model" and of
  // `strokelab sweep --model`): a fit's fitted model, a diagnosis's diagnosed model; the web page's
  // download. The diagnosis's is also its report's model.json.
  On("GET", R"(/v1/jobs/(\d+)/model)", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const JobRecord job = RequireJob(req.matches[1]);
             if (!jobs::IsCampaignKind(job.kind))
               throw HttpError{400, "no_model_file",
                               "only fit and diagnose jobs produce a model file (a sweep's model is in its resolved spec "
                               "at /v1/jobs/" + std::to_string(job.id) + ")", ""};
             const bool fit = job.kind == "fit";
             const std::vector<json> rows = CampaignJobRows(job, fit ? "fit" : "diagnosis");
             const char* member = fit ? "fitted_model" : "model";
             if (rows.empty() || !rows.front().contains(member))
               throw std::runtime_error("job " + std::to_string(job.id) + " has no stored " + member);
             res.set_header("Content-Disposition", "attachment; filename=\"job-" + std::to_string(job.id) + "-model.json\"");
             res.set_content(rows.front()[member].dump(2) + "\n", "application/json");
           }));
  // The report's main page is its index.html (else its first .html file); FILE is another file of it.
  On("GET", R"(/v1/jobs/(\d+)/report(/.*)?)", Route(Role::kRead, [this](const httplib::Request& req, httplib::Response& res) {
             const JobRecord job = RequireJob(req.matches[1]);
             if (job.kind != "diagnose")
               throw HttpError{400, "no_report", "only diagnose jobs have an HTML report", ""};
             const std::vector<json> files = CampaignJobRows(job, "report_files");
             const std::string wanted = req.matches[2].length() > 1 ? req.matches[2].str().substr(1) : "";
             const json* found = nullptr;
             for (const json& f : files) {
               const std::string name = f.at("name");
               if (wanted.empty() ? name == "index.html" : name == wanted) {
                 found = &f;
                 break;
               }
               if (wanted.empty() && found == nullptr && name.ends_with(".html")) found = &f;
             }
             if (found == nullptr)
               throw HttpError{404, "no_report_file",
                               files.empty() ? "this server stored no report for the job (built without the report writer)"
                                             : "the report has no file '" + wanted + "'", ""};
             std::string body = found->at("text");
             // At .../report (no slash) the page's relative links (records.csv) would miss the report.
             if (req.matches[2].length() == 0)
               if (const size_t head = body.find("<head>"); head != std::string::npos)
                 body.insert(head + 6, "<base href=\"/v1/jobs/" + std::to_string(job.id) + "/report/\">");
             res.set_content(body, found->at("content_type").get<std::string>());
           }));
}

}  // namespace strokelab::server
