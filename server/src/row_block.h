// A result block: the rows of one table of one task as one compact binary value, the unit the job
// store writes and reads (store_results.cc). Rows of a table share their keys, so a block names
// each distinct key list once and stores the rows' values in that order, numbers as their 8 bytes:
// a sweep row of 14 fields takes ~130 bytes against ~440 as JSON text, and needs no number
// formatting. Decoding gives back the same JSON values (numbers bit for bit; integers keep their
// sign, an unsigned one may come back from a signed one of the same value). Internal to the store.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

namespace strokelab::server::internal {

// Appends rows to a block. Any JSON value is a row; objects are the common case.
class RowBlockWriter {
 public:
  void Add(const nlohmann::json& row);
  // Rows given as cells in the order of `columns` (jobs::ResultRecords), each encoded as Add encodes
  // the object {column: cell, ...} it stands for, without building it.
  void AddRecords(const std::vector<std::string>& columns, const std::vector<nlohmann::json>& cells);
  int64_t rows() const { return rows_; }
  // The block: header (its key lists), then the rows.
  std::string Finish() const;

 private:
  size_t KeyListOf(const nlohmann::json& object);  // 1-based index into key_lists_, added if new
  size_t KeyListOf(const std::vector<std::string>& keys);
  std::vector<std::vector<std::string>> key_lists_;
  size_t last_key_list_ = 0;
  std::string body_;
  int64_t rows_ = 0;
};

// The rows of a block, in order. Throws StoreError when the bytes are not a well-formed block.
std::vector<nlohmann::json> DecodeRowBlock(std::string_view block);

}  // namespace strokelab::server::internal
