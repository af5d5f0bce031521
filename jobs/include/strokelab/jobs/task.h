// A task, the unit of work that a job is split into (jobs.h), and the rows it produces.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace strokelab::jobs {

struct TaskSpec {
  std::string key;                 // content hash: identical work has the same key
  nlohmann::json spec;             // what the worker needs to run it
};

// One result row of a task: a table name ("points", "thresholds", "jumps", "records") and its
// values as a JSON object. Rows are stored as JSON text with their task and row index, which make
// them unique: (job, task, row).
struct ResultRow {
  std::string table;
  nlohmann::json values;
};

}  // namespace strokelab::jobs
