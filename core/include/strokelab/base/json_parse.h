// The one way strokelab parses JSON text: nlohmann's parser behind a nesting bound. nlohmann parses
// without recursion, but copying, comparing and dumping a value recurse once per level, so a
// request body of 200,000 nested brackets (400 KB) parsed fine and then overflowed the stack when
// the value was copied. Every parse of text that strokelab did not write itself in this process
// (request bodies, replies, files, stored rows) goes through ParseJson.
#pragma once

#include <nlohmann/json.hpp>
#include <string_view>

namespace strokelab {

// Deeper than any document strokelab reads or writes (a job spec or a result row is < 10 levels).
inline constexpr int kMaxJsonDepth = 64;

// Parses `text` as nlohmann::json::parse does, after checking that no array or object nests deeper
// than kMaxJsonDepth. Throws nlohmann::json::parse_error (id 101, like any syntax error, with the
// byte offset of the first bracket too deep) so that callers handle it with the other syntax errors.
nlohmann::json ParseJson(std::string_view text);

}  // namespace strokelab
