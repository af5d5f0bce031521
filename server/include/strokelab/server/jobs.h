// The bridge between the job store and core: a job is split into tasks, and one task is run.
//
// A sweep becomes one task per amplitude row (continuation in frequency: steady states and jump
// intervals) and one task per chunk of frequency columns (saturation thresholds); a simulate job is
// one task. Task specs carry the full model, so that a task's key (a hash of its spec and the code
// version) identifies its result whatever job it came from.
#pragma once

#include <atomic>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "strokelab/server/store.h"
#include "strokelab/sweep.h"

namespace strokelab::server {

// Bumped whenever a change to core alters results, so that cached results are not reused.
inline constexpr const char* kCodeVersion = "strokelab-0.3.0";

// Splits a validated job into tasks (throws InputError naming the field for semantic errors).
std::vector<TaskSpec> PlanTasks(const nlohmann::json& job);

// Runs one task; `cancel` is polled between points and ends the task with strokelab::Cancelled.
std::vector<ResultRow> RunTask(const nlohmann::json& task_spec, const std::atomic<bool>* cancel = nullptr);

// A sweep point as a "points" result row (the stored and served form).
nlohmann::json SweepPointJson(const SweepPoint& point);

// 64-bit FNV-1a of the text, as 16 hex digits (a content key, not a security hash).
std::string ContentKey(const std::string& text);

}  // namespace strokelab::server
