// Task results (task.h).
#include "strokelab/jobs/task.h"

namespace strokelab::jobs {

nlohmann::json ResultRecords::RowAt(size_t row) const {
  nlohmann::json object = nlohmann::json::object();
  const size_t first = row * columns.size();
  for (size_t c = 0; c < columns.size(); ++c) object[columns[c]] = cells.at(first + c);
  return object;
}

size_t TaskResult::RowCount() const {
  size_t count = rows.size();
  for (const ResultRecords& table : records) count += table.size();
  return count;
}

std::vector<ResultRow> TaskResult::AllRows() const {
  std::vector<ResultRow> all = rows;
  for (const ResultRecords& table : records)
    for (size_t r = 0; r < table.size(); ++r) all.push_back({table.table, table.RowAt(r)});
  return all;
}

}  // namespace strokelab::jobs
