// Bounded-depth JSON parsing (json_parse.h).
#include "strokelab/base/json_parse.h"

#include <string>

namespace strokelab {
namespace {

// The byte offset (1-based, as nlohmann counts) of the first '[' or '{' outside a string that opens
// a level beyond `max_depth`, or 0 when there is none. Malformed text is left to the parser.
size_t FirstTooDeepBracket(std::string_view text, int max_depth) {
  int depth = 0;
  bool in_string = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\') ++i;  // the escaped character cannot end the string
      else if (c == '"') in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > max_depth) return i + 1;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return 0;
}

}  // namespace

nlohmann::json ParseJson(std::string_view text) {
  if (const size_t at = FirstTooDeepBracket(text, kMaxJsonDepth); at != 0)
    throw nlohmann::json::parse_error::create(
        101, at, "syntax error: arrays and objects nest deeper than " + std::to_string(kMaxJsonDepth) + " levels",
        nullptr);
  return nlohmann::json::parse(text);
}

}  // namespace strokelab
