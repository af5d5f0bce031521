// One record's CSV file (strokelab/data/recordings.h): read in one piece, parsed with
// std::from_chars, its time column checked against the manifest's sample rate, made a Recording.
// Every error names the file and line.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "format_number.h"
#include "recordings_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/data/recordings.h"

namespace strokelab::data_internal {
namespace {

namespace fs = std::filesystem;
// A rate estimated from a time column printed to a few digits: 6 significant digits.
std::string Rate(double value) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.6g", value);
  return buffer;
}

class CsvError {
 public:
  explicit CsvError(const std::string& file) : file_(file) {}
  [[noreturn]] void At(size_t line, const std::string& message) const {
    throw InputError(file_ + ":" + std::to_string(line), message);
  }

 private:
  const std::string& file_;
};

std::vector<std::string> SplitHeader(std::string_view line) {
  std::vector<std::string> names;
  size_t start = 0;
  while (true) {
    const size_t comma = line.find(',', start);
    std::string_view cell =
        Trim(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start));
    if (cell.size() >= 2 && cell.front() == '"' && cell.back() == '"') cell = cell.substr(1, cell.size() - 2);
    names.emplace_back(cell);
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  return names;
}

std::string JoinNames(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& name : names) out += (out.empty() ? "" : ",") + name;
  return out;
}

size_t CountCells(const char* begin, const char* end) { return 1 + static_cast<size_t>(std::count(begin, end, ',')); }

// One CSV file's samples; raw sensor volts in `response`.
struct CsvRecord {
  std::vector<double> time_s, voltage_v, response;
};

enum Role : signed char { kIgnored = -1, kTime = 0, kVoltage = 1, kResponse = 2 };

// Parses a numeric cell [begin, end) of a data row.
inline double ParseCell(const char* begin, const char* end, const CsvError& error, size_t line,
                        const std::string& column, const char* row_begin, const char* row_end, size_t columns) {
  while (begin < end && IsBlank(*begin)) ++begin;
  while (end > begin && IsBlank(end[-1])) --end;
  const char* number = begin;
  if (number < end && *number == '+') ++number;  // from_chars takes no '+'
  double value = 0.0;
  auto [ptr, ec] = std::from_chars(number, end, value);
  if (number > begin && number < end && (*number == '-' || *number == '+')) ec = std::errc::invalid_argument;  // "+-1"
  if (ec == std::errc() && ptr == end && std::isfinite(value)) return value;

  // The rare paths: say what is wrong, preferring a wrong cell count (a truncated row) to a
  // complaint about a half-written number.
  const size_t cells = CountCells(row_begin, row_end);
  if (cells != columns)
    error.At(line, "row has " + std::to_string(cells) + " columns, the header has " + std::to_string(columns) +
                       (cells < columns ? " (truncated row?)" : ""));
  const std::string text(begin, end);
  if (text.empty()) error.At(line, "empty cell in column '" + column + "'");
  if (ec == std::errc::result_out_of_range && ptr == end) {
    value = std::strtod(text.c_str(), nullptr);  // underflow gives 0 or a subnormal, overflow inf
    if (std::isfinite(value)) return value;
    error.At(line, "column '" + column + "': '" + text + "' is out of range");
  }
  if (ec != std::errc() || ptr != end) error.At(line, "column '" + column + "': '" + text + "' is not a number");
  error.At(line, "column '" + column + "': non-finite value '" + text + "'");
}

CsvRecord ParseCsv(std::string_view text, const std::string& file, const Channels& channels) {
  const CsvError error(file);
  const char* p = text.data();
  const char* const end = p + text.size();
  if (text.size() >= 3 && std::memcmp(p, "\xEF\xBB\xBF", 3) == 0) p += 3;  // UTF-8 byte-order mark

  // Header.
  const char* eol = static_cast<const char*>(std::memchr(p, '\n', end - p));
  if (!eol) eol = end;
  std::string_view header_line(p, eol - p);
  if (!header_line.empty() && header_line.back() == '\r') header_line.remove_suffix(1);
  if (Trim(header_line).empty())
    error.At(1, p == end ? "empty file; expected a header line naming the columns (time_s,...)"
                         : "empty header line; expected the column names (time_s,...)");
  const std::vector<std::string> names = SplitHeader(header_line);
  const size_t columns = names.size();
  std::vector<Role> roles(columns, kIgnored);
  const std::string* wanted[3] = {nullptr, &channels.voltage_column, &channels.response_column};
  const std::string time_name = "time_s";
  wanted[kTime] = &time_name;
  for (size_t c = 0; c < columns; ++c) {
    for (int role = 0; role < 3; ++role)
      if (names[c] == *wanted[role]) roles[c] = static_cast<Role>(role);
  }
  // A missing column first: a file without a header line has numbers there, often repeated.
  for (int role = 0; role < 3; ++role) {
    if (std::find(roles.begin(), roles.end(), static_cast<Role>(role)) == roles.end())
      error.At(1, "no column '" + *wanted[role] + "' (header: " + JoinNames(names) + ")");
  }
  for (size_t c = 0; c < columns; ++c) {
    if (names[c].empty()) error.At(1, "column " + std::to_string(c + 1) + " of the header has no name");
    for (size_t d = 0; d < c; ++d)
      if (names[d] == names[c]) error.At(1, "column '" + names[c] + "' appears twice in the header");
  }

  CsvRecord out;
  const size_t estimate = static_cast<size_t>(std::count(eol, end, '\n')) + 1;
  out.time_s.reserve(estimate);
  out.voltage_v.reserve(estimate);
  out.response.reserve(estimate);
  std::vector<double>* targets[3] = {&out.time_s, &out.voltage_v, &out.response};

  size_t line = 1;
  p = eol < end ? eol + 1 : end;
  double row[3] = {0, 0, 0};
  while (p < end) {
    ++line;
    const char* line_end = static_cast<const char*>(std::memchr(p, '\n', end - p));
    if (!line_end) line_end = end;
    const char* row_end = line_end;
    if (row_end > p && row_end[-1] == '\r') --row_end;
    if (row_end == p || std::all_of(p, row_end, IsBlank)) {
      // Blank lines are allowed only at the very end of the file.
      if (std::all_of(p, end, [](char c) { return IsBlank(c) || c == '\r' || c == '\n'; })) break;
      error.At(line, "blank line among the data rows");
    }
    const char* cell = p;
    size_t column = 0;
    while (true) {
      const char* comma = static_cast<const char*>(std::memchr(cell, ',', row_end - cell));
      const char* cell_end = comma ? comma : row_end;
      if (column < columns && roles[column] != kIgnored)
        row[roles[column]] = ParseCell(cell, cell_end, error, line, names[column], p, row_end, columns);
      ++column;
      if (!comma) break;
      cell = comma + 1;
    }
    if (column != columns)
      error.At(line, "row has " + std::to_string(column) + " columns, the header has " + std::to_string(columns) +
                         (column < columns ? " (truncated row?)" : ""));
    for (int role = 0; role < 3; ++role) targets[role]->push_back(row[role]);
    p = line_end < end ? line_end + 1 : end;
  }
  if (out.time_s.empty()) error.At(2, "no samples: the file ends after its header");
  if (out.time_s.size() < 2) error.At(2, "a single sample; a record needs at least 2");
  return out;
}

// The time column against uniform sampling from 0 at `sample_rate_hz` (recordings.h: start,
// uniform, rate). Row n is on line n + 2.
void CheckTimeColumn(const std::vector<double>& t, double sample_rate_hz, const std::string& rate_source,
                     const std::string& file) {
  const CsvError error(file);
  const double dt = 1.0 / sample_rate_hz;
  const auto tolerance = [&](double time_s) {
    return kTimeToleranceSamples * dt + kTimeRelativeTolerance * std::abs(time_s);
  };
  const size_t count = t.size();
  if (std::abs(t[0]) > tolerance(0.0))
    error.At(2, "time column starts at t = " + Num(t[0]) + " s; the first sample must be at t = 0");

  // Least-squares slope of t against n: the column's own mean step (its rate, for messages).
  const double n_mean = 0.5 * static_cast<double>(count - 1);
  double t_mean = 0.0;
  for (double time : t) t_mean += time;
  t_mean /= static_cast<double>(count);
  double covariance = 0.0;
  for (size_t n = 0; n < count; ++n) covariance += (static_cast<double>(n) - n_mean) * (t[n] - t_mean);
  const double nd = static_cast<double>(count);
  const double step = covariance / (nd * (nd * nd - 1.0) / 12.0);

  // Each step against the median step, which a glitch, a dropped or a repeated sample cannot move.
  std::vector<double> steps(count - 1);
  for (size_t n = 1; n < count; ++n) steps[n - 1] = t[n] - t[n - 1];
  std::nth_element(steps.begin(), steps.begin() + static_cast<long>(steps.size() / 2), steps.end());
  const double median_step = steps[steps.size() / 2];
  for (size_t n = 1; n < count; ++n) {
    const double this_step = t[n] - t[n - 1];
    if (std::abs(this_step - median_step) > kTimeToleranceSamples * dt + 2.0 * kTimeRelativeTolerance * std::abs(t[n]))
      error.At(n + 2, "time column is not uniform: it steps by " + Num(this_step) + " s to t = " + Num(t[n]) +
                          " s, against " + Num(median_step) + " s elsewhere");
  }
  for (size_t n = 1; n < count; ++n) {
    const double expected = static_cast<double>(n) * dt;
    if (std::abs(t[n] - expected) > tolerance(t[n]))
      error.At(n + 2, "sample_rate_hz " + Num(sample_rate_hz) + " of " + rate_source +
                          " disagrees with the time column's " + Rate(1.0 / step) + " Hz (t = " + Num(t[n]) +
                          " s on this row, expected " + Num(expected) + " s)");
  }
}

}  // namespace

bool ReadWholeFile(const fs::path& path, std::string* text) {
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (!file) return false;
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> closer(file, &std::fclose);
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  text->clear();
  if (!ec) {
    text->resize(size);
    const size_t got = std::fread(text->data(), 1, size, file);
    text->resize(got);
  }
  // Whatever is left (a file that grew, or one whose size the file system does not report).
  char buffer[65536];
  size_t n;
  while ((n = std::fread(buffer, 1, sizeof buffer, file)) > 0) text->append(buffer, n);
  return !std::ferror(file);
}

Recording ReadRecord(const fs::path& dir, const RecordSpec& spec, const Channels& channels) {
  std::string text;
  if (!ReadWholeFile(dir / spec.file, &text))
    ManifestError(spec.pointer + "/file", "cannot read '" + spec.file + "' in " + dir.string());
  CsvRecord csv = ParseCsv(text, spec.file, channels);
  text = std::string();
  CheckTimeColumn(csv.time_s, spec.sample_rate_hz,
                  spec.rate_from_record ? std::string(kManifestName) + ":" + spec.pointer : kManifestName, spec.file);
  Recording record;
  record.name = spec.file;
  record.sample_rate_hz = spec.sample_rate_hz;
  record.voltage_v = std::move(csv.voltage_v);
  record.response = std::move(csv.response);
  for (double& value : record.response) value /= channels.sensitivity;
  record.broadband = spec.broadband;
  record.nominal_frequency_hz = spec.frequency_hz;
  record.nominal_amplitude_v = spec.amplitude_v;
  return record;
}

}  // namespace strokelab::data_internal
