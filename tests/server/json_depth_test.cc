// ParseJson (core/base/json_parse.h), the one JSON parser configuration: nesting is bounded, and
// brackets inside strings are text, not levels.
#include "strokelab/base/json_parse.h"

#include <gtest/gtest.h>

#include <string>

namespace strokelab {
namespace {

std::string Nested(int depth) { return std::string(depth, '[') + std::string(depth, ']'); }

TEST(ParseJsonTest, NestingIsBoundedAndCountedOutsideStringsOnly) {
  EXPECT_NO_THROW(ParseJson(Nested(kMaxJsonDepth)));
  EXPECT_THROW(ParseJson(Nested(kMaxJsonDepth + 1)), nlohmann::json::parse_error);
  EXPECT_THROW(ParseJson("{\"a\":" + Nested(200000) + "}"), nlohmann::json::parse_error);
  // Brackets and escaped quotes inside strings are not levels.
  const std::string brackets = "\"" + std::string(1000, '[') + "\\\"" + std::string(1000, '{') + "\"";
  EXPECT_EQ(ParseJson("[" + brackets + "]").at(0).get<std::string>().size(), 2001u);
  // The error is a syntax error at the first bracket too deep.
  try {
    ParseJson(Nested(kMaxJsonDepth + 5));
    FAIL() << "no error";
  } catch (const nlohmann::json::parse_error& e) {
    EXPECT_EQ(e.byte, static_cast<size_t>(kMaxJsonDepth + 1));
    EXPECT_NE(std::string(e.what()).find("nest deeper than 64"), std::string::npos) << e.what();
  }
  // Other syntax errors are nlohmann's.
  EXPECT_THROW(ParseJson("{"), nlohmann::json::parse_error);
}

}  // namespace
}  // namespace strokelab
