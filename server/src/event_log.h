// The service's structured log: one JSON object per line on stderr, for every HTTP request and for
// every job state change, so that a log shipper can parse each line on its own.
//
//   {"event":"request","time":"2024-05-01T12:00:00.123Z","ts_ms":...,"method":"GET","path":"/v1/jobs/3",
//    "status":200,"duration_ms":0.41,"remote":"127.0.0.1:50412"}
//   {"event":"job","time":...,"ts_ms":...,"job_id":3,"kind":"sweep","status":"succeeded",
//    "tasks_done":40,"tasks_total":40,"points":1600,"reason":"all 40 tasks done"}
//
// What is never logged: request headers (the bearer token travels there), query strings and bodies.
// Bytes that are not UTF-8 (a client may send any path) are written as U+FFFD, never dropped with
// the line. Internal to the service.
#pragma once

#include <cstdint>
#include <cstdio>
#include <ctime>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "strokelab/server/store.h"

namespace strokelab::server::internal {

// "2024-05-01T12:00:00.123Z" (UTC) for unix epoch milliseconds.
inline std::string IsoTime(int64_t ms) {
  const std::time_t seconds = static_cast<std::time_t>(ms / 1000);
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  char text[40];
  const size_t n = std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%S", &utc);
  std::snprintf(text + n, sizeof text - n, ".%03dZ", static_cast<int>(ms % 1000));
  return text;
}

// One line, written with one call so that lines of concurrent threads do not interleave.
inline void WriteLogLine(const nlohmann::json& line) {
  const std::string text = line.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
  std::fwrite(text.data(), 1, text.size(), stderr);
}

// duration_ms is null for requests refused before routing (malformed request line, body over the
// limit), where no start time was taken.
inline nlohmann::json RequestLogLine(int64_t now_ms, const std::string& method, const std::string& path, int status,
                                     std::optional<double> duration_ms, const std::string& remote_addr,
                                     int remote_port) {
  return {{"event", "request"},
          {"time", IsoTime(now_ms)},
          {"ts_ms", now_ms},
          {"method", method},
          {"path", path},
          {"status", status},
          {"duration_ms", duration_ms ? nlohmann::json(*duration_ms) : nlohmann::json(nullptr)},
          {"remote", remote_addr + ":" + std::to_string(remote_port)}};
}

inline nlohmann::json JobEventLogLine(const JobEvent& e) {
  return {{"event", "job"},          {"time", IsoTime(e.at_ms)},   {"ts_ms", e.at_ms},
          {"job_id", e.job_id},      {"kind", e.kind},             {"status", ToString(e.status)},
          {"tasks_done", e.tasks_done}, {"tasks_total", e.tasks_total}, {"points", e.points},
          {"reason", e.reason}};
}

}  // namespace strokelab::server::internal
