// Parsing and checking what a request carries (request_params.h).
#include "request_params.h"

#include <charconv>
#include <cmath>

#include "strokelab/base/errors.h"
#include "strokelab/base/parse.h"
#include "strokelab/base/json_parse.h"

namespace strokelab::server::internal {

using nlohmann::json;

int64_t ParseId(const std::string& text) {
  try {
    return std::stoll(text);
  } catch (...) {
    throw HttpError{404, "unknown_job", "no job " + text, ""};
  }
}

double QueryNumber(const httplib::Request& req, const std::string& name) {
  double value = 0;
  try {
    value = ParseNumber(req.get_param_value(name), name);
  } catch (const InputError& e) {
    throw HttpError{400, "bad_query", e.bare_message(), name};
  }
  if (!std::isfinite(value)) throw HttpError{400, "bad_query", "must be a finite number", name};
  return value;
}

int64_t QueryInteger(const httplib::Request& req, const std::string& name) {
  const std::string text = req.get_param_value(name);
  int64_t value = -1;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || value < 0)
    throw HttpError{400, "bad_query", "expected a whole number >= 0 (as returned by the service)", name};
  return value;
}

bool WantsSvg(const httplib::Request& req) {
  if (!req.has_param("format")) return false;
  const std::string format = req.get_param_value("format");
  if (format != "json" && format != "svg") throw HttpError{400, "bad_query", "must be json or svg", "format"};
  return format == "svg";
}

bool WantsCsv(const httplib::Request& req) {
  if (!req.has_param("format")) return req.get_header_value("Accept").find("text/csv") != std::string::npos;
  const std::string format = req.get_param_value("format");
  if (format != "json" && format != "csv") throw HttpError{400, "bad_query", "must be json or csv", "format"};
  return format == "csv";
}

namespace {

// What a refused request sent, in words: curl -d's default type is the usual mistake.
std::string SentTypeWords(const std::string& type) {
  if (type.empty()) return "no Content-Type";
  if (type.rfind("application/x-www-form-urlencoded", 0) == 0)
    return "Content-Type '" + type + "', which curl sends for -d and --data-binary unless told otherwise";
  return "Content-Type '" + type + "'";
}

}  // namespace

std::string UnsupportedJsonBodyMessage(const std::string& type) {
  return "a JSON body needs the header 'Content-Type: application/json' (with curl: -H 'Content-Type: "
         "application/json'); this request had " + SentTypeWords(type);
}

std::string UnsupportedCampaignMessage(const std::string& type) {
  return "a campaign upload needs the header 'Content-Type: application/x-tar' for a tar archive (ustar or pax) "
         "or 'Content-Type: application/zip' for a zip archive (with curl: -H 'Content-Type: application/x-tar' "
         "--data-binary @campaign.tar); this request had " + SentTypeWords(type);
}

json JsonBody(const httplib::Request& req) {
  const std::string type = req.get_header_value("Content-Type");
  if (type.substr(0, type.find(';')) != "application/json")
    throw HttpError{415, "unsupported_media_type", UnsupportedJsonBodyMessage(type), ""};
  try {
    return ParseJson(req.body);
  } catch (const json::exception& e) {
    throw HttpError{400, "bad_json", std::string("request body is not valid JSON: ") + e.what(), ""};
  }
}

TaskLease LeaseOf(const httplib::Request& req, const json& body) {
  TaskLease lease;
  const std::string id = req.matches[1];
  const auto [end, ec] = std::from_chars(id.data(), id.data() + id.size(), lease.task_id);
  if (ec != std::errc() || end != id.data() + id.size()) throw HttpError{404, "unknown_task", "no task " + id, ""};
  lease.job_id = BodyField<int64_t>(body, "job_id", "/job_id");
  lease.lease_token = BodyField<std::string>(body, "lease_token", "/lease_token");
  return lease;
}

void CheckBodyField(const json& object, const std::string& key, json::value_t type, const std::string& pointer) {
  if (!object.is_object()) throw HttpError{400, "bad_request", "expected a JSON object", pointer.substr(0, pointer.rfind('/'))};
  const auto it = object.find(key);
  if (it == object.end()) throw HttpError{400, "bad_request", "is required", pointer};
  if (it->type() != type)
    throw HttpError{400, "bad_request", type == json::value_t::string ? "expected a string" : "expected an object", pointer};
}

int QueryLimit(const httplib::Request& req, int fallback, int maximum) {
  if (!req.has_param("limit")) return fallback;
  const double limit = QueryNumber(req, "limit");
  if (limit < 1 || limit > maximum || limit != std::floor(limit))
    throw HttpError{400, "bad_query", "must be an integer from 1 to " + std::to_string(maximum), "limit"};
  return static_cast<int>(limit);
}

}  // namespace strokelab::server::internal
