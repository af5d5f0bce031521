#include "strokelab/report/csv_table.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>

#include "strokelab/base/errors.h"

namespace strokelab::report {

std::string CsvNumber(double value) {
  if (!std::isfinite(value)) return "";
  char text[32];
  const auto result = std::to_chars(text, text + sizeof text, value, std::chars_format::general);
  return std::string(text, result.ptr);
}

CsvTable::CsvTable(std::vector<std::string> columns) : names_(std::move(columns)), columns_(names_.size()) {}

void CsvTable::SetColumn(const std::string& name, const std::vector<double>& values) {
  const auto it = std::find(names_.begin(), names_.end(), name);
  if (it == names_.end()) BrokenInvariant("CsvTable: undeclared column " + name);
  columns_[static_cast<size_t>(it - names_.begin())] = values;
}

void CsvTable::AddColumn(const std::string& name, const std::vector<double>& values) {
  names_.push_back(name);
  columns_.push_back(values);
}

size_t CsvTable::rows() const {
  size_t n = 0;
  for (const auto& c : columns_) n = std::max(n, c.size());
  return n;
}

std::string CsvTable::ToString() const {
  std::string text;
  for (size_t i = 0; i < names_.size(); ++i) text += (i ? "," : "") + names_[i];
  text += "\n";
  for (size_t r = 0; r < rows(); ++r) {
    for (size_t i = 0; i < columns_.size(); ++i) {
      if (i) text += ",";
      if (r < columns_[i].size()) text += CsvNumber(columns_[i][r]);
    }
    text += "\n";
  }
  return text;
}

void CsvTable::Write(const std::filesystem::path& path) const {
  std::ofstream out(path);
  out << ToString();
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

}  // namespace strokelab::report
