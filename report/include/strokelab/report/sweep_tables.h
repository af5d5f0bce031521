// A sweep's result tables (points, saturation thresholds, jump intervals) from one table of columns
// per row type: the JSON of the CLI and of the jobs' stored rows, the CSV of the sweep folder and of
// the service, and the reading of stored rows back all come from it, so they cannot drift apart.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "strokelab/sweep/sweep.h"

namespace strokelab::report {

// How a column's value is written: a number (a non-finite one as JSON null, an empty CSV cell), a
// period (an integer >= 1 or "aperiodic": an empty CSV cell), a flag (JSON bool, CSV 1 or 0) or text.
enum class ColumnKind { kNumber, kPeriod, kFlag, kText };

template <class Row>
struct Column {
  const char* name;
  ColumnKind kind;
  nlohmann::json (*get)(const Row&);        // the value as JSON (a number may be non-finite here)
  void (*set)(Row&, const nlohmann::json&);  // from a value of the column's kind
};

// The columns of SweepPoint, SaturationThreshold and JumpInterval, in table order.
template <class Row>
const std::vector<Column<Row>>& Columns();

template <class Row>
nlohmann::json RowToJson(const Row& row);
// The same values without an object per row: the column names in table order, and a row's values
// as RowToJson writes them, appended to `cells` in that order (jobs' ResultRecords).
template <class Row>
std::vector<std::string> ColumnNames();
template <class Row>
void AppendCells(const Row& row, std::vector<nlohmann::json>& cells);
// A row from its JSON (a stored result row); throws InputError naming the column when one is missing
// or of another kind.
template <class Row>
Row RowFromJson(const nlohmann::json& json);

template <class Row>
std::string CsvHeader();  // "frequency_hz,amplitude_v,...\n"
template <class Row>
std::string CsvLine(const Row& row);  // one line, numbers in their shortest round-trip form

}  // namespace strokelab::report
