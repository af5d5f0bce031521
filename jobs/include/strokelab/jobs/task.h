// A task, the unit of work that a job is split into (jobs.h), and the rows it produces.
#pragma once

#include <nlohmann/json.hpp>
#include <initializer_list>
#include <string>
#include <vector>

namespace strokelab::jobs {

struct TaskSpec {
  std::string key;                 // content hash: identical work has the same key
  nlohmann::json spec;             // what the worker needs to run it
};

// One result row of a task: a table name ("points", "thresholds", "jumps", "records", "fit", ...)
// and its values, usually a JSON object. The store keeps a task's rows of one table as one result
// block, in order: (job, task, row) makes a row unique.
struct ResultRow {
  std::string table;
  nlohmann::json values;
};

// Rows of one table that share their columns, as flat cells: what a sweep task returns (thousands
// of rows). Building each row as a JSON object cost the service as much CPU as computing it (issue
// 17), so the store encodes these cells as they are; RowAt gives the JSON object a row stands for.
struct ResultRecords {
  std::string table;
  std::vector<std::string> columns;
  std::vector<nlohmann::json> cells;  // scalars; row r, column c at r * columns.size() + c

  size_t size() const { return columns.empty() ? 0 : cells.size() / columns.size(); }
  nlohmann::json RowAt(size_t row) const;  // {column: cell, ...}
};

// What a task returns: rows as JSON (fit, diagnosis, simulate, report files, warnings) and tables
// of flat rows (sweep tasks). A result of JSON rows alone converts from them.
struct TaskResult {
  std::vector<ResultRow> rows;
  std::vector<ResultRecords> records;

  TaskResult() = default;
  TaskResult(std::vector<ResultRow> json_rows) : rows(std::move(json_rows)) {}  // NOLINT: implicit on purpose
  TaskResult(std::initializer_list<ResultRow> json_rows) : rows(json_rows) {}

  size_t RowCount() const;
  // Every row as JSON: `rows`, then each table of `records` (what a remote worker sends).
  std::vector<ResultRow> AllRows() const;
};

}  // namespace strokelab::jobs
