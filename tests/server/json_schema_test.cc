// The JSON Schema subset validator (json_schema.h) on small schemas, keyword by keyword, and the
// schema files compiled into the binary: each loads, matches its file in schema/, uses only the
// supported keywords, and every $ref resolves.
#include "strokelab/jobs/json_schema.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <string>
#include <utility>

#include "strokelab/diagnose/diagnose.h"
#include "strokelab/identify/fit.h"
#include "strokelab/model/model.h"

namespace strokelab::jobs {
namespace {

using nlohmann::json;
using ::testing::HasSubstr;

// The violation's pointer and message, or "ok".
std::string Outcome(const json& schema, const json& document) {
  const auto violation = ValidateAgainstSchema(schema, document);
  return violation ? violation->pointer + ": " + violation->message : "ok";
}

TEST(JsonSchemaTest, TypeNamesTheExpectedType) {
  EXPECT_EQ(Outcome({{"type", "number"}}, "x"), ": must be a number");
  EXPECT_EQ(Outcome({{"type", "number"}}, nullptr), ": must be a number");
  EXPECT_EQ(Outcome({{"type", "string"}}, 1), ": must be a string");
  EXPECT_EQ(Outcome({{"type", "object"}}, json::array()), ": must be an object");
  EXPECT_EQ(Outcome({{"type", "array"}}, json::object()), ": must be an array");
  EXPECT_EQ(Outcome({{"type", "boolean"}}, 0), ": must be a boolean");
  EXPECT_EQ(Outcome({{"type", "null"}}, false), ": must be null");
  EXPECT_EQ(Outcome({{"type", {"number", "null"}}}, "x"), ": must be a number or null");
  EXPECT_EQ(Outcome({{"type", {"string", "number", "null"}}}, true), ": must be a string, a number or null");
  EXPECT_EQ(Outcome({{"type", {"number", "null"}}}, nullptr), "ok");
  EXPECT_EQ(Outcome({{"type", "number"}}, 3), "ok");
  EXPECT_EQ(Outcome({{"type", "number"}}, 2.5), "ok");
}

TEST(JsonSchemaTest, IntegerAcceptsWholeFloatsOnly) {
  // Draft 2020-12: an integer is a number with a zero fractional part, 3.0 included.
  const json schema = {{"type", "integer"}};
  EXPECT_EQ(Outcome(schema, 3), "ok");
  EXPECT_EQ(Outcome(schema, 3.0), "ok");
  EXPECT_EQ(Outcome(schema, -7), "ok");
  EXPECT_EQ(Outcome(schema, 3.5), ": must be an integer");
  EXPECT_EQ(Outcome(schema, "3"), ": must be an integer");
}

TEST(JsonSchemaTest, NonFiniteNumbersAreRejected) {
  // JSON text cannot hold them, but documents built in code can.
  EXPECT_EQ(Outcome({{"type", "number"}}, std::numeric_limits<double>::quiet_NaN()), ": must be a finite number");
  EXPECT_EQ(Outcome(json::object(), std::numeric_limits<double>::infinity()), ": must be a finite number");
}

TEST(JsonSchemaTest, BoundsStateTheLimitAsWritten) {
  EXPECT_EQ(Outcome({{"minimum", 0.001}}, 0.0009), ": must be >= 0.001");
  EXPECT_EQ(Outcome({{"minimum", 0.001}}, 0.001), "ok");
  EXPECT_EQ(Outcome({{"minimum", 0.000001}}, 0), ": must be >= 1e-06");
  EXPECT_EQ(Outcome({{"maximum", 10000}}, 10000.5), ": must be <= 10000");
  EXPECT_EQ(Outcome({{"maximum", 1000000.0}}, 2e6), ": must be <= 1000000");
  EXPECT_EQ(Outcome({{"maximum", 10000}}, 10000), "ok");
  EXPECT_EQ(Outcome({{"exclusiveMinimum", 0}}, 0), ": must be > 0");
  EXPECT_EQ(Outcome({{"exclusiveMinimum", 0}}, 1e-300), "ok");
  EXPECT_EQ(Outcome({{"exclusiveMaximum", 60}}, 60), ": must be < 60");
  EXPECT_EQ(Outcome({{"exclusiveMaximum", 60}}, 59.9), "ok");
  // Bounds apply to numbers only.
  EXPECT_EQ(Outcome({{"minimum", 1}}, "a"), "ok");
}

TEST(JsonSchemaTest, ConstAndEnumListTheValues) {
  EXPECT_EQ(Outcome({{"const", "sweep"}}, "simulate"), ": must be sweep");
  EXPECT_EQ(Outcome({{"const", "sweep"}}, "sweep"), "ok");
  EXPECT_EQ(Outcome({{"enum", {"sweep", "simulate"}}}, "fit"), ": must be one of: sweep, simulate");
  EXPECT_EQ(Outcome({{"enum", {"sweep", "simulate"}}}, 1), ": must be one of: sweep, simulate");
  EXPECT_EQ(Outcome({{"enum", {1, 2.5, nullptr}}}, 3), ": must be one of: 1, 2.5, null");
  EXPECT_EQ(Outcome({{"enum", {1, 2.5, nullptr}}}, nullptr), "ok");
  // Type first: a number where an enum of strings is expected is a type error when type is given.
  EXPECT_EQ(Outcome({{"type", "string"}, {"enum", {"a", "b"}}}, 1), ": must be a string");
}

TEST(JsonSchemaTest, StringLengthCountsCharactersNotBytes) {
  const json schema = {{"minLength", 2}, {"maxLength", 3}};
  EXPECT_EQ(Outcome(schema, "a"), ": must be at least 2 characters long");
  EXPECT_EQ(Outcome(schema, "abcd"), ": must be at most 3 characters long");
  EXPECT_EQ(Outcome(schema, "\xC3\xA9\xC3\xA9\xC3\xA9"), "ok");  // "ééé": 3 characters, 6 bytes
  EXPECT_EQ(Outcome(schema, "\xE2\x82\xAC\xE2\x82\xAC\xE2\x82\xAC\xE2\x82\xAC"), ": must be at most 3 characters long");
}

TEST(JsonSchemaTest, ObjectsReportUnknownThenMissingThenFieldErrors) {
  const json schema = {{"type", "object"},
                       {"additionalProperties", false},
                       {"required", {"from", "to"}},
                       {"properties", {{"from", {{"type", "number"}}}, {"to", {{"type", "number"}}}, {"points", {{"type", "integer"}}}}}};
  EXPECT_EQ(Outcome(schema, {{"from", 1}, {"to", 2}}), "ok");
  EXPECT_EQ(Outcome(schema, {{"from", 1}}), "/to: is required");
  EXPECT_EQ(Outcome(schema, {{"from", 1}, {"to", 2}, {"step", 1}}), "/step: unknown field (allowed: from, points, to)");
  // An unknown field is reported before the required field it may be a typo of.
  EXPECT_EQ(Outcome(schema, {{"from", 1}, {"too", 2}}), "/too: unknown field (allowed: from, points, to)");
  EXPECT_EQ(Outcome(schema, {{"from", "1"}, {"to", 2}}), "/from: must be a number");
  // Present fields in key order: "from" before "points".
  EXPECT_EQ(Outcome(schema, {{"from", "1"}, {"to", 2}, {"points", "x"}}), "/from: must be a number");
}

TEST(JsonSchemaTest, AdditionalPropertiesAsASchema) {
  const json schema = {{"properties", {{"a", {{"type", "string"}}}}}, {"additionalProperties", {{"type", "number"}}}};
  EXPECT_EQ(Outcome(schema, {{"a", "x"}, {"b", 1}}), "ok");
  EXPECT_EQ(Outcome(schema, {{"a", "x"}, {"b", "y"}}), "/b: must be a number");
  EXPECT_EQ(Outcome({{"additionalProperties", false}}, {{"x", 1}}), "/x: unknown field (no fields are allowed)");
}

TEST(JsonSchemaTest, PointersEscapeSlashAndTilde) {
  const json schema = {{"additionalProperties", false}, {"properties", {{"a/b", {{"type", "object"}, {"required", {"c~d"}}}}}}};
  EXPECT_EQ(Outcome(schema, {{"a/b", json::object()}}), "/a~1b/c~0d: is required");
  EXPECT_EQ(Outcome(schema, {{"x~y", 1}}), "/x~0y: unknown field (allowed: a/b)");
}

TEST(JsonSchemaTest, ItemsAndItemCounts) {
  const json schema = {{"type", "array"}, {"minItems", 1}, {"maxItems", 3}, {"items", {{"type", "object"}, {"required", {"f"}}}}};
  EXPECT_EQ(Outcome(schema, json::array()), ": must have at least 1 items");
  EXPECT_EQ(Outcome(schema, json::array({{{"f", 1}}, {{"f", 1}}, {{"f", 1}}, {{"f", 1}}})), ": must have at most 3 items");
  EXPECT_EQ(Outcome(schema, json::array({{{"f", 1}}, {{"g", 1}}})), "/1/f: is required");
  EXPECT_EQ(Outcome(schema, json::array({{{"f", 1}}, 5})), "/1: must be an object");
  EXPECT_EQ(Outcome({{"properties", {{"list", {{"items", {{"type", "number"}}}}}}}}, {{"list", {1, 2, "3"}}}),
            "/list/2: must be a number");
}

TEST(JsonSchemaTest, RefsResolveInTheRootSchema) {
  const json schema = {
      {"$defs",
       {{"positive", {{"type", "number"}, {"exclusiveMinimum", 0}}},
        {"pair", {{"type", "object"}, {"properties", {{"a", {{"$ref", "#/$defs/positive"}}}, {"b", {{"$ref", "#/$defs/pair"}}}}}}}}},
      {"$ref", "#/$defs/pair"}};
  EXPECT_EQ(Outcome(schema, {{"a", 1}}), "ok");
  EXPECT_EQ(Outcome(schema, {{"a", 0}}), "/a: must be > 0");
  // Recursive: pair.b is a pair.
  EXPECT_EQ(Outcome(schema, {{"b", {{"b", {{"a", -1}}}}}}), "/b/b/a: must be > 0");
  EXPECT_EQ(Outcome(schema, {{"b", 3}}), "/b: must be an object");
  // $ref sits beside other keywords; both apply.
  const json beside = {{"$defs", {{"n", {{"type", "number"}}}}}, {"$ref", "#/$defs/n"}, {"maximum", 2}};
  EXPECT_EQ(Outcome(beside, 3), ": must be <= 2");
  EXPECT_EQ(Outcome(beside, "x"), ": must be a number");
}

TEST(JsonSchemaTest, SchemaDefectsAreProgrammingErrors) {
  EXPECT_THROW(ValidateAgainstSchema({{"$ref", "#/$defs/missing"}}, 1), std::logic_error);
  EXPECT_THROW(ValidateAgainstSchema({{"$ref", "other.json#/x"}}, 1), std::logic_error);
  EXPECT_THROW(ValidateAgainstSchema({{"pattern", "^a"}}, "a"), std::logic_error);
  EXPECT_THROW(ValidateAgainstSchema({{"properties", {{"a", {{"format", "uri"}}}}}}, {{"a", "x"}}), std::logic_error);
  EXPECT_THROW(ValidateAgainstSchema({{"type", "float"}}, 1), std::logic_error);
}

TEST(JsonSchemaTest, BooleanSchemas) {
  EXPECT_EQ(Outcome(true, {{"anything", 1}}), "ok");
  EXPECT_EQ(Outcome(false, 1), ": is not allowed");
  EXPECT_EQ(Outcome({{"properties", {{"to", false}}}}, {{"to", 1}}), "/to: is not allowed");
  EXPECT_EQ(Outcome({{"properties", {{"to", false}}}}, {{"from", 1}}), "ok");
}

TEST(JsonSchemaTest, AllOfReportsTheFirstFailingBranch) {
  const json schema = {{"allOf", {{{"minimum", 0}}, {{"maximum", 1}}, {{"type", "integer"}}}}};
  EXPECT_EQ(Outcome(schema, -1), ": must be >= 0");
  EXPECT_EQ(Outcome(schema, 2), ": must be <= 1");
  EXPECT_EQ(Outcome(schema, 0.5), ": must be an integer");
  EXPECT_EQ(Outcome(schema, 1), "ok");
}

TEST(JsonSchemaTest, AnyOfReportsTheAlternativeThatFitsTheType) {
  // A period: an integer >= 1 or the word "aperiodic".
  const json period = {{"anyOf", {{{"type", "integer"}, {"minimum", 1}}, {{"const", "aperiodic"}}}}};
  EXPECT_EQ(Outcome(period, 2), "ok");
  EXPECT_EQ(Outcome(period, "aperiodic"), "ok");
  EXPECT_EQ(Outcome(period, 0), ": must be >= 1");
  // "const" alone admits every type; the integer branch does not admit a string.
  EXPECT_EQ(Outcome(period, "never"), ": must be aperiodic");

  // No alternative admits the type: the types are listed.
  const json model = {{"anyOf", {{{"type", "string"}, {"enum", {"paper", "linear"}}}, {{"type", "object"}}}}};
  EXPECT_EQ(Outcome(model, 5), ": must be a string or an object");
  EXPECT_EQ(Outcome(model, nullptr), ": must be a string or an object");
  EXPECT_EQ(Outcome(model, "papr"), ": must be one of: paper, linear");
}

TEST(JsonSchemaTest, AnyOfPrefersTheAlternativeThatGotFurthest) {
  // Two object alternatives: the error deepest in the document wins, not a generic "matches none".
  const json schema = {
      {"anyOf",
       {{{"type", "object"}, {"required", {"a"}}, {"properties", {{"a", {{"type", "object"}, {"required", {"x"}}}}}}},
        {{"type", "object"}, {"required", {"b"}}}}}};
  EXPECT_EQ(Outcome(schema, {{"a", json::object()}}), "/a/x: is required");
  EXPECT_EQ(Outcome(schema, {{"b", 1}}), "ok");
  // Equal depth: the first alternative.
  EXPECT_EQ(Outcome(schema, json::object()), "/a: is required");
}

TEST(JsonSchemaTest, OneOfNeedsExactlyOneMatch) {
  const json schema = {{"oneOf", {{{"type", "number"}, {"minimum", 0}}, {{"type", "number"}, {"maximum", 10}}}}};
  EXPECT_EQ(Outcome(schema, -5), "ok");
  EXPECT_EQ(Outcome(schema, 50), "ok");
  EXPECT_EQ(Outcome(schema, 5), ": must match exactly one alternative, matches 2");
  EXPECT_EQ(Outcome(schema, "x"), ": must be a number");
}

TEST(JsonSchemaTest, IfThenAppliesThenOnlyWhenIfHolds) {
  const json schema = {
      {"type", "object"},
      {"allOf",
       {{{"if", {{"properties", {{"kind", {{"const", "a"}}}}}, {"required", {"kind"}}}}, {"then", {{"required", {"alpha"}}}}},
        {{"if", {{"properties", {{"kind", {{"const", "b"}}}}}, {"required", {"kind"}}}},
         {"then", {{"properties", {{"beta", {{"type", "string"}}}}}}}}}}};
  EXPECT_EQ(Outcome(schema, {{"kind", "a"}}), "/alpha: is required");
  EXPECT_EQ(Outcome(schema, {{"kind", "a"}, {"alpha", 1}}), "ok");
  EXPECT_EQ(Outcome(schema, {{"kind", "b"}, {"beta", 1}}), "/beta: must be a string");
  EXPECT_EQ(Outcome(schema, {{"kind", "c"}, {"beta", 1}}), "ok");
  // The failed "if" is silent: its own errors are never reported.
  EXPECT_EQ(Outcome(schema, json::object()), "ok");
  // if without then is allowed and does nothing.
  EXPECT_EQ(Outcome({{"if", {{"type", "string"}}}}, 1), "ok");
}

TEST(JsonSchemaTest, AnnotationsAreIgnored) {
  const json schema = {{"$schema", "https://json-schema.org/draft/2020-12/schema"},
                       {"$id", "x"},
                       {"title", "t"},
                       {"description", "d"},
                       {"default", 3},
                       {"examples", {1}},
                       {"type", "number"}};
  EXPECT_EQ(Outcome(schema, 1), "ok");
  EXPECT_EQ(Outcome(schema, "1"), ": must be a number");
}

// ---------------------------------------------------------------------------------------------
// The built-in schemas.

// Walks a schema, independently of the validator: every keyword must be in the supported subset,
// every subschema well-formed, every $ref resolvable. Adds a description of each defect to *defects.
void Walk(const json& root, const json& schema, const std::string& where, std::vector<std::string>* defects) {
  static const std::set<std::string> kSubschemaKeywords = {"additionalProperties", "items", "if", "then"};
  static const std::set<std::string> kSchemaListKeywords = {"allOf", "anyOf", "oneOf"};
  static const std::set<std::string> kSchemaMapKeywords = {"properties", "$defs"};
  static const std::set<std::string> kNumberKeywords = {"minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum"};
  static const std::set<std::string> kCountKeywords = {"minLength", "maxLength", "minItems", "maxItems"};
  static const std::set<std::string> kTypes = {"object", "array", "string", "number", "integer", "boolean", "null"};
  static const std::set<std::string> kOther = {"$schema", "$id", "title", "description", "default", "examples",
                                               "type",    "required", "enum", "const",    "$ref"};
  if (schema.is_boolean()) return;
  if (!schema.is_object()) {
    defects->push_back(where + ": a schema must be an object or a boolean");
    return;
  }
  for (const auto& [keyword, argument] : schema.items()) {
    const std::string at = where + "/" + keyword;
    if (kSubschemaKeywords.count(keyword)) {
      Walk(root, argument, at, defects);
    } else if (kSchemaListKeywords.count(keyword)) {
      if (!argument.is_array() || argument.empty()) defects->push_back(at + ": must be a non-empty array");
      for (size_t i = 0; i < argument.size(); ++i) Walk(root, argument[i], at + "/" + std::to_string(i), defects);
    } else if (kSchemaMapKeywords.count(keyword)) {
      if (!argument.is_object()) defects->push_back(at + ": must be an object");
      for (const auto& [name, sub] : argument.items()) Walk(root, sub, at + "/" + name, defects);
    } else if (kNumberKeywords.count(keyword)) {
      if (!argument.is_number()) defects->push_back(at + ": must be a number");
    } else if (kCountKeywords.count(keyword)) {
      if (!argument.is_number_unsigned()) defects->push_back(at + ": must be a non-negative integer");
    } else if (keyword == "type") {
      const json types = argument.is_array() ? argument : json::array({argument});
      for (const json& t : types)
        if (!t.is_string() || !kTypes.count(t.get<std::string>())) defects->push_back(at + ": unknown type " + t.dump());
    } else if (keyword == "required") {
      for (const json& name : argument)
        if (!name.is_string()) defects->push_back(at + ": names must be strings");
    } else if (keyword == "enum") {
      if (!argument.is_array() || argument.empty()) defects->push_back(at + ": must be a non-empty array");
    } else if (keyword == "$ref") {
      const std::string ref = argument.get<std::string>();
      if (ref.rfind("#/$defs/", 0) != 0) defects->push_back(at + ": only #/$defs/NAME refs are supported: " + ref);
      else if (!root.contains(json::json_pointer(ref.substr(1)))) defects->push_back(at + ": does not resolve: " + ref);
    } else if (!kOther.count(keyword)) {
      defects->push_back(at + ": unsupported keyword");
    }
  }
  if (schema.contains("then") && !schema.contains("if")) defects->push_back(where + ": then without if");
}

std::vector<std::string> SchemaFileStems() {
  std::vector<std::string> stems;
  for (const auto& entry : std::filesystem::directory_iterator(STROKELAB_SCHEMA_DIR)) {
    const std::string name = entry.path().filename().string();
    const std::string suffix = ".schema.json";
    if (name.size() > suffix.size() && name.ends_with(suffix)) stems.push_back(name.substr(0, name.size() - suffix.size()));
  }
  std::sort(stems.begin(), stems.end());
  return stems;
}

TEST(BuiltInSchemaTest, EverySchemaFileIsEmbeddedAsWritten) {
  const std::vector<std::string> stems = SchemaFileStems();
  EXPECT_THAT(stems, ::testing::IsSupersetOf({"job", "result"}));
  for (const std::string& stem : stems) {
    SCOPED_TRACE(stem);
    std::ifstream file(std::string(STROKELAB_SCHEMA_DIR) + "/" + stem + ".schema.json");
    const json on_disk = json::parse(file);
    ASSERT_NO_THROW(BuiltInSchema(stem));
    EXPECT_EQ(BuiltInSchema(stem), on_disk) << "the build embeds a stale copy; re-run cmake";
    EXPECT_EQ(BuiltInSchema(stem).value("$schema", ""), "https://json-schema.org/draft/2020-12/schema");
  }
  EXPECT_THROW(BuiltInSchema("no_such_schema"), std::out_of_range);
}

TEST(BuiltInSchemaTest, SchemasUseOnlyTheSupportedSubset) {
  for (const std::string& stem : SchemaFileStems()) {
    SCOPED_TRACE(stem);
    std::vector<std::string> defects;
    Walk(BuiltInSchema(stem), BuiltInSchema(stem), "", &defects);
    EXPECT_THAT(defects, ::testing::IsEmpty());
  }
}

TEST(BuiltInSchemaTest, TheWalkerCatchesDefects) {
  const json bad = {{"properties", {{"a", {{"pattern", "x"}}}, {"b", {{"$ref", "#/$defs/none"}}}}},
                    {"anyOf", {{{"type", "float"}}}},
                    {"maxLength", -1}};
  std::vector<std::string> defects;
  Walk(bad, bad, "", &defects);
  EXPECT_THAT(defects, ::testing::UnorderedElementsAre(HasSubstr("/properties/a/pattern: unsupported keyword"),
                                                       HasSubstr("/properties/b/$ref: does not resolve"),
                                                       HasSubstr("/anyOf/0/type: unknown type"),
                                                       HasSubstr("/maxLength: must be a non-negative integer")));
}

// Every object in the job schema is closed (additionalProperties false), so typos are caught.
void CollectOpenObjects(const json& schema, const std::string& where, std::vector<std::string>* open) {
  if (!schema.is_object()) return;
  if (schema.contains("properties") && schema.value("additionalProperties", json(true)) != json(false))
    open->push_back(where);
  for (const auto& [keyword, argument] : schema.items()) {
    if (keyword == "properties" || keyword == "$defs") {
      for (const auto& [name, sub] : argument.items()) CollectOpenObjects(sub, where + "/" + keyword + "/" + name, open);
    } else if (argument.is_array()) {
      for (size_t i = 0; i < argument.size(); ++i)
        CollectOpenObjects(argument[i], where + "/" + keyword + "/" + std::to_string(i), open);
    } else if (argument.is_object() && keyword != "if") {
      CollectOpenObjects(argument, where + "/" + keyword, open);
    }
  }
}

TEST(BuiltInSchemaTest, JobObjectsAreClosed) {
  std::vector<std::string> open;
  CollectOpenObjects(BuiltInSchema("job"), "", &open);
  // The root only dispatches on kind; each kind's schema is closed.
  EXPECT_THAT(open, ::testing::ElementsAre(""));
  EXPECT_FALSE(BuiltInSchema("job").contains("additionalProperties"));
}

TEST(BuiltInSchemaTest, ModelObjectListsExactlyTheCoreParameters) {
  std::set<std::string> expected = {"preset", "contact_law"};
  for (const ParameterInfo& info : Parameters()) {
    expected.insert(info.key);
    expected.insert(info.json_name);
  }
  std::set<std::string> actual;
  const json& properties = BuiltInSchema("job").at("$defs").at("model_object").at("properties");
  for (const auto& [name, unused] : properties.items()) actual.insert(name);
  EXPECT_EQ(actual, expected);
  // null (absent) is allowed exactly for the stops and the amplifier limit, as in ModelFromJson.
  for (const ParameterInfo& info : Parameters()) {
    const std::string name = info.json_name;
    const bool may_be_absent = name == "lower_stop_m" || name == "upper_stop_m" || name == "amplifier_limit_v";
    for (const std::string& key : {std::string(info.key), name}) {
      SCOPED_TRACE(key);
      const json probe = {{"$defs", BuiltInSchema("job").at("$defs")}, {"$ref", "#/$defs/model_object"}};
      EXPECT_EQ(Outcome(probe, {{key, nullptr}}), may_be_absent ? "ok" : "/" + key + ": must be a number");
      EXPECT_EQ(Outcome(probe, {{key, 1.5}}), "ok");
    }
  }
}

// A definition of result.schema.json as a schema of its own.
json ResultDefinition(const std::string& name) {
  return {{"$defs", BuiltInSchema("result").at("$defs")}, {"$ref", "#/$defs/" + name}};
}

TEST(BuiltInSchemaTest, ResultSchemaDescribesPointsAndStatus) {
  const json point = {{"frequency_hz", 8.0},   {"amplitude_v", 0.4},        {"branch", "up"},
                      {"stable", true},        {"period", 1},               {"first_harmonic_force_n", 0.1},
                      {"first_harmonic_phase_rad", -1.2}, {"h_re_n_per_v", 0.1}, {"h_im_n_per_v", -0.2},
                      {"min_displacement_m", -1e-3},      {"max_displacement_m", 2e-3},
                      {"peak_force_n", 0.5},   {"contacts_per_period", 1.0}, {"max_multiplier", 0.3}};
  EXPECT_EQ(Outcome(ResultDefinition("sweep_point"), point), "ok");
  json aperiodic = point;
  aperiodic["period"] = "aperiodic";
  aperiodic["max_multiplier"] = nullptr;
  EXPECT_EQ(Outcome(ResultDefinition("sweep_point"), aperiodic), "ok");
  json bad = point;
  bad["branch"] = "sideways";
  EXPECT_EQ(Outcome(ResultDefinition("sweep_point"), bad), "/branch: must be one of: up, down, unstable");
  bad = point;
  bad["period"] = 0;
  EXPECT_EQ(Outcome(ResultDefinition("sweep_point"), bad), "/period: must be >= 1");
  bad = point;
  bad.erase("h_im_n_per_v");
  EXPECT_EQ(Outcome(ResultDefinition("sweep_point"), bad), "/h_im_n_per_v: is required");

  const json status = {{"id", 3},
                       {"kind", "sweep"},
                       {"status", "running"},
                       {"progress", {{"done", 2}, {"total", 12}}},
                       {"created_ms", 1700000000000},
                       {"started_ms", 1700000000100},
                       {"finished_ms", nullptr},
                       {"error", nullptr}};
  EXPECT_EQ(Outcome(ResultDefinition("job_status"), status), "ok");
  json bad_status = status;
  bad_status["status"] = "done";
  EXPECT_EQ(Outcome(ResultDefinition("job_status"), bad_status),
            "/status: must be one of: queued, running, succeeded, failed, cancelled");
  bad_status = status;
  bad_status["progress"].erase("total");
  EXPECT_EQ(Outcome(ResultDefinition("job_status"), bad_status), "/progress/total: is required");

  const json page = {{"points", {point, aperiodic}}, {"next_cursor", nullptr}};
  EXPECT_EQ(Outcome(ResultDefinition("points_page"), page), "ok");
  json bad_page = page;
  bad_page["points"][1]["stable"] = "yes";
  EXPECT_EQ(Outcome(ResultDefinition("points_page"), bad_page), "/points/1/stable: must be a boolean");

  const json error = {{"error", {{"code", "invalid_job"}, {"message", "must be >= 0.001"}, {"field", "/grid/frequency_hz/from"}}}};
  EXPECT_EQ(Outcome(ResultDefinition("error_body"), error), "ok");
  // The whole document: any of the entries.
  EXPECT_EQ(Outcome(BuiltInSchema("result"), error), "ok");
  EXPECT_EQ(Outcome(BuiltInSchema("result"), status), "ok");
}

// The job options of fit and diagnose jobs are exactly the job names of the option tables (fit.h,
// diagnose.h): an option added to one and not the other fails here.
TEST(BuiltInSchemaTest, FitAndDiagnoseOptionsAreTheOptionTables) {
  std::set<std::string> fit_names, diagnose_names;
  for (const OptionInfo<FitOptions>& info : FitOptionFields()) fit_names.insert(info.job_name);
  diagnose_names = fit_names;
  for (const OptionInfo<DiagnoseOptions>& info : DiagnoseOptionFields()) diagnose_names.insert(info.job_name);
  for (const auto& [kind, expected] : {std::pair{"fit", fit_names}, std::pair{"diagnose", diagnose_names}}) {
    SCOPED_TRACE(kind);
    std::set<std::string> actual;
    const json& options = BuiltInSchema("job").at("$defs").at(kind).at("properties").at("options");
    for (const auto& [name, unused] : options.at("properties").items()) actual.insert(name);
    EXPECT_EQ(actual, expected);
  }
}

}  // namespace
}  // namespace strokelab::jobs
