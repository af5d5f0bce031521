// Malformed HTTP requests for the service, generated (bad_input_cases.cc): each with the status and
// the error object ({"error": {"code", "message", "field"}}) it must get. Used by bad_input_test.cc.
#pragma once

#include <httplib.h>

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace strokelab::testing {

// The bearer tokens of the server under test, one per role (server/src/auth.cc).
struct Tokens {
  std::string submit, read, worker;
};

struct BadRequest {
  std::string group;  // "spec", "body", "content-type", "size", "upload", "route", "query", "auth", "worker"
  std::string name;   // what is wrong, for failure messages
  httplib::Request request;
  int status = 0;                    // expected exactly; 0: any 4xx
  std::string code;                  // expected error code; "": any
  std::optional<std::string> field;  // expected error field ("": absent); nullopt: not checked
};

// Existing jobs the route and query cases refer to: a queued sweep and a queued simulate job.
struct KnownJobs {
  int64_t sweep = 0, simulate = 0;
};

// A valid sweep and a valid simulate job spec, small enough to plan in microseconds.
nlohmann::json ValidSweep();
nlohmann::json ValidSimulate();

std::vector<BadRequest> GenerateBadRequests(const Tokens& tokens, const KnownJobs& jobs);

}  // namespace strokelab::testing
