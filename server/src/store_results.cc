// The store's result rows (store.h): encoded once, written with their filter columns in batches,
// read back in pages with keyset cursors.
#include <cmath>
#include <cstdint>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "store_internal.h"
#include "strokelab/server/store.h"
#include "strokelab/base/json_parse.h"

namespace strokelab::server::internal {
namespace {

using nlohmann::json;

// Amplitude filter: stored and requested amplitudes match when they differ by at most this
// fraction of the requested one (dimensionless).
constexpr double kAmplitudeMatchRel = 1e-9;

// Results cursors encode the position (task_idx, row_idx) of the last row returned as
// task_idx * 2^32 + row_idx + 1, so that 0 stays "from the start" and the order of cursors is the
// order of rows.
constexpr int64_t kRowsPerTaskLimit = (int64_t{1} << 32) - 1;
int64_t EncodeCursor(int64_t task_idx, int64_t row_idx) { return (task_idx << 32) | (row_idx + 1); }

// The values copied out of a row's JSON into indexed columns.
struct FilterColumns {
  std::optional<double> frequency_hz, amplitude_v;
  std::optional<std::string> branch;
};
FilterColumns ExtractFilterColumns(const json& values) {
  FilterColumns c;
  if (!values.is_object()) return c;
  auto number = [&](const char* name) -> std::optional<double> {
    auto it = values.find(name);
    if (it == values.end() || !it->is_number()) return std::nullopt;
    const double v = it->get<double>();
    return std::isfinite(v) ? std::optional<double>(v) : std::nullopt;
  };
  c.frequency_hz = number("frequency_hz");
  c.amplitude_v = number("amplitude_v");
  if (auto it = values.find("branch"); it != values.end() && it->is_string()) c.branch = it->get<std::string>();
  return c;
}

}  // namespace

Store::Page SqliteStore::Results(int64_t job_id, const std::string& table, const Filter& filter, int64_t cursor,
                                 int limit) {
  if (cursor < 0) throw std::invalid_argument("cursor: not a cursor returned by this service");
  if (limit <= 0) throw std::invalid_argument("limit: must be at least 1");
  // One statement per combination of filters (at most 32), so that each can use its best index.
  std::string sql = "SELECT task_idx, row_idx, json FROM results WHERE job_id = ?1 AND table_name = ?2";
  if (cursor > 0) sql += " AND (task_idx, row_idx) > (?3, ?4)";
  if (filter.frequency_min_hz) sql += " AND frequency_hz >= ?5";
  if (filter.frequency_max_hz) sql += " AND frequency_hz <= ?6";
  if (filter.amplitude_v) sql += " AND amplitude_v BETWEEN ?7 AND ?8";
  if (filter.branch) sql += " AND branch = ?9";
  sql += " ORDER BY task_idx, row_idx LIMIT ?10";

  ReaderPool::Handle reader = readers_.Acquire();
  Stmt s = reader->Prepare(sql);
  s.Int(1, job_id).Text(2, table);
  if (cursor > 0) s.Int(3, cursor >> 32).Int(4, (cursor & kRowsPerTaskLimit) - 1);
  if (filter.frequency_min_hz) s.Double(5, *filter.frequency_min_hz);
  if (filter.frequency_max_hz) s.Double(6, *filter.frequency_max_hz);
  if (filter.amplitude_v) {
    const double a = *filter.amplitude_v, tol = kAmplitudeMatchRel * std::abs(a);
    s.Double(7, a - tol).Double(8, a + tol);
  }
  if (filter.branch) s.Text(9, *filter.branch);
  s.Int(10, static_cast<int64_t>(limit) + 1);  // one more tells whether there is a next page

  Page page;
  int64_t last = 0;
  while (s.Step()) {
    if (static_cast<int>(page.rows.size()) == limit) {
      page.next_cursor = last;
      break;
    }
    last = EncodeCursor(s.ColInt(0), s.ColInt(1));
    page.rows.push_back(ParseJson(s.ColText(2)));
  }
  return page;
}

int64_t SqliteStore::CountResults(int64_t job_id, const std::string& table) {
  ReaderPool::Handle reader = readers_.Acquire();
  Stmt s = reader->Prepare("SELECT count(*) FROM results WHERE job_id = ?1 AND table_name = ?2");
  s.Int(1, job_id).Text(2, table).Step();
  return s.ColInt(0);
}

EncodedRows EncodeRows(const std::vector<ResultRow>& rows) {
  if (static_cast<int64_t>(rows.size()) >= kRowsPerTaskLimit) throw std::length_error("job store: too many rows");
  EncodedRows out;
  out.rows.reserve(rows.size());
  size_t bytes = 2;
  for (const ResultRow& r : rows) {
    const FilterColumns c = ExtractFilterColumns(r.values);
    out.rows.push_back({&r.table, r.values.dump(-1, ' ', false, json::error_handler_t::replace), c.frequency_hz,
                        c.amplitude_v, c.branch});
    bytes += out.rows.back().json.size() + r.table.size() + 24;
    if (r.table == "points") ++out.points;
  }
  // The cache entry is the array of {"table": ..., "values": ...} objects that json::dump writes
  // (keys in order, no spaces), made of the texts above rather than by encoding every row again.
  out.cache_json.reserve(bytes);
  out.cache_json += '[';
  for (const EncodedRow& e : out.rows) {
    if (out.cache_json.size() > 1) out.cache_json += ',';
    out.cache_json += "{\"table\":";
    out.cache_json += json(*e.table).dump(-1, ' ', false, json::error_handler_t::replace);
    out.cache_json += ",\"values\":";
    out.cache_json += e.json;
    out.cache_json += '}';
  }
  out.cache_json += ']';
  return out;
}

// Rows go in by kBatchRows per INSERT statement (fewer statement executions than one per row), each
// batch statement prepared once per connection; the last rows of a task one by one.
void SqliteStore::InsertResultRows(int64_t job_id, int64_t task_idx, const EncodedRows& encoded) {
  constexpr int kColumns = 8;
  constexpr size_t kBatchRows = 50;  // 400 parameters, within every SQLite's limit (999)
  static const std::string kInsertOne =
      "INSERT INTO results (job_id, table_name, task_idx, row_idx, frequency_hz, amplitude_v, branch, json) "
      "VALUES (?, ?, ?, ?, ?, ?, ?, ?)";
  static const std::string kInsertBatch = [] {
    std::string sql = kInsertOne;
    for (size_t r = 1; r < kBatchRows; ++r) sql += ", (?, ?, ?, ?, ?, ?, ?, ?)";
    return sql;
  }();
  const std::vector<EncodedRow>& rows = encoded.rows;
  const auto bind_row = [&](Stmt& s, int first, size_t r) {
    const EncodedRow& e = rows[r];
    s.Int(first, job_id).StaticText(first + 1, *e.table).Int(first + 2, task_idx).Int(first + 3, static_cast<int64_t>(r));
    s.OptDouble(first + 4, e.frequency_hz).OptDouble(first + 5, e.amplitude_v).OptStaticText(first + 6, e.branch);
    s.StaticText(first + 7, e.json);
  };
  size_t r = 0;
  if (rows.size() >= kBatchRows) {
    Stmt s = writer_.Prepare(kInsertBatch);
    for (; r + kBatchRows <= rows.size(); r += kBatchRows) {
      for (size_t k = 0; k < kBatchRows; ++k) bind_row(s, static_cast<int>(k) * kColumns + 1, r + k);
      s.Run();
      s.Reset();
    }
  }
  Stmt s = writer_.Prepare(kInsertOne);
  for (; r < rows.size(); ++r) {
    bind_row(s, 1, r);
    s.Run();
    s.Reset();
  }
}

}  // namespace strokelab::server::internal
