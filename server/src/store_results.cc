// The store's result rows (store.h): written with their filter columns, read back in pages with
// keyset cursors.
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

  std::lock_guard lock(mu_);
  Stmt s = Prepare(sql);
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
  std::lock_guard lock(mu_);
  Stmt s = Prepare("SELECT count(*) FROM results WHERE job_id = ?1 AND table_name = ?2");
  s.Int(1, job_id).Text(2, table).Step();
  return s.ColInt(0);
}

void SqliteStore::InsertResultRows(int64_t job_id, int64_t task_idx, const std::vector<ResultRow>& rows) {
  if (static_cast<int64_t>(rows.size()) >= kRowsPerTaskLimit) throw std::length_error("job store: too many rows");
  for (size_t r = 0; r < rows.size(); ++r) {
    const FilterColumns c = ExtractFilterColumns(rows[r].values);
    Stmt s = Prepare(
        "INSERT INTO results (job_id, table_name, task_idx, row_idx, frequency_hz, amplitude_v, branch, json) "
        "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)");
    s.Int(1, job_id).Text(2, rows[r].table).Int(3, task_idx).Int(4, static_cast<int64_t>(r));
    s.OptDouble(5, c.frequency_hz).OptDouble(6, c.amplitude_v).OptText(7, c.branch);
    s.Text(8, rows[r].values.dump(-1, ' ', false, json::error_handler_t::replace)).Run();
  }
}

}  // namespace strokelab::server::internal
