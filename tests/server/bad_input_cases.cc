// The generated malformed requests of bad_input_cases.h. Job specs are mutated systematically: every
// field of two valid specs is given each wrong type, each bound is crossed, every object gets an
// unknown field, every required field is removed; the body as a whole is truncated at every tenth of
// its length, nested deeply, made huge, made invalid UTF-8. Routes, query parameters and
// authorisation are crossed with the endpoints they apply to.
#include "bad_input_cases.h"
#include "zip_writer.h"

#include <functional>
#include <string>
#include <utility>
#include <vector>

namespace strokelab::testing {
namespace {

using nlohmann::json;

constexpr size_t kMaxBodyBytes = 1 << 20;  // the server's default --max-body-bytes

httplib::Headers Auth(const std::string& token) { return {{"Authorization", "Bearer " + token}}; }

httplib::Request MakeRequest(const std::string& method, const std::string& path, const httplib::Headers& headers,
                             const std::string& body = "", const std::string& content_type = "application/json") {
  httplib::Request r;
  r.method = method;
  r.path = path;
  r.headers = headers;
  r.body = body;
  if (!body.empty() && !content_type.empty()) r.headers.emplace("Content-Type", content_type);
  return r;
}

// Every (pointer, value) of a JSON document, parents before children.
void Walk(const json& value, const std::string& pointer, const std::function<void(const std::string&, const json&)>& f) {
  f(pointer, value);
  if (value.is_object())
    for (const auto& [key, child] : value.items()) Walk(child, pointer + "/" + key, f);
}

// Values of other JSON types than `value`'s, none of which the schema allows where `value` is.
std::vector<std::pair<std::string, json>> WrongTypes(const json& value) {
  std::vector<std::pair<std::string, json>> out;
  if (!value.is_string()) out.push_back({"a string", "12"});
  if (!value.is_number()) out.push_back({"a number", 12});
  if (!value.is_boolean()) out.push_back({"a boolean", true});
  if (!value.is_array()) out.push_back({"an array", json::array({1, 2})});
  if (!value.is_object()) out.push_back({"an object", json::object()});
  out.push_back({"null", nullptr});
  return out;
}

// Bounds of the numeric fields that have them (schema/job.schema.json): values just outside.
std::vector<json> OutOfRange(const std::string& pointer) {
  const auto ends_with = [&](const std::string& tail) {
    return pointer.size() >= tail.size() && pointer.compare(pointer.size() - tail.size(), tail.size(), tail) == 0;
  };
  if (ends_with("/points")) return {0, -1, 2001, 2.5, 1e300};
  if (pointer.find("frequency_hz") != std::string::npos) return {0.0005, -5, 10001, 1e308, -1e308};
  if (pointer.find("amplitude_v") != std::string::npos) return {0, -0.1, 1000.5, 1e308};
  if (ends_with("/duration_s")) return {0, -1, 61};
  if (ends_with("/sample_rate_hz")) return {0, -1000, 2e6};
  return {};
}

struct SpecCases {
  std::vector<BadRequest>& out;
  const Tokens& tokens;

  void Add(const std::string& name, const json& spec, const std::string& code, std::optional<std::string> field) {
    BadRequest b{"spec", name, MakeRequest("POST", "/v1/jobs", Auth(tokens.submit), spec.dump()), 400, code,
                 std::move(field)};
    out.push_back(std::move(b));
  }

  void Mutate(const json& base, const std::string& label, const std::vector<std::string>& required) {
    Walk(base, "", [&](const std::string& pointer, const json& value) {
      if (pointer.empty()) return;
      const json::json_pointer at(pointer);
      // The model may be a preset name or an object: a string or an object there is no type error.
      const bool model = pointer == "/model";
      for (const auto& [type, wrong] : WrongTypes(value)) {
        if (model && (wrong.is_string() || wrong.is_object())) continue;
        json spec = base;
        spec[at] = wrong;
        Add(label + pointer + " as " + type, spec, "invalid_job", pointer == "/kind" ? "/kind" : pointer);
      }
      for (const json& bad : OutOfRange(pointer)) {
        json spec = base;
        spec[at] = bad;
        Add(label + pointer + " = " + bad.dump(), spec, "invalid_job", pointer);
      }
      if (value.is_string() && pointer != "/name") {  // enums: a value none of them has
        json spec = base;
        spec[at] = "bogus";
        Add(label + pointer + " = \"bogus\"", spec, "invalid_job", pointer);
      }
      if (value.is_object()) {
        json spec = base;
        spec[at]["bogus_field"] = 1;
        Add(label + pointer + " with an unknown field", spec, "invalid_job", pointer + "/bogus_field");
      }
    });
    json extra = base;
    extra["bogus_field"] = 1;
    Add(label + " with an unknown top-level field", extra, "invalid_job", "/bogus_field");
    for (const std::string& pointer : required) {
      json spec = base;
      const json::json_pointer at(pointer);
      spec[at.parent_pointer()].erase(at.back());
      Add(label + pointer + " removed", spec, "invalid_job", pointer);
    }
  }
};

// Whole-body defects of POST /v1/jobs: not JSON, not an object, nested, huge, not UTF-8.
void BodyCases(std::vector<BadRequest>& out, const Tokens& tokens) {
  const auto add = [&](const std::string& name, const std::string& body, const std::string& code) {
    out.push_back({"body", name, MakeRequest("POST", "/v1/jobs", Auth(tokens.submit), body), 400, code, std::nullopt});
  };
  const std::string valid = ValidSweep().dump();
  for (int tenth = 1; tenth < 10; ++tenth)
    add("truncated at " + std::to_string(tenth * 10) + "%", valid.substr(0, valid.size() * tenth / 10), "bad_json");
  add("truncated by one byte", valid.substr(0, valid.size() - 1), "bad_json");
  add("trailing garbage", valid + "}", "bad_json");
  add("a comment", "/* job */" + valid, "bad_json");
  add("bare NaN", R"({"kind":"simulate","model":"paper","frequency_hz":NaN,"amplitude_v":0.1})", "bad_json");
  add("bare Infinity", R"({"kind":"simulate","model":"paper","frequency_hz":Infinity,"amplitude_v":0.1})", "bad_json");
  add("single quotes", "{'kind': 'sweep'}", "bad_json");
  add("whitespace only", " \n\t ", "bad_json");
  for (const char* scalar : {"[]", "1", "\"sweep\"", "null", "true", "[{\"kind\":\"sweep\"}]"})
    add(std::string("top level ") + scalar, scalar, "invalid_job");
  add("no kind", "{}", "invalid_job");
  add("kind fit (planned, unknown)", R"({"kind":"fit"})", "invalid_job");
  // Deep nesting where a string belongs, and as the whole body: at most 64 levels are parsed
  // (ParseJson; copying or dumping a value recurses once per level).
  for (int depth : {63, 64, 65, 10000, 200000}) {
    const std::string deep = std::string(depth, '[') + std::string(depth, ']');
    if (deep.size() < kMaxBodyBytes / 2) {
      add("name nested " + std::to_string(depth) + " deep",
          valid.substr(0, valid.size() - 1) + ",\"name2\":" + deep + "}", depth + 1 > 64 ? "bad_json" : "invalid_job");
    }
    add("body nested " + std::to_string(depth) + " deep", deep, depth > 64 ? "bad_json" : "invalid_job");
    add("objects nested " + std::to_string(depth) + " deep, unclosed", std::string(depth, '{'), "bad_json");
  }
  // Huge arrays and numbers.
  std::string array = "[";
  for (int i = 0; i < 100000; ++i) array += i ? ",0" : "0";
  array += "]";
  add("grid a 100,000-element array", R"({"kind":"sweep","model":"paper","grid":)" + array + "}", "invalid_job");
  add("points with 400 digits", R"({"kind":"sweep","model":"paper","grid":{"frequency_hz":{"from":5,"to":6,"points":)" +
                                    std::string(400, '9') + R"(},"amplitude_v":{"from":0.1,"to":0.2,"points":2}}})",
      "bad_json");  // nlohmann refuses numbers beyond double as it parses
  add("frequency 1e999", R"({"kind":"simulate","model":"paper","frequency_hz":1e999,"amplitude_v":0.1})", "");
  add("a 500 kB name", R"({"kind":"sweep","model":"paper","name":")" + std::string(500000, 'x') + "\"}", "invalid_job");
  // Invalid UTF-8 and escapes.
  for (const auto& [what, bytes] : std::vector<std::pair<std::string, std::string>>{
           {"byte 0xFF", "\xff"}, {"overlong '/'", "\xc0\xaf"}, {"cut 3-byte sequence", "\xe2\x82"},
           {"UTF-16 surrogate as UTF-8", "\xed\xa0\x80"}, {"lone surrogate escape", "\\ud800"},
           {"bad escape", "\\x41"}, {"raw control character", std::string("a\x01", 2)}, {"NUL byte", std::string("a\0b", 3)}})
    add("name with " + what, R"({"kind":"sweep","model":"paper","name":")" + bytes + "\"}", "bad_json");
  add("key with byte 0xFF", "{\"kind\":\"sweep\",\"\xff\":1}", "bad_json");
}

void ContentTypeAndSizeCases(std::vector<BadRequest>& out, const Tokens& tokens) {
  const std::string valid = ValidSimulate().dump();
  for (const char* type : {"text/plain", "application/x-www-form-urlencoded", "multipart/form-data; boundary=x",
                           "application/xml", "application/jsonp", "json", "", "*/*"}) {
    httplib::Request r = MakeRequest("POST", "/v1/jobs", Auth(tokens.submit), valid, type);
    out.push_back({"content-type", std::string("POST /v1/jobs as '") + type + "'", std::move(r), 415,
                   "unsupported_media_type", ""});
  }
  out.push_back({"content-type", "task completion as text/plain",
                 MakeRequest("POST", "/v1/tasks/1/complete", Auth(tokens.worker),
                             R"({"job_id":1,"lease_token":"x","rows":[]})", "text/plain"),
                 415, "unsupported_media_type", ""});
  // The header block is bounded (server/src/http_gate.h): 400,000 headers were read and kept.
  httplib::Headers many = Auth(tokens.read);
  for (int i = 0; i < 150; ++i) many.emplace("X-Filler-" + std::to_string(i), "1");
  out.push_back({"size", "150 header lines", MakeRequest("GET", "/v1/jobs", many), 431, "headers_too_large", ""});
  out.push_back({"size", "a 40 kB header", MakeRequest("GET", "/v1/jobs", {{"X-Large", std::string(40000, 'a')}}), 431,
                 "headers_too_large", ""});
  for (size_t bytes : {kMaxBodyBytes + 1, 2 * kMaxBodyBytes}) {
    const std::string body = R"({"kind":"sweep","name":")" + std::string(bytes, 'x') + "\"}";
    out.push_back({"size", "a " + std::to_string(body.size()) + "-byte body",
                   MakeRequest("POST", "/v1/jobs", Auth(tokens.submit), body), 413, "body_too_large", ""});
  }
}

void RouteCases(std::vector<BadRequest>& out, const Tokens& tokens, const KnownJobs& jobs) {
  const std::string j = std::to_string(jobs.sweep);
  const auto add = [&](const std::string& method, const std::string& path, int status, const std::string& code) {
    out.push_back({"route", method + " " + path.substr(0, 80), MakeRequest(method, path, Auth(tokens.submit)), status,
                   code, std::nullopt});
  };
  // A known path with a method it does not take: 405 (with an Allow header, service_test); methods
  // httplib does not parse at all are a 400.
  for (const char* method : {"PUT", "PATCH", "DELETE"}) add(method, "/v1/jobs", 405, "method_not_allowed");
  for (const char* method : {"TRACE", "FOO"}) add(method, "/v1/jobs", 0, "");
  for (const char* method : {"PUT", "PATCH", "POST"}) add(method, "/v1/jobs/" + j, 405, "method_not_allowed");
  for (const char* path : {"/v1/job", "/v2/jobs", "/v1/jobs/", "/v1/jobs/abc", "/v1/jobs/-1", "/v1/jobs/1.5",
                           "/v1/jobs/0x10", "/v1/jobs/%00", "/v1/jobs/1%2F2", "//v1//jobs", "/v1/jobs/../../etc/passwd",
                           "/v1/tasks/abc/complete", "/v1/healthz", "/metrics/x"})
    add("GET", path, 404, "");
  add("GET", "/v1/" + std::string(8000, 'a'), 414, "uri_too_long");  // before any route pattern sees it
  // Ids: unknown, zero, beyond int64, each on every job endpoint.
  for (const std::string id : {"999999", "0", "99999999999999999999999"}) {
    for (const char* tail : {"", "/points", "/saturation-map", "/frf?amplitude_v=0.1"})
      add("GET", "/v1/jobs/" + id + tail, 404, "unknown_job");
    add("DELETE", "/v1/jobs/" + id, 404, "unknown_job");
  }
  for (const std::string task : {"99999999999999999999999", "18446744073709551616"}) {
    for (const char* verb : {"complete", "fail"})
      out.push_back({"route", "task id " + task + " " + verb,
                     MakeRequest("POST", "/v1/tasks/" + task + "/" + verb, Auth(tokens.worker),
                                 R"({"job_id":1,"lease_token":"x","rows":[]})"),
                     404, "unknown_task", ""});
  }
}

void QueryCases(std::vector<BadRequest>& out, const Tokens& tokens, const KnownJobs& jobs) {
  const std::string sweep = "/v1/jobs/" + std::to_string(jobs.sweep);
  const std::string simulate = "/v1/jobs/" + std::to_string(jobs.simulate);
  const auto add = [&](const std::string& path, const std::string& code, std::optional<std::string> field) {
    out.push_back({"query", "GET " + path, MakeRequest("GET", path, Auth(tokens.read)), 400, code, std::move(field)});
  };
  const std::vector<std::string> not_numbers = {"abc", "", "nan", "NaN", "inf", "-inf", "1e999", "0x10", "1,5",
                                                "%FF%FE", "1%00"};
  for (const std::string& bad : not_numbers) {
    add(sweep + "/points?frequency_min_hz=" + bad, "bad_query", "frequency_min_hz");
    add(sweep + "/points?amplitude_v=" + bad, "bad_query", "amplitude_v");
    add(sweep + "/points?cursor=" + bad, "bad_query", "cursor");
    add("/v1/jobs?before=" + bad, "bad_query", "before");
  }
  add(sweep + "/points?frequency_max_hz=x", "bad_query", "frequency_max_hz");
  add(sweep + "/frf?amplitude_v=x", "bad_query", "amplitude_v");
  for (const std::string limit : {"0", "-1", "10001", "1.5", "abc", "1e400", "inf"})
    add(sweep + "/points?limit=" + limit, "bad_query", "limit");
  for (const std::string limit : {"0", "501", "2.5", "x"}) add("/v1/jobs?limit=" + limit, "bad_query", "limit");
  for (const std::string cursor : {"-1", "1.5", "1e30", "99999999999999999999"})
    add(sweep + "/points?cursor=" + cursor, "bad_query", "cursor");
  add("/v1/jobs?before=-5", "bad_query", "before");
  for (const std::string branch : {"sideways", "UP", "", "up,down", "%FF"})
    add(sweep + "/points?branch=" + branch, "bad_query", "branch");
  for (const std::string format : {"png", "SVG", "", "svg%00"}) {
    add(sweep + "/saturation-map?format=" + format, "bad_query", "format");
    add(sweep + "/frf?amplitude_v=0.1&format=" + format, "bad_query", "format");
  }
  for (const std::string format : {"svg", "CSV", "", "tsv"}) {
    add(sweep + "/points?format=" + format, "bad_query", "format");
    add(sweep + "/thresholds?format=" + format, "bad_query", "format");
  }
  add(simulate + "/jumps?format=csv", "not_a_sweep", "");
  add(sweep + "/frf?format=svg&branch=sideways", "bad_query", "branch");
  add(sweep + "/frf", "bad_query", "amplitude_v");
  add(simulate + "/saturation-map", "not_a_sweep", "");
  add(simulate + "/frf?amplitude_v=0.1", "not_a_sweep", "");
  add(simulate + "/frf?format=svg", "not_a_sweep", "");
}

void AuthCases(std::vector<BadRequest>& out, const Tokens& tokens, const KnownJobs& jobs) {
  const std::string j = "/v1/jobs/" + std::to_string(jobs.sweep);
  const std::string job = ValidSimulate().dump();
  const std::string completion = R"({"job_id":1,"lease_token":"x","rows":[]})";
  struct Endpoint {
    std::string method, path, body;
  };
  const std::vector<Endpoint> endpoints = {
      {"GET", "/v1/jobs", ""},          {"GET", j, ""},          {"POST", "/v1/jobs", job},
      {"DELETE", j, ""},                {"GET", j + "/points", ""}, {"GET", j + "/saturation-map", ""},
      {"GET", j + "/frf?amplitude_v=0.1", ""}, {"GET", "/metrics", ""}, {"POST", "/v1/tasks/lease", R"({"worker":"w"})"},
      {"POST", "/v1/tasks/1/complete", completion}, {"POST", "/v1/tasks/1/fail", completion}};
  const std::vector<std::pair<std::string, std::string>> bad_headers = {
      {"no header", ""},
      {"'Bearer' alone", "Bearer"},
      {"'Bearer ' and nothing", "Bearer "},
      {"unknown token", "Bearer 0123456789abcdef0123"},
      {"Basic scheme", "Basic dXNlcjpwYXNzd29yZA=="},
      {"lower-case scheme", "bearer " + tokens.submit},
      {"two spaces", "Bearer  " + tokens.submit},
      {"token with a suffix", "Bearer " + tokens.submit + "x"},
      {"token prefix", "Bearer " + tokens.submit.substr(0, tokens.submit.size() - 1)},
      {"token twice", "Bearer " + tokens.submit + ", Bearer " + tokens.submit},
      {"4 kB token", "Bearer " + std::string(4096, 'a')},
      {"non-ASCII token", "Bearer \xc3\xa9\xff" + tokens.submit}};
  for (const Endpoint& e : endpoints) {
    for (const auto& [what, header] : bad_headers) {
      httplib::Headers headers;
      if (!header.empty()) headers.emplace("Authorization", header);
      out.push_back({"auth", e.method + " " + e.path + ": " + what, MakeRequest(e.method, e.path, headers, e.body), 401,
                     "unauthorized", ""});
    }
    // A header line over cpp-httplib's 8 kB is a malformed request; the connection must close, or
    // the unread body would be parsed as the next request (the non-ASCII case after it checks).
    out.push_back({"auth", e.method + " " + e.path + ": 9 kB header line",
                   MakeRequest(e.method, e.path, {{"Authorization", "Bearer " + std::string(9000, 'a')}}, e.body), 400,
                   "bad_request", ""});
    out.push_back({"auth", e.method + " " + e.path + ": non-ASCII token after a malformed request",
                   MakeRequest(e.method, e.path, {{"Authorization", "Bearer \xc3\xa9" + tokens.submit}}, e.body), 401,
                   "unauthorized", ""});
  }
  // Tokens of the wrong role (auth.cc: read < worker < submit; workers may not submit or cancel).
  const auto forbidden = [&](const Endpoint& e, const std::string& token, const std::string& role) {
    out.push_back({"auth", e.method + " " + e.path + " with a " + role + " token",
                   MakeRequest(e.method, e.path, Auth(token), e.body), 403, "forbidden", ""});
  };
  // Worker tokens lease and complete tasks and nothing else; no other token does (issue 15, item 5).
  for (const Endpoint& e : endpoints) {
    const bool task = e.path.rfind("/v1/tasks", 0) == 0;
    if (e.method != "GET") forbidden(e, tokens.read, "read");
    if (!task) forbidden(e, tokens.worker, "worker");
    if (task) forbidden(e, tokens.submit, "submit");
  }
}

// Campaign uploads that are zip bombs as a whole (issue 15: 250 members of 1 MiB each, each under the
// per-member floor of the ratio rule, in a 638 KB zip): refused on the central directory.
void UploadCases(std::vector<BadRequest>& out, const Tokens& tokens) {
  for (size_t members : {size_t{101}, size_t{250}}) {
    std::vector<server::zip_writer::ZipEntry> entries;
    const std::string zeros = server::zip_writer::DeflatedZeros(1);
    for (size_t i = 0; i < members; ++i) {
      server::zip_writer::ZipEntry e("c/rec_" + std::to_string(i) + ".csv", "");
      e.packed = zeros;
      e.size = 1u << 20;
      e.crc = 0xB0B0C0DE;  // never reached: refused before any member is inflated
      entries.push_back(std::move(e));
    }
    out.push_back({"upload", std::to_string(members) + " members of 1 MiB zeros in one zip",
                   MakeRequest("POST", "/v1/campaigns", Auth(tokens.submit), server::zip_writer::Zip(entries), "application/zip"),
                   400, "bad_archive", "archive"});
  }
}

// Worker endpoints with bodies that are not what a worker sends; each names the field.
void WorkerCases(std::vector<BadRequest>& out, const Tokens& tokens) {
  const auto add = [&](const std::string& verb, const std::string& body, int status, const std::string& code,
                       std::optional<std::string> field) {
    out.push_back({"worker", verb + " " + body.substr(0, 60),
                   MakeRequest("POST", "/v1/tasks/1/" + verb, Auth(tokens.worker), body), status, code,
                   std::move(field)});
  };
  for (const char* verb : {"complete", "fail"}) {
    add(verb, "{", 400, "bad_json", "");
    add(verb, "[]", 400, "bad_request", "");
    add(verb, R"({"lease_token":"x","rows":[]})", 400, "bad_request", "/job_id");
    add(verb, R"({"job_id":"1","lease_token":"x","rows":[]})", 400, "bad_request", "/job_id");
    add(verb, R"({"job_id":1,"rows":[]})", 400, "bad_request", "/lease_token");
    add(verb, R"({"job_id":1,"lease_token":7,"rows":[]})", 400, "bad_request", "/lease_token");
  }
  add("fail", R"({"job_id":1,"lease_token":"x","error":42})", 400, "bad_request", "/error");
  add("complete", R"({"job_id":1,"lease_token":"x"})", 400, "bad_request", "/rows");
  add("complete", R"({"job_id":1,"lease_token":"x","rows":{}})", 400, "bad_request", "/rows");
  add("complete", R"({"job_id":1,"lease_token":"x","rows":[{"values":{}}]})", 400, "bad_request", "/rows/0/table");
  add("complete", R"({"job_id":1,"lease_token":"x","rows":[{"table":"points"}]})", 400, "bad_request",
      "/rows/0/values");
  add("complete", R"({"job_id":1,"lease_token":"x","rows":[{"table":"points","values":{}},{"table":3,"values":{}}]})",
      400, "bad_request", "/rows/1/table");
  add("complete", R"({"job_id":1,"lease_token":"not-held","rows":[]})", 409, "lease_lost", "");
  // Values nested deeply in a completion: refused as they are parsed, lease or not (200,000 levels
  // crashed the server when the rows were copied before the lease was checked).
  for (int depth : {65, 200000}) {
    const std::string deep = std::string(depth, '[') + std::string(depth, ']');
    add("complete", R"({"job_id":1,"lease_token":"bogus","rows":[{"table":"points","values":{"x":)" + deep + "}}]}",
        400, "bad_json", "");
  }
  // Issue 15: a spent work budget is reported as such ("budget": true), a boolean.
  add("fail", R"({"job_id":1,"lease_token":"x","error":"spent","budget":"yes"})", 400, "bad_request", "/budget");
  for (const char* body : {"[]", "{\"worker\":5}", "{\"worker\":", "\"w\""})
    out.push_back({"worker", std::string("lease ") + body,
                   MakeRequest("POST", "/v1/tasks/lease", Auth(tokens.worker), body), 400, "", std::nullopt});
}

}  // namespace

json ValidSweep() {
  return {{"kind", "sweep"},
          {"name", "bad-input base"},
          {"model", "paper"},
          {"thresholds", false},
          {"grid",
           {{"frequency_hz", {{"from", 5}, {"to", 50}, {"points", 3}, {"spacing", "linear"}}},
            {"amplitude_v", {{"from", 0.1}, {"to", 0.6}, {"points", 2}}}}}};
}

json ValidSimulate() {
  return {{"kind", "simulate"},    {"model", {{"preset", "paper"}, {"contact_law", "linear"}}},
          {"frequency_hz", 10},    {"amplitude_v", 0.2},
          {"duration_s", 1},       {"sample_rate_hz", 1000},
          {"method", "exact"}};
}

std::vector<BadRequest> GenerateBadRequests(const Tokens& tokens, const KnownJobs& jobs) {
  std::vector<BadRequest> out;
  SpecCases specs{out, tokens};
  specs.Mutate(ValidSweep(), "sweep",
               {"/model", "/grid", "/grid/frequency_hz", "/grid/frequency_hz/points", "/grid/frequency_hz/from",
                "/grid/frequency_hz/to", "/grid/amplitude_v", "/grid/amplitude_v/from", "/grid/amplitude_v/to",
                "/grid/amplitude_v/points"});
  specs.Mutate(ValidSimulate(), "simulate", {"/model", "/frequency_hz", "/amplitude_v"});
  // Issue 15: models beyond the physical bounds (ModelBounds) hung the workers for good.
  for (const auto& [key, value] : std::vector<std::pair<std::string, double>>{
           {"k_s", 1e40}, {"m_p", 1e-300}, {"m_p", 1e4}, {"c_s", 1e12}, {"k3", 1e20}}) {
    for (json spec : {ValidSimulate(), ValidSweep()}) {
      spec["model"] = json{{key, value}};
      specs.Add(spec["kind"].get<std::string>() + " /model/" + key + " = " + json(value).dump(), spec, "invalid_job",
                "/model/" + key);
    }
  }
  // Issue 15: a job's own wall time beyond the server's cap (serve --max-job-seconds, 600 s by
  // default; the schema allows 3600), refused before its campaign is looked for.
  specs.Add("diagnose /options/max_seconds = 3600",
            {{"kind", "diagnose"}, {"campaign", {{"path", "campaign-a"}}}, {"options", {{"max_seconds", 3600}}}},
            "invalid_job", "/options/max_seconds");
  specs.Add("fit /options/max_refinement_seconds = 601",
            {{"kind", "fit"}, {"campaign", {{"path", "campaign-a"}}}, {"options", {{"max_refinement_seconds", 601}}}},
            "invalid_job", "/options/max_refinement_seconds");
  BodyCases(out, tokens);
  UploadCases(out, tokens);
  ContentTypeAndSizeCases(out, tokens);
  RouteCases(out, tokens, jobs);
  QueryCases(out, tokens, jobs);
  AuthCases(out, tokens, jobs);
  WorkerCases(out, tokens);
  return out;
}

}  // namespace strokelab::testing
