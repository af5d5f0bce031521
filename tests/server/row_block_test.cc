// Result blocks (server/src/row_block.h): rows come back as they went in, numbers bit for bit and
// integers with their sign, whatever their keys; a damaged block is refused with StoreError, never
// read past its end.
#include "row_block.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "strokelab/server/store.h"

namespace strokelab::server::internal {
namespace {

using nlohmann::json;

std::vector<json> BlockRoundTrip(const std::vector<json>& rows) {
  RowBlockWriter writer;
  for (const json& r : rows) writer.Add(r);
  EXPECT_EQ(writer.rows(), static_cast<int64_t>(rows.size()));
  return DecodeRowBlock(writer.Finish());
}

uint64_t DoubleBits(double d) {
  uint64_t b;
  std::memcpy(&b, &d, sizeof b);
  return b;
}

// Rows as a sweep, a fit and a diagnosis store them: shared and differing key lists, nesting, and
// rows that are not objects.
std::vector<json> MixedBlockRows() {
  return {
      {{"frequency_hz", 5.0}, {"amplitude_v", 0.4}, {"branch", "up"}, {"stable", true}, {"period", 1}},
      {{"frequency_hz", 5.1}, {"amplitude_v", 0.4}, {"branch", "down"}, {"stable", false}, {"period", "aperiodic"}},
      {{"name", "k3"}, {"value", -1.5e5}, {"se", nullptr}, {"bounds", {-1e9, 1e9}}, {"flags", json::array()}},
      {{"frequency_hz", 5.2}, {"amplitude_v", 0.4}, {"branch", "unstable"}, {"stable", false}, {"period", 2}},
      {{"nested", {{"a", {{"b", {1, 2.5, "three", nullptr, {{"c", false}}}}}}}}},
      json::object(),
      json::array({1, 2}),
      "a bare string",
      42,
      nullptr,
  };
}

TEST(RowBlock, RowsComeBackAsTheyWentIn) {
  const std::vector<json> rows = MixedBlockRows();
  const std::vector<json> back = BlockRoundTrip(rows);
  ASSERT_EQ(back.size(), rows.size());
  for (size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(back[i], rows[i]) << i;
    EXPECT_EQ(back[i].dump(), rows[i].dump()) << i;
  }
  EXPECT_TRUE(BlockRoundTrip({}).empty());
}

TEST(RowBlock, NumbersKeepTheirBitsAndIntegersTheirSign) {
  const double doubles[] = {0.0,
                            -0.0,
                            1.0 / 3.0,
                            -2.65e8,
                            std::numeric_limits<double>::denorm_min(),
                            std::numeric_limits<double>::max(),
                            std::numeric_limits<double>::infinity(),
                            -std::numeric_limits<double>::infinity(),
                            std::numeric_limits<double>::quiet_NaN()};
  for (const double d : doubles) {
    const json back = BlockRoundTrip({{{"x", d}}}).at(0).at("x");
    ASSERT_TRUE(back.is_number_float()) << d;
    EXPECT_EQ(DoubleBits(back.get<double>()), DoubleBits(d)) << d;
  }
  const int64_t signed_values[] = {0, -1, 1, std::numeric_limits<int64_t>::min(), std::numeric_limits<int64_t>::max()};
  for (const int64_t i : signed_values) {
    const json back = BlockRoundTrip({{{"i", json(i)}}}).at(0).at("i");
    ASSERT_TRUE(back.is_number_integer()) << i;
    EXPECT_EQ(back.get<int64_t>(), i);
  }
  const uint64_t big = std::numeric_limits<uint64_t>::max();
  const json back = BlockRoundTrip({{{"u", json(big)}}}).at(0).at("u");
  ASSERT_TRUE(back.is_number_unsigned());
  EXPECT_EQ(back.get<uint64_t>(), big);
  // Strings are bytes: an embedded NUL and UTF-8 survive.
  const std::string text = std::string("a\0b", 3) + "\xc2\xb5m";
  EXPECT_EQ(BlockRoundTrip({{{"s", text}}}).at(0).at("s").get<std::string>(), text);
}

TEST(RowBlock, RowsOfOneShareTheirKeysOnce) {
  // 1000 sweep rows: the keys are written once, each row holds its values (about 9 bytes a number).
  std::vector<json> rows;
  for (int i = 0; i < 1000; ++i)
    rows.push_back({{"frequency_hz", 5.0 + 0.01 * i}, {"amplitude_v", 0.4}, {"first_harmonic_force_n", 0.1 * i}});
  RowBlockWriter writer;
  for (const json& r : rows) writer.Add(r);
  const std::string block = writer.Finish();
  EXPECT_LT(block.size(), 1000u * (1 + 3 * 9) + 100);
  EXPECT_EQ(DecodeRowBlock(block), rows);
}

TEST(RowBlock, RecordsDecodeAsTheObjectsTheyStandFor) {
  // Cells in column order (jobs::ResultRecords, as sweep tasks return them), beside object rows in
  // the same block: each record comes back as the object {column: cell}, numbers bit for bit.
  const std::vector<std::string> columns = {"frequency_hz", "amplitude_v", "branch", "period", "max_multiplier"};
  const std::vector<json> cells = {5.0, 0.4, "up", 1, nullptr,  //
                                   5.1, 0.4, "unstable", "aperiodic", -0.0,
                                   1.0 / 3.0, 0.4, "down", 2, 1e-300};
  RowBlockWriter writer;
  writer.Add({{"name", "k3"}, {"value", -1.5e5}});
  writer.AddRecords(columns, cells);
  writer.AddRecords(columns, {});  // no rows
  writer.Add({{"frequency_hz", 9.0}, {"amplitude_v", 0.4}, {"branch", "up"}, {"period", 1}, {"max_multiplier", 0.5}});
  EXPECT_EQ(writer.rows(), 5);
  const std::vector<json> back = DecodeRowBlock(writer.Finish());
  ASSERT_EQ(back.size(), 5u);
  EXPECT_EQ(back[0], json({{"name", "k3"}, {"value", -1.5e5}}));
  for (size_t r = 0; r < 3; ++r) {
    json expected = json::object();
    for (size_t c = 0; c < columns.size(); ++c) expected[columns[c]] = cells[r * columns.size() + c];
    EXPECT_EQ(back[1 + r].dump(), expected.dump()) << r;
  }
  EXPECT_EQ(DoubleBits(back[2].at("max_multiplier").get<double>()), DoubleBits(-0.0));
  EXPECT_EQ(back[4].at("max_multiplier"), 0.5);
  // Cells that do not fill whole rows are refused.
  EXPECT_THROW(writer.AddRecords(columns, {1.0, 2.0}), StoreError);
  EXPECT_THROW(writer.AddRecords({}, {1.0}), StoreError);
}

TEST(RowBlock, ADamagedBlockIsRefusedNotReadPastItsEnd) {
  RowBlockWriter writer;
  for (const json& r : MixedBlockRows()) writer.Add(r);
  const std::string block = writer.Finish();
  // Every proper prefix is cut short somewhere.
  for (size_t n = 0; n < block.size(); ++n) {
    EXPECT_THROW(DecodeRowBlock(std::string_view(block).substr(0, n)), StoreError) << "prefix of " << n << " bytes";
  }
  EXPECT_THROW(DecodeRowBlock(block + "x"), StoreError);
  try {
    DecodeRowBlock("JSON");
    FAIL();
  } catch (const StoreError& e) {
    EXPECT_NE(std::string(e.what()).find("a stored result block is damaged (not a result block)"), std::string::npos)
        << e.what();
  }
  // Any single changed byte decodes to something or is refused; it is never read out of bounds (the
  // sanitizer build watches) and never takes more than the block's size in items.
  std::mt19937 rng(17);
  for (int trial = 0; trial < 4000; ++trial) {
    std::string bad = block;
    bad[rng() % bad.size()] = static_cast<char>(rng());
    try {
      const std::vector<json> rows = DecodeRowBlock(bad);
      EXPECT_LE(rows.size(), bad.size());
    } catch (const StoreError&) {
    }
  }
  // A count larger than the bytes left, and nesting deeper than any row has.
  const std::string huge_count = std::string("SLB1") + '\0' + "\xff\xff\xff\xff\x0f";
  EXPECT_THROW(DecodeRowBlock(huge_count), StoreError);
  std::string deep = std::string("SLB1") + '\0' + '\1' + '\0';
  for (int i = 0; i < 100; ++i) deep += std::string("\x07\x01", 2);  // arrays of one array of ...
  deep += '\0';
  EXPECT_THROW(DecodeRowBlock(deep), StoreError);
}

}  // namespace
}  // namespace strokelab::server::internal
