// Validation of job specs against the JSON Schema files in schema/, at the edge of the service.
// Implements the subset of JSON Schema (draft 2020-12) that those files use: type, properties,
// required, additionalProperties (false or a schema), enum, const, minimum, maximum,
// exclusiveMinimum, exclusiveMaximum, minLength, maxLength, items, minItems, maxItems, oneOf,
// anyOf, allOf, if/then, $ref to "#/$defs/NAME", and "description" (ignored). A keyword outside the
// subset in a schema is a programming error (the schema tests catch it), not a user error.
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

namespace strokelab::jobs {

struct SchemaViolation {
  std::string pointer;  // JSON pointer of the offending field in the document, e.g. "/grid/amplitude_v/to"
  std::string message;  // one sentence naming the rule, e.g. "must be >= 0.001"
};

// The first violation in document order, or nullopt when the document is valid.
std::optional<SchemaViolation> ValidateAgainstSchema(const nlohmann::json& schema, const nlohmann::json& document);

// The schemas compiled into the binary from schema/*.schema.json, by file stem ("job", ...).
// Throws std::out_of_range for an unknown name.
const nlohmann::json& BuiltInSchema(const std::string& name);

}  // namespace strokelab::jobs
