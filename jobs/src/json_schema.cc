// The JSON Schema subset of json_schema.h. One recursive pass that stops at the first violation.
//
// Order of checks on one value (so that the first violation is the most useful one):
//   $ref, type, const, enum, number bounds, string length,
//   object: unknown fields (additionalProperties), required fields, then each present field in key
//           order (nlohmann::json keeps object keys sorted),
//   array:  item count, then each item,
//   allOf, anyOf, oneOf, if/then.
// Unknown fields come before missing ones: a typo ("amplitude" for "amplitude_v") is reported as
// the unknown field it is, not as the required field it hides.
//
// anyOf/oneOf with no matching alternative report the error of one alternative rather than a bare
// "matches none": among the alternatives whose "type" admits the value, the one that got furthest
// into the document (longest error pointer). When no alternative admits the value's type the
// message lists the types ("must be a string or an object").
#include "strokelab/jobs/json_schema.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <stdexcept>
#include <map>
#include <string_view>

#include "builtin_schemas.h"
#include "strokelab/base/json_parse.h"

namespace strokelab::jobs {
namespace {

using nlohmann::json;

constexpr std::string_view kKeywords[] = {
    // applied
    "$ref", "type", "const", "enum", "minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum", "minLength",
    "maxLength", "properties", "required", "additionalProperties", "items", "minItems", "maxItems", "allOf", "anyOf",
    "oneOf", "if", "then",
    // annotations and containers, not applied
    "$schema", "$id", "$defs", "title", "description", "default", "examples"};

bool IsKnownKeyword(std::string_view keyword) {
  return std::find(std::begin(kKeywords), std::end(kKeywords), keyword) != std::end(kKeywords);
}

// RFC 6901: "~" -> "~0", "/" -> "~1".
std::string EscapePointerToken(std::string_view token) {
  std::string out;
  out.reserve(token.size());
  for (char c : token) {
    if (c == '~') out += "~0";
    else if (c == '/') out += "~1";
    else out += c;
  }
  return out;
}

size_t PointerDepth(const std::string& pointer) { return std::count(pointer.begin(), pointer.end(), '/'); }

// Numbers as a person writes them: 0.001, 10000, 1000000, 1e-06.
std::string FormatNumber(const json& value) {
  if (value.is_number_integer()) return value.dump();
  const double x = value.get<double>();
  if (std::isfinite(x) && x == std::floor(x) && std::abs(x) < 1e15) return std::to_string(static_cast<long long>(x));
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, x);
  return std::string(buffer, result.ptr);
}

// A value in a message: strings bare, numbers as above, anything else as JSON.
std::string Display(const json& value) {
  if (value.is_string()) return value.get<std::string>();
  if (value.is_number()) return FormatNumber(value);
  return value.dump();
}

std::string TypeNoun(const std::string& type) {
  if (type == "object" || type == "array" || type == "integer") return "an " + type;
  if (type == "null") return "null";
  return "a " + type;
}

std::string JoinNouns(const std::vector<std::string>& types) {
  std::string out;
  for (size_t i = 0; i < types.size(); ++i) {
    if (i > 0) out += i + 1 == types.size() ? " or " : ", ";
    out += TypeNoun(types[i]);
  }
  return out;
}

bool IsIntegral(const json& value) {
  if (value.is_number_integer()) return true;
  if (!value.is_number_float()) return false;
  const double x = value.get<double>();
  return std::isfinite(x) && x == std::floor(x);
}

bool HasType(const json& value, const std::string& type) {
  if (type == "object") return value.is_object();
  if (type == "array") return value.is_array();
  if (type == "string") return value.is_string();
  if (type == "boolean") return value.is_boolean();
  if (type == "null") return value.is_null();
  if (type == "number") return value.is_number();
  if (type == "integer") return IsIntegral(value);
  throw std::logic_error("JSON Schema: unknown type '" + type + "'");
}

std::vector<std::string> TypeList(const json& type) {
  if (type.is_string()) return {type.get<std::string>()};
  std::vector<std::string> out;
  for (const json& t : type) out.push_back(t.get<std::string>());
  return out;
}

// UTF-8 code points (JSON Schema counts characters, not bytes).
size_t CodePoints(const std::string& text) {
  return std::count_if(text.begin(), text.end(), [](char c) { return (static_cast<unsigned char>(c) & 0xC0) != 0x80; });
}

class Validator {
 public:
  explicit Validator(const json& root) : root_(root) {}

  std::optional<SchemaViolation> Check(const json& schema, const json& value, const std::string& pointer) const {
    if (schema.is_boolean()) {
      if (schema.get<bool>()) return std::nullopt;
      return SchemaViolation{pointer, "is not allowed"};
    }
    if (!schema.is_object()) throw std::logic_error("JSON Schema: a schema must be an object or a boolean");
    for (const auto& [keyword, argument] : schema.items())
      if (!IsKnownKeyword(keyword)) throw std::logic_error("JSON Schema: unsupported keyword '" + keyword + "'");

    if (auto it = schema.find("$ref"); it != schema.end())
      if (auto v = Check(Resolve(*it), value, pointer)) return v;

    if (auto it = schema.find("type"); it != schema.end()) {
      const std::vector<std::string> types = TypeList(*it);
      const bool ok = std::any_of(types.begin(), types.end(), [&](const std::string& t) { return HasType(value, t); });
      if (!ok) return SchemaViolation{pointer, "must be " + JoinNouns(types)};
    }
    if (value.is_number_float() && !std::isfinite(value.get<double>()))
      return SchemaViolation{pointer, "must be a finite number"};
    if (auto it = schema.find("const"); it != schema.end() && value != *it)
      return SchemaViolation{pointer, "must be " + Display(*it)};
    if (auto it = schema.find("enum"); it != schema.end()) {
      if (std::find(it->begin(), it->end(), value) == it->end()) {
        std::string list;
        for (const json& option : *it) list += (list.empty() ? "" : ", ") + Display(option);
        return SchemaViolation{pointer, "must be one of: " + list};
      }
    }
    if (value.is_number()) {
      if (auto v = CheckBounds(schema, value.get<double>(), pointer)) return v;
    }
    if (value.is_string()) {
      const size_t length = CodePoints(value.get_ref<const std::string&>());
      if (auto it = schema.find("minLength"); it != schema.end() && length < it->get<size_t>())
        return SchemaViolation{pointer, "must be at least " + it->dump() + " characters long"};
      if (auto it = schema.find("maxLength"); it != schema.end() && length > it->get<size_t>())
        return SchemaViolation{pointer, "must be at most " + it->dump() + " characters long"};
    }
    if (value.is_object()) {
      if (auto v = CheckObject(schema, value, pointer)) return v;
    }
    if (value.is_array()) {
      if (auto v = CheckArray(schema, value, pointer)) return v;
    }
    if (auto it = schema.find("allOf"); it != schema.end()) {
      for (const json& branch : *it)
        if (auto v = Check(branch, value, pointer)) return v;
    }
    if (auto it = schema.find("anyOf"); it != schema.end()) {
      if (auto v = CheckAlternatives(*it, value, pointer, false)) return v;
    }
    if (auto it = schema.find("oneOf"); it != schema.end()) {
      if (auto v = CheckAlternatives(*it, value, pointer, true)) return v;
    }
    if (auto it = schema.find("if"); it != schema.end()) {
      const bool condition = !Check(*it, value, pointer).has_value();
      if (auto then = schema.find("then"); condition && then != schema.end())
        if (auto v = Check(*then, value, pointer)) return v;
    }
    return std::nullopt;
  }

 private:
  // "#/$defs/NAME" (or any "#/..." pointer) inside the root schema.
  const json& Resolve(const json& ref) const {
    const std::string text = ref.get<std::string>();
    if (text == "#") return root_;
    if (text.rfind("#/", 0) != 0) throw std::logic_error("JSON Schema: only local $ref (#/...) is supported: " + text);
    const json::json_pointer target(text.substr(1));
    if (!root_.contains(target)) throw std::logic_error("JSON Schema: $ref " + text + " does not resolve");
    return root_.at(target);
  }

  static std::optional<SchemaViolation> CheckBounds(const json& schema, double x, const std::string& pointer) {
    if (auto it = schema.find("minimum"); it != schema.end() && !(x >= it->get<double>()))
      return SchemaViolation{pointer, "must be >= " + FormatNumber(*it)};
    if (auto it = schema.find("exclusiveMinimum"); it != schema.end() && !(x > it->get<double>()))
      return SchemaViolation{pointer, "must be > " + FormatNumber(*it)};
    if (auto it = schema.find("maximum"); it != schema.end() && !(x <= it->get<double>()))
      return SchemaViolation{pointer, "must be <= " + FormatNumber(*it)};
    if (auto it = schema.find("exclusiveMaximum"); it != schema.end() && !(x < it->get<double>()))
      return SchemaViolation{pointer, "must be < " + FormatNumber(*it)};
    return std::nullopt;
  }

  std::optional<SchemaViolation> CheckObject(const json& schema, const json& value, const std::string& pointer) const {
    static const json kNoProperties = json::object();
    const auto properties_it = schema.find("properties");
    const json& properties = properties_it != schema.end() ? *properties_it : kNoProperties;
    if (auto additional = schema.find("additionalProperties"); additional != schema.end()) {
      for (const auto& [key, field] : value.items()) {
        if (properties.contains(key)) continue;
        const std::string field_pointer = pointer + "/" + EscapePointerToken(key);
        if (additional->is_boolean() && !additional->get<bool>()) {
          std::string allowed;
          for (const auto& [name, unused] : properties.items()) allowed += (allowed.empty() ? "" : ", ") + name;
          return SchemaViolation{field_pointer, allowed.empty() ? "unknown field (no fields are allowed)"
                                                                : "unknown field (allowed: " + allowed + ")"};
        }
        if (auto v = Check(*additional, field, field_pointer)) return v;
      }
    }
    if (auto required = schema.find("required"); required != schema.end()) {
      for (const json& name : *required) {
        const std::string& key = name.get_ref<const std::string&>();
        if (!value.contains(key)) return SchemaViolation{pointer + "/" + EscapePointerToken(key), "is required"};
      }
    }
    for (const auto& [key, field] : value.items()) {
      auto property = properties.find(key);
      if (property == properties.end()) continue;
      if (auto v = Check(*property, field, pointer + "/" + EscapePointerToken(key))) return v;
    }
    return std::nullopt;
  }

  std::optional<SchemaViolation> CheckArray(const json& schema, const json& value, const std::string& pointer) const {
    if (auto it = schema.find("minItems"); it != schema.end() && value.size() < it->get<size_t>())
      return SchemaViolation{pointer, "must have at least " + it->dump() + " items"};
    if (auto it = schema.find("maxItems"); it != schema.end() && value.size() > it->get<size_t>())
      return SchemaViolation{pointer, "must have at most " + it->dump() + " items"};
    if (auto items = schema.find("items"); items != schema.end()) {
      for (size_t i = 0; i < value.size(); ++i)
        if (auto v = Check(*items, value[i], pointer + "/" + std::to_string(i))) return v;
    }
    return std::nullopt;
  }

  // The types an alternative admits, looking through $ref; empty: any type.
  std::vector<std::string> AdmittedTypes(const json& schema) const {
    if (!schema.is_object()) return {};
    if (auto it = schema.find("type"); it != schema.end()) return TypeList(*it);
    if (auto it = schema.find("$ref"); it != schema.end()) return AdmittedTypes(Resolve(*it));
    return {};
  }

  std::optional<SchemaViolation> CheckAlternatives(const json& alternatives, const json& value,
                                                   const std::string& pointer, bool exactly_one) const {
    size_t matches = 0;
    std::optional<SchemaViolation> best;
    std::vector<std::string> all_types;
    for (const json& branch : alternatives) {
      std::optional<SchemaViolation> v = Check(branch, value, pointer);
      if (!v) {
        ++matches;
        continue;
      }
      const std::vector<std::string> types = AdmittedTypes(branch);
      for (const std::string& t : types)
        if (std::find(all_types.begin(), all_types.end(), t) == all_types.end()) all_types.push_back(t);
      const bool admits = types.empty() || std::any_of(types.begin(), types.end(),
                                                       [&](const std::string& t) { return HasType(value, t); });
      if (admits && (!best || PointerDepth(v->pointer) > PointerDepth(best->pointer))) best = std::move(v);
    }
    if (exactly_one && matches > 1)
      return SchemaViolation{pointer, "must match exactly one alternative, matches " + std::to_string(matches)};
    if (matches > 0) return std::nullopt;
    if (best) return best;
    return SchemaViolation{pointer, "must be " + JoinNouns(all_types)};
  }

  const json& root_;
};

}  // namespace

std::optional<SchemaViolation> ValidateAgainstSchema(const nlohmann::json& schema, const nlohmann::json& document) {
  return Validator(schema).Check(schema, document, "");
}

const nlohmann::json& BuiltInSchema(const std::string& name) {
  // Parsed once, on first use (thread-safe static initialisation); a schema that does not parse is
  // a build defect, caught by the schema tests.
  static const std::map<std::string, nlohmann::json, std::less<>> schemas = [] {
    std::map<std::string, nlohmann::json, std::less<>> parsed;
    for (const internal::EmbeddedSchema& schema : internal::EmbeddedSchemas())
      parsed.emplace(std::string(schema.name), ParseJson(schema.text));
    return parsed;
  }();
  const auto it = schemas.find(name);
  if (it == schemas.end()) throw std::out_of_range("no built-in JSON schema named '" + name + "'");
  return it->second;
}

}  // namespace strokelab::jobs
