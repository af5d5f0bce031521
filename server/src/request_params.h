// What a request carries, parsed and checked: ids, query parameters, a JSON body and its members, a
// worker's lease. Each refusal is an HttpError naming the parameter (or the body's JSON pointer).
// Internal to the service.
#pragma once

#include <httplib.h>

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <type_traits>

#include "http_reply.h"
#include "strokelab/server/store.h"

namespace strokelab::server::internal {

// A job id of a path (404 when it is not one).
int64_t ParseId(const std::string& text);
// A finite number: an infinite filter or limit is a client's mistake, never a useful query.
double QueryNumber(const httplib::Request& req, const std::string& name);
// A cursor or job id bound: digits only (a double would round cursors above 2^53).
int64_t QueryInteger(const httplib::Request& req, const std::string& name);
// ?format= of the picture endpoints: absent or "json" (JSON), "svg" (a picture).
bool WantsSvg(const httplib::Request& req);
// Whether a table endpoint answers in CSV: ?format=csv, or Accept: text/csv without ?format=
// (?format= is "json" or "csv"; anything else is 400 naming format).
bool WantsCsv(const httplib::Request& req);
// A JSON request body: sent as application/json (parameters such as charset allowed), and parsed.
// The one place where a json::exception is the client's (400 bad_json).
nlohmann::json JsonBody(const httplib::Request& req);
// The 415 messages: the exact header to add (and its curl option), and what the request had.
std::string UnsupportedJsonBodyMessage(const std::string& content_type);
std::string UnsupportedCampaignMessage(const std::string& content_type);
// ?limit=, an integer from 1 to `maximum` (`fallback` when absent).
int QueryLimit(const httplib::Request& req, int fallback, int maximum);
// The lease a worker's complete or fail request names.
TaskLease LeaseOf(const httplib::Request& req, const nlohmann::json& body);

// Checks that `object` is an object with a member `key` of JSON type `type` (400 naming `pointer`
// otherwise), without copying it.
void CheckBodyField(const nlohmann::json& object, const std::string& key, nlohmann::json::value_t type,
                    const std::string& pointer);

// A member of a worker's request body with the JSON type of T; 400 naming it (a JSON pointer)
// when it is missing or of another type.
template <typename T>
T BodyField(const nlohmann::json& object, const std::string& key, const std::string& pointer) {
  if (!object.is_object()) throw HttpError{400, "bad_request", "expected a JSON object", pointer.substr(0, pointer.rfind('/'))};
  const auto it = object.find(key);
  if (it == object.end()) throw HttpError{400, "bad_request", "is required", pointer};
  static_assert(std::is_same_v<T, std::string> || std::is_same_v<T, int64_t> || std::is_same_v<T, bool> ||
                std::is_same_v<T, nlohmann::json>);
  if constexpr (std::is_same_v<T, std::string>) {
    if (!it->is_string()) throw HttpError{400, "bad_request", "expected a string", pointer};
  } else if constexpr (std::is_same_v<T, bool>) {
    if (!it->is_boolean()) throw HttpError{400, "bad_request", "expected true or false", pointer};
  } else if constexpr (std::is_same_v<T, int64_t>) {
    if (!it->is_number_integer()) throw HttpError{400, "bad_request", "expected an integer", pointer};
  } else if (!it->is_object()) {
    throw HttpError{400, "bad_request", "expected an object", pointer};
  }
  return it->template get<T>();
}

}  // namespace strokelab::server::internal
