// A column-oriented table written as CSV (header line, then one row per index; NaN as empty).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace strokelab::report {

// A number as a CSV cell: the fewest digits that read back to the same double, laid out as %g does
// (0.0009, 1.5e-05, 12345678), or empty when not finite.
std::string CsvNumber(double value);


class CsvTable {
 public:
  explicit CsvTable(std::vector<std::string> columns);
  // Sets a declared column's values.
  void SetColumn(const std::string& name, const std::vector<double>& values);
  // Appends a new column.
  void AddColumn(const std::string& name, const std::vector<double>& values);
  size_t rows() const;
  std::string ToString() const;
  void Write(const std::filesystem::path& path) const;  // throws std::runtime_error on failure

 private:
  std::vector<std::string> names_;
  std::vector<std::vector<double>> columns_;
};

}  // namespace strokelab::report
