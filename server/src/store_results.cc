// The store's result rows (store.h): a task's rows of one table go in as one result block
// (row_block.h) with the ranges of their filter columns, and come back in pages with keyset cursors.
// One SQL row per block rather than per result row: a completion of a 2,000-row sweep task writes
// one B-tree entry of ~260 KB per table instead of 2,000 rows of JSON text in three B-trees.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "row_block.h"
#include "store_internal.h"
#include "strokelab/server/store.h"
#include "strokelab/base/json_parse.h"

namespace strokelab::server::internal {
namespace {

using nlohmann::json;

// Amplitude filter: stored and requested amplitudes match when they differ by at most this
// fraction of the requested one (dimensionless).
constexpr double kAmplitudeMatchRel = 1e-9;

// Results cursors encode the position (task_idx, row_idx: the row's place in its block) of the last
// row returned as task_idx * 2^32 + row_idx + 1, so that 0 stays "from the start" and the order of
// cursors is the order of rows.
constexpr int64_t kRowsPerTaskLimit = (int64_t{1} << 32) - 1;
int64_t EncodeCursor(int64_t task_idx, int64_t row_idx) { return (task_idx << 32) | (row_idx + 1); }

// The values copied out of a row's JSON into indexed columns.
struct FilterColumns {
  std::optional<double> frequency_hz, amplitude_v;
  std::optional<std::string> branch;
};
std::optional<double> FiniteNumber(const json& value) {
  if (!value.is_number()) return std::nullopt;
  const double v = value.get<double>();
  return std::isfinite(v) ? std::optional<double>(v) : std::nullopt;
}
FilterColumns ExtractFilterColumns(const json& values) {
  FilterColumns c;
  if (!values.is_object()) return c;
  auto number = [&](const char* name) -> std::optional<double> {
    auto it = values.find(name);
    return it == values.end() ? std::nullopt : FiniteNumber(*it);
  };
  c.frequency_hz = number("frequency_hz");
  c.amplitude_v = number("amplitude_v");
  if (auto it = values.find("branch"); it != values.end() && it->is_string()) c.branch = it->get<std::string>();
  return c;
}

bool Matches(const FilterColumns& c, const Store::Filter& filter) {
  if (filter.frequency_min_hz && !(c.frequency_hz && *c.frequency_hz >= *filter.frequency_min_hz)) return false;
  if (filter.frequency_max_hz && !(c.frequency_hz && *c.frequency_hz <= *filter.frequency_max_hz)) return false;
  if (filter.amplitude_v) {
    const double a = *filter.amplitude_v, tol = kAmplitudeMatchRel * std::abs(a);
    if (!(c.amplitude_v && *c.amplitude_v >= a - tol && *c.amplitude_v <= a + tol)) return false;
  }
  return !filter.branch || c.branch == *filter.branch;
}

// Widens [lo, hi] to take v.
void Extend(std::optional<double>& lo, std::optional<double>& hi, const std::optional<double>& v) {
  if (!v) return;
  if (!lo || *v < *lo) lo = v;
  if (!hi || *v > *hi) hi = v;
}

// The blocks of a task's rows, one per table, in the order of each table's first row.
class BlockBuilder {
 public:
  void Add(const std::string& table, const json& values) {
    Part& part = PartOf(table);
    const FilterColumns c = ExtractFilterColumns(values);
    Extend(part.block.frequency_min_hz, part.block.frequency_max_hz, c.frequency_hz);
    Extend(part.block.amplitude_min_v, part.block.amplitude_max_v, c.amplitude_v);
    part.writer.Add(values);
  }
  void Add(const jobs::ResultRecords& records) {
    if (records.size() == 0) return;
    Part& part = PartOf(records.table);
    const auto column = [&](const char* name) {
      return std::find(records.columns.begin(), records.columns.end(), name) - records.columns.begin();
    };
    const size_t width = records.columns.size(), frequency = column("frequency_hz"), amplitude = column("amplitude_v");
    for (size_t first = 0; first < records.cells.size(); first += width) {
      if (frequency < width)
        Extend(part.block.frequency_min_hz, part.block.frequency_max_hz, FiniteNumber(records.cells[first + frequency]));
      if (amplitude < width)
        Extend(part.block.amplitude_min_v, part.block.amplitude_max_v, FiniteNumber(records.cells[first + amplitude]));
    }
    part.writer.AddRecords(records.columns, records.cells);
  }
  EncodedRows Finish() {
    EncodedRows out;
    for (Part& p : parts_) {
      p.block.rows = p.writer.rows();
      p.block.bytes = p.writer.Finish();
      if (p.block.table == "points") out.points += p.block.rows;
      out.blocks.push_back(std::move(p.block));
    }
    return out;
  }

 private:
  struct Part {
    EncodedBlock block;
    RowBlockWriter writer;
  };
  Part& PartOf(const std::string& table) {
    for (Part& p : parts_)
      if (p.block.table == table) return p;
    Part& part = parts_.emplace_back();
    part.block.table = table;
    return part;
  }
  std::vector<Part> parts_;
};

}  // namespace

Store::Page SqliteStore::Results(int64_t job_id, const std::string& table, const Filter& filter, int64_t cursor,
                                 int limit) {
  if (cursor < 0) throw std::invalid_argument("cursor: not a cursor returned by this service");
  if (limit <= 0) throw std::invalid_argument("limit: must be at least 1");
  const int64_t cursor_task = cursor >> 32, cursor_row = (cursor & kRowsPerTaskLimit) - 1;  // row -1: none yet
  // Blocks whose ranges cannot hold a matching row are skipped unread (a NULL range: no row has
  // that column). One statement per combination of filters, at most 8.
  std::string sql = "SELECT task_idx, block FROM result_blocks WHERE job_id = ?1 AND table_name = ?2 AND task_idx >= ?3";
  if (filter.frequency_min_hz) sql += " AND frequency_max_hz >= ?4";
  if (filter.frequency_max_hz) sql += " AND frequency_min_hz <= ?5";
  if (filter.amplitude_v) sql += " AND amplitude_max_v >= ?6 AND amplitude_min_v <= ?7";
  sql += " ORDER BY task_idx";

  ReaderPool::Handle reader = readers_.Acquire();
  Stmt s = reader->Prepare(sql);
  s.Int(1, job_id).Text(2, table).Int(3, cursor_task);
  if (filter.frequency_min_hz) s.Double(4, *filter.frequency_min_hz);
  if (filter.frequency_max_hz) s.Double(5, *filter.frequency_max_hz);
  if (filter.amplitude_v) {
    const double a = *filter.amplitude_v, tol = kAmplitudeMatchRel * std::abs(a);
    s.Double(6, a - tol).Double(7, a + tol);
  }

  Page page;
  int64_t last = 0;
  while (s.Step()) {
    const int64_t task_idx = s.ColInt(0);
    std::vector<json> rows = DecodeRowBlock(s.ColBlob(1));
    const int64_t first = task_idx == cursor_task ? cursor_row + 1 : 0;
    for (int64_t r = first; r < static_cast<int64_t>(rows.size()); ++r) {
      if (!Matches(ExtractFilterColumns(rows[r]), filter)) continue;
      if (static_cast<int>(page.rows.size()) == limit) {  // one more: there is a next page
        page.next_cursor = last;
        return page;
      }
      last = EncodeCursor(task_idx, r);
      page.rows.push_back(std::move(rows[r]));
    }
  }
  return page;
}

int64_t SqliteStore::CountResults(int64_t job_id, const std::string& table) {
  ReaderPool::Handle reader = readers_.Acquire();
  Stmt s = reader->Prepare("SELECT coalesce(sum(rows), 0) FROM result_blocks WHERE job_id = ?1 AND table_name = ?2");
  s.Int(1, job_id).Text(2, table).Step();
  return s.ColInt(0);
}

EncodedRows EncodeRows(const TaskResult& result) {
  if (static_cast<int64_t>(result.RowCount()) >= kRowsPerTaskLimit) throw std::length_error("job store: too many rows");
  BlockBuilder builder;
  for (const ResultRow& r : result.rows) builder.Add(r.table, r.values);
  for (const jobs::ResultRecords& records : result.records) builder.Add(records);
  return builder.Finish();
}

void SqliteStore::InsertResultRows(int64_t job_id, int64_t task_idx, const EncodedRows& encoded) {
  Stmt s = writer_.Prepare(
      "INSERT INTO result_blocks (job_id, table_name, task_idx, rows, frequency_min_hz, frequency_max_hz, "
      "amplitude_min_v, amplitude_max_v, block) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9)");
  for (const EncodedBlock& b : encoded.blocks) {
    s.Int(1, job_id).StaticText(2, b.table).Int(3, task_idx).Int(4, b.rows);
    s.OptDouble(5, b.frequency_min_hz).OptDouble(6, b.frequency_max_hz);
    s.OptDouble(7, b.amplitude_min_v).OptDouble(8, b.amplitude_max_v).StaticBlob(9, b.bytes);
    s.Run();
    s.Reset();
  }
}

int64_t SqliteStore::CopyResultBlocks(int64_t from_job_id, int64_t from_task_idx, int64_t job_id, int64_t task_idx) {
  {
    Stmt s = writer_.Prepare(
        "INSERT INTO result_blocks (job_id, table_name, task_idx, rows, frequency_min_hz, frequency_max_hz, "
        "amplitude_min_v, amplitude_max_v, block) "
        "SELECT ?3, table_name, ?4, rows, frequency_min_hz, frequency_max_hz, amplitude_min_v, amplitude_max_v, block "
        "FROM result_blocks WHERE job_id = ?1 AND task_idx = ?2 ORDER BY id");
    s.Int(1, from_job_id).Int(2, from_task_idx).Int(3, job_id).Int(4, task_idx).Run();
  }
  Stmt s = writer_.Prepare(
      "SELECT coalesce(sum(rows), 0) FROM result_blocks WHERE job_id = ?1 AND task_idx = ?2 AND table_name = 'points'");
  s.Int(1, job_id).Int(2, task_idx).Step();
  return s.ColInt(0);
}

// Migration 006: schema 5 kept one row per result row (results) and a JSON copy of each finished
// task's rows by task key (cache). The rows move into blocks in their order; the cache is dropped,
// since a finished task with the same key now serves a hit from its own blocks.
void SqliteStore::MoveResultRowsIntoBlocks() {
  Stmt s = writer_.Prepare(
      "SELECT job_id, task_idx, table_name, json FROM results ORDER BY job_id, task_idx, row_idx");
  int64_t job_id = -1, task_idx = -1;
  std::vector<ResultRow> rows;
  const auto flush = [&] {
    if (!rows.empty()) InsertResultRows(job_id, task_idx, EncodeRows(rows));
    rows.clear();
  };
  while (s.Step()) {
    if (s.ColInt(0) != job_id || s.ColInt(1) != task_idx) {
      flush();
      job_id = s.ColInt(0);
      task_idx = s.ColInt(1);
    }
    rows.push_back({s.ColText(2), ParseJson(s.ColText(3))});
  }
  flush();
  s.Reset();
  writer_.Exec("DROP TABLE results");
  writer_.Exec("DROP TABLE cache");
}

}  // namespace strokelab::server::internal
