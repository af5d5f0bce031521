// Result blocks (row_block.h). Layout, integers as unsigned LEB128 varints:
//   "SLB1"
//   key lists: count, then each: key count, then each key: length, bytes
//   rows:      count, then each: its key list's 1-based index k, then
//              k >= 1: the object's values in that list's key order; k = 0: one value (not an object)
//   value:     tag byte, then 0 null | 1 false | 2 true | 3 signed integer (zigzag varint)
//              | 4 unsigned integer (varint) | 5 double (8 bytes, IEEE 754, little-endian)
//              | 6 string (length, bytes) | 7 array (count, values) | 8 object (count, (key, value)...)
#include "row_block.h"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>

#include "strokelab/server/store.h"

namespace strokelab::server::internal {
namespace {

using nlohmann::json;

static_assert(std::endian::native == std::endian::little, "result blocks store doubles in host order");

constexpr std::string_view kMagic = "SLB1";
constexpr int kMaxDepth = 64;  // nesting a decoded block may have (the rows nest 2-3 deep)

enum Tag : uint8_t { kNull, kFalse, kTrue, kSigned, kUnsigned, kDouble, kString, kArray, kObject };

void PutVarint(std::string& out, uint64_t v) {
  while (v >= 0x80) {
    out.push_back(static_cast<char>((v & 0x7f) | 0x80));
    v >>= 7;
  }
  out.push_back(static_cast<char>(v));
}

void PutString(std::string& out, std::string_view s) {
  PutVarint(out, s.size());
  out.append(s);
}

void PutValue(std::string& out, const json& v) {
  switch (v.type()) {
    case json::value_t::null: out.push_back(kNull); break;
    case json::value_t::boolean: out.push_back(v.get<bool>() ? kTrue : kFalse); break;
    case json::value_t::number_integer: {
      const int64_t i = v.get<int64_t>();
      out.push_back(kSigned);
      PutVarint(out, (static_cast<uint64_t>(i) << 1) ^ static_cast<uint64_t>(i >> 63));  // zigzag
      break;
    }
    case json::value_t::number_unsigned:
      out.push_back(kUnsigned);
      PutVarint(out, v.get<uint64_t>());
      break;
    case json::value_t::number_float: {
      const double d = v.get<double>();
      char bytes[sizeof d];
      std::memcpy(bytes, &d, sizeof d);
      out.push_back(kDouble);
      out.append(bytes, sizeof d);
      break;
    }
    case json::value_t::string:
      out.push_back(kString);
      PutString(out, v.get_ref<const std::string&>());
      break;
    case json::value_t::array:
      out.push_back(kArray);
      PutVarint(out, v.size());
      for (const json& e : v) PutValue(out, e);
      break;
    case json::value_t::object:
      out.push_back(kObject);
      PutVarint(out, v.size());
      for (const auto& [key, e] : v.items()) {
        PutString(out, key);
        PutValue(out, e);
      }
      break;
    default: throw StoreError("job store: a result row holds a value JSON cannot write (binary)");
  }
}

bool SameKeys(const std::vector<std::string>& keys, const json& object) {
  if (keys.size() != object.size()) return false;
  size_t i = 0;
  for (const auto& [key, value] : object.items())
    if (keys[i++] != key) return false;
  return true;
}

// Reads a block front to back; every read checks the bounds.
class Reader {
 public:
  explicit Reader(std::string_view bytes) : bytes_(bytes) {}

  [[noreturn]] static void Damaged(const char* what) {
    throw StoreError(std::string("job store: a stored result block is damaged (") + what +
                     "); restore the database from a backup");
  }
  bool AtEnd() const { return pos_ == bytes_.size(); }
  std::string_view Bytes(uint64_t n) {
    if (n > bytes_.size() - pos_) Damaged("cut short");
    const std::string_view s = bytes_.substr(pos_, n);
    pos_ += n;
    return s;
  }
  uint8_t Byte() { return static_cast<uint8_t>(Bytes(1)[0]); }
  uint64_t Varint() {
    uint64_t v = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      const uint8_t b = Byte();
      v |= static_cast<uint64_t>(b & 0x7f) << shift;
      if (!(b & 0x80)) return v;
    }
    Damaged("an integer runs over 64 bits");
  }
  // A count of items that take at least one byte each: never more than the bytes left.
  uint64_t Count() {
    const uint64_t n = Varint();
    if (n > bytes_.size() - pos_) Damaged("a count exceeds the block");
    return n;
  }
  std::string String() {
    const std::string_view s = Bytes(Varint());
    return std::string(s);
  }
  json Value(int depth) {
    if (depth > kMaxDepth) Damaged("nested too deep");
    switch (Byte()) {
      case kNull: return nullptr;
      case kFalse: return false;
      case kTrue: return true;
      case kSigned: {
        const uint64_t z = Varint();
        return static_cast<int64_t>((z >> 1) ^ (~(z & 1) + 1));
      }
      case kUnsigned: return Varint();
      case kDouble: {
        double d;
        std::memcpy(&d, Bytes(sizeof d).data(), sizeof d);
        return d;
      }
      case kString: return String();
      case kArray: {
        json a = json::array();
        for (uint64_t n = Count(); n > 0; --n) a.push_back(Value(depth + 1));
        return a;
      }
      case kObject: {
        json o = json::object();
        for (uint64_t n = Count(); n > 0; --n) {
          std::string key = String();
          o[std::move(key)] = Value(depth + 1);
        }
        return o;
      }
      default: Damaged("unknown value tag");
    }
  }

 private:
  std::string_view bytes_;
  size_t pos_ = 0;
};

}  // namespace

size_t RowBlockWriter::KeyListOf(const json& object) {
  if (last_key_list_ > 0 && SameKeys(key_lists_[last_key_list_ - 1], object)) return last_key_list_;
  for (size_t k = 0; k < key_lists_.size(); ++k)
    if (SameKeys(key_lists_[k], object)) return last_key_list_ = k + 1;
  std::vector<std::string>& keys = key_lists_.emplace_back();
  for (const auto& [key, value] : object.items()) keys.push_back(key);
  return last_key_list_ = key_lists_.size();
}

size_t RowBlockWriter::KeyListOf(const std::vector<std::string>& keys) {
  const auto it = std::find(key_lists_.begin(), key_lists_.end(), keys);
  if (it != key_lists_.end()) return last_key_list_ = static_cast<size_t>(it - key_lists_.begin()) + 1;
  key_lists_.push_back(keys);
  return last_key_list_ = key_lists_.size();
}

void RowBlockWriter::AddRecords(const std::vector<std::string>& columns, const std::vector<json>& cells) {
  if (columns.empty() || cells.size() % columns.size() != 0)
    throw StoreError("job store: a table of records whose cells do not fill its rows");
  const size_t rows = cells.size() / columns.size();
  const size_t key_list = KeyListOf(columns);
  body_.reserve(body_.size() + rows + cells.size() * (1 + sizeof(double)));  // numbers: tag and 8 bytes
  for (size_t r = 0; r < rows; ++r) {
    PutVarint(body_, key_list);
    for (size_t c = 0; c < columns.size(); ++c) PutValue(body_, cells[r * columns.size() + c]);
  }
  rows_ += static_cast<int64_t>(rows);
}

void RowBlockWriter::Add(const json& row) {
  ++rows_;
  if (!row.is_object()) {
    PutVarint(body_, 0);
    PutValue(body_, row);
    return;
  }
  PutVarint(body_, KeyListOf(row));
  for (const auto& [key, value] : row.items()) PutValue(body_, value);
}

std::string RowBlockWriter::Finish() const {
  std::string out(kMagic);
  PutVarint(out, key_lists_.size());
  for (const std::vector<std::string>& keys : key_lists_) {
    PutVarint(out, keys.size());
    for (const std::string& key : keys) PutString(out, key);
  }
  PutVarint(out, static_cast<uint64_t>(rows_));
  out.reserve(out.size() + body_.size());
  out += body_;
  return out;
}

std::vector<json> DecodeRowBlock(std::string_view block) {
  Reader in(block);
  if (in.Bytes(kMagic.size()) != kMagic) Reader::Damaged("not a result block");
  std::vector<std::vector<std::string>> key_lists(in.Count());
  for (std::vector<std::string>& keys : key_lists) {
    keys.resize(in.Count());
    for (std::string& key : keys) key = in.String();
  }
  std::vector<json> rows(in.Count());
  for (json& row : rows) {
    const uint64_t k = in.Varint();
    if (k == 0) {
      row = in.Value(1);
      continue;
    }
    if (k > key_lists.size()) Reader::Damaged("a row names a key list the block lacks");
    row = json::object();
    for (const std::string& key : key_lists[k - 1]) row[key] = in.Value(1);
  }
  if (!in.AtEnd()) Reader::Damaged("bytes after the last row");
  return rows;
}

}  // namespace strokelab::server::internal
