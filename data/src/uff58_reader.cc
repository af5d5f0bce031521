// Reading UFF files (strokelab/data/uff58.h): datasets found between "-1" lines, datasets 58 parsed
// from their fixed-width ASCII records, values from ASCII lines or 58b bytes. Every error names the
// file, the dataset's index and the line or byte offset.
#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "format_number.h"
#include "strokelab/base/errors.h"
#include "strokelab/data/uff58.h"

namespace strokelab {
namespace {

using data_internal::Num;

std::string_view TrimUff(std::string_view text) {
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.front()))) text.remove_prefix(1);
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back()))) text.remove_suffix(1);
  return text;
}

// A fixed-width field [begin, begin + width) of a line, trimmed ("" past its end).
std::string_view UffField(std::string_view line, size_t begin, size_t width) {
  if (begin >= line.size()) return {};
  return TrimUff(line.substr(begin, width));
}

std::optional<long long> UffInteger(std::string_view text) {
  if (!text.empty() && text.front() == '+') text.remove_prefix(1);
  long long value = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || ptr != text.data() + text.size() || text.empty()) return std::nullopt;
  return value;
}

// A Fortran real: E or D exponent, optional '+'.
std::optional<double> UffReal(std::string_view text) {
  char buffer[64];
  if (text.empty() || text.size() >= sizeof buffer) return std::nullopt;
  size_t n = 0;
  for (char c : text) buffer[n++] = (c == 'D' || c == 'd') ? 'E' : c;
  const char* begin = buffer;
  if (*begin == '+') ++begin;
  if (begin < buffer + n && (*begin == '+' || *begin == '-') && begin > buffer) return std::nullopt;
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(begin, buffer + n, value);
  if (ptr != buffer + n) return std::nullopt;
  if (ec == std::errc::result_out_of_range) {
    // from_chars refuses values below the normal range; they are numbers (a subnormal, or 0 beyond
    // it), as the CSV reader's strtod takes them. Above the range is inf, refused below.
    buffer[n] = '\0';
    value = std::strtod(begin, nullptr);
  } else if (ec != std::errc()) {
    return std::nullopt;
  }
  if (!std::isfinite(value)) return std::nullopt;
  return value;
}

const char* FunctionTypeName(long long type) {
  static const char* const kNames[] = {"general or unknown", "time response", "auto spectrum", "cross spectrum",
                                       "frequency response function", "transmissibility", "coherence",
                                       "auto correlation", "cross correlation", "power spectral density",
                                       "energy spectral density", "probability density function", "spectrum",
                                       "cumulative frequency distribution", "peaks valley", "stress/cycles",
                                       "strain/cycles", "orbit", "mode indicator function", "force pattern",
                                       "partial power", "partial coherence", "eigenvalue", "eigenvector",
                                       "shock response spectrum", "finite impulse response function",
                                       "multiple coherence", "order function"};
  return type >= 0 && type < static_cast<long long>(std::size(kNames)) ? kNames[type] : "unknown";
}

const char* DataTypeName(long long type) {
  switch (type) {
    case 0: return "unknown";
    case 1: return "general";
    case 2: return "stress";
    case 3: return "strain";
    case 5: return "temperature";
    case 6: return "heat flux";
    case 8: return "displacement";
    case 9: return "reaction force";
    case 11: return "velocity";
    case 12: return "acceleration";
    case 13: return "excitation force";
    case 15: return "pressure";
    case 16: return "mass";
    case 17: return "time";
    case 18: return "frequency";
    case 19: return "rpm";
    case 20: return "order";
    default: return "other";
  }
}

// The file as lines, with the position of each, walked once.
class UffCursor {
 public:
  UffCursor(std::string_view bytes, const std::string& file) : bytes_(bytes), file_(file) {}

  bool AtEnd() const { return pos_ >= bytes_.size(); }
  size_t pos() const { return pos_; }
  size_t line() const { return line_; }  // the line last returned by Next

  // The next line without its line end; nullopt at the end of the file.
  std::optional<std::string_view> Next() {
    if (AtEnd()) return std::nullopt;
    const size_t eol = bytes_.find('\n', pos_);
    const size_t end = eol == std::string_view::npos ? bytes_.size() : eol;
    std::string_view out = bytes_.substr(pos_, end - pos_);
    if (!out.empty() && out.back() == '\r') out.remove_suffix(1);
    pos_ = eol == std::string_view::npos ? bytes_.size() : eol + 1;
    ++line_;
    return out;
  }

  // Skips `count` bytes (a binary block), counting the line ends in it.
  void SkipBytes(size_t count) {
    line_ += static_cast<size_t>(std::count(bytes_.begin() + static_cast<long>(pos_),
                                            bytes_.begin() + static_cast<long>(pos_ + count), '\n'));
    pos_ += count;
  }
  // A line end right after a binary block (some writers put one before the closing "-1").
  void SkipLineEnd() {
    if (pos_ < bytes_.size() && bytes_[pos_] == '\r') ++pos_;
    if (pos_ < bytes_.size() && bytes_[pos_] == '\n') {
      ++pos_;
      ++line_;
    }
  }

  [[noreturn]] void ErrorAtLine(size_t line, size_t dataset, const std::string& kind, const std::string& message) const {
    throw InputError(file_ + ":" + std::to_string(line), "dataset " + std::to_string(dataset) + " (" + kind + "): " + message);
  }
  [[noreturn]] void ErrorAtByte(size_t byte, size_t dataset, const std::string& kind, const std::string& message) const {
    throw InputError(file_ + ":byte " + std::to_string(byte),
                     "dataset " + std::to_string(dataset) + " (" + kind + "): " + message);
  }

  std::string_view bytes() const { return bytes_; }

 private:
  std::string_view bytes_;
  const std::string& file_;
  size_t pos_ = 0;
  size_t line_ = 0;
};

// The binary header's fields after "58b" (or "2414b", ...): byte ordering, floating-point format,
// ASCII lines, bytes.
struct UffBinaryHeader {
  long long byte_ordering = 0, fp_format = 0, ascii_lines = 0, bytes = 0;
};

struct UffTypeLine {
  long long type = 0;
  bool binary = false;
  UffBinaryHeader header;
};

UffTypeLine ParseUffTypeLine(std::string_view line, size_t line_number, size_t index, const UffCursor& cursor) {
  UffTypeLine out;
  const std::string_view text = TrimUff(line);
  size_t digits = 0;
  while (digits < text.size() && std::isdigit(static_cast<unsigned char>(text[digits]))) ++digits;
  const auto type = UffInteger(text.substr(0, digits));
  if (!type) cursor.ErrorAtLine(line_number, index, "?", "bad header line: expected the dataset type (I6), got '" + std::string(text.substr(0, 40)) + "'");
  out.type = *type;
  std::string_view rest = text.substr(digits);
  if (!rest.empty() && (rest.front() == 'b' || rest.front() == 'B')) {
    out.binary = true;
    rest.remove_prefix(1);
    long long* fields[] = {&out.header.byte_ordering, &out.header.fp_format, &out.header.ascii_lines, &out.header.bytes};
    for (long long* field : fields) {
      rest = TrimUff(rest);
      const size_t end = std::min(rest.find_first_of(" \t"), rest.size());
      const auto value = UffInteger(rest.substr(0, end));
      if (!value)
        cursor.ErrorAtLine(line_number, index, std::to_string(out.type) + "b",
                           "bad header line: expected byte ordering, floating-point format, ASCII lines and bytes "
                           "after '" + std::to_string(out.type) + "b'");
      *field = *value;
      rest.remove_prefix(end);
    }
  } else if (!TrimUff(rest).empty() && !std::isspace(static_cast<unsigned char>(rest.front()))) {
    cursor.ErrorAtLine(line_number, index, "?", "bad header line: expected the dataset type (I6), got '" + std::string(text.substr(0, 40)) + "'");
  }
  return out;
}

bool IsUffDelimiter(std::string_view line) { return TrimUff(line) == "-1"; }

// Skips a dataset that is not 58 up to its closing "-1".
void SkipUffDataset(UffCursor& cursor, const UffTypeLine& type, size_t index, size_t open_line) {
  const std::string kind = std::to_string(type.type) + (type.binary ? "b" : "");
  if (type.binary) {
    if (type.header.ascii_lines < 0 || type.header.bytes < 0)
      cursor.ErrorAtLine(open_line + 1, index, kind, "bad header line: negative line or byte count");
    for (long long i = 0; i < type.header.ascii_lines; ++i)
      if (!cursor.Next()) cursor.ErrorAtLine(cursor.line(), index, kind, "truncated dataset: the file ends in its header");
    if (static_cast<unsigned long long>(type.header.bytes) > cursor.bytes().size() - cursor.pos())
      cursor.ErrorAtByte(cursor.pos(), index, kind, "truncated dataset: its header announces " + std::to_string(type.header.bytes) + " bytes, the file holds " + std::to_string(cursor.bytes().size() - cursor.pos()));
    cursor.SkipBytes(static_cast<size_t>(type.header.bytes));
    cursor.SkipLineEnd();
  }
  while (true) {
    const auto line = cursor.Next();
    if (!line) cursor.ErrorAtLine(cursor.line(), index, kind, "truncated dataset: the file ends before its closing -1 (opened on line " + std::to_string(open_line) + ")");
    if (IsUffDelimiter(*line)) return;
  }
}

struct UffAxisRecord {
  long long data_type = 0;
  std::string units;
};

UffAxisRecord ParseUffAxis(std::string_view line, size_t line_number, size_t index, const std::string& kind,
                     const UffCursor& cursor, const char* what) {
  const auto type = UffInteger(UffField(line, 0, 10));
  if (!type)
    cursor.ErrorAtLine(line_number, index, kind,
                       std::string("bad header line: expected the ") + what + "'s specific data type (I10), got '" +
                           std::string(UffField(line, 0, 10)) + "'");
  UffAxisRecord out;
  out.data_type = *type;
  std::string units(UffField(line, 47, 20));
  if (units == "NONE" || units == "none") units.clear();
  out.units = units;
  return out;
}

UffTimeSeries ParseDataset58(UffCursor& cursor, const UffTypeLine& type, size_t index, size_t open_line) {
  const std::string kind = type.binary ? "58b" : "58";
  UffTimeSeries out;
  out.index = index;
  out.line = open_line;
  out.binary = type.binary;
  const size_t type_line = open_line + 1;
  if (type.binary) {
    if (type.header.ascii_lines != 11)
      cursor.ErrorAtLine(type_line, index, kind, "bad header line: " + std::to_string(type.header.ascii_lines) + " ASCII lines announced, dataset 58 has 11");
    if (type.header.fp_format != 2)
      cursor.ErrorAtLine(type_line, index, kind, "floating-point format " + std::to_string(type.header.fp_format) + " is not supported (only 2, IEEE 754)");
    if (type.header.byte_ordering != 1 && type.header.byte_ordering != 2)
      cursor.ErrorAtLine(type_line, index, kind, "byte ordering " + std::to_string(type.header.byte_ordering) + " is not known (1 little-endian, 2 big-endian)");
  }
  std::string_view records[11];
  size_t record_lines[11];
  for (int r = 0; r < 11; ++r) {
    const auto line = cursor.Next();
    if (!line) cursor.ErrorAtLine(cursor.line() + 1, index, kind, "truncated dataset: the file ends in its header (record " + std::to_string(r + 1) + " of 11)");
    if (IsUffDelimiter(*line)) cursor.ErrorAtLine(cursor.line(), index, kind, "truncated dataset: it ends in its header (record " + std::to_string(r + 1) + " of 11)");
    records[r] = *line;
    record_lines[r] = cursor.line();
  }
  out.id1 = std::string(TrimUff(records[0]));

  // Record 6: the function type (I5).
  const auto function = UffInteger(UffField(records[5], 0, 5));
  if (!function)
    cursor.ErrorAtLine(record_lines[5], index, kind, "bad header line: expected the function type (I5), got '" + std::string(UffField(records[5], 0, 5)) + "'");
  if (*function != 1)
    cursor.ErrorAtLine(record_lines[5], index, kind, "function type " + std::to_string(*function) + " (" + FunctionTypeName(*function) + ") is not supported: strokelab reads time responses (function type 1)");
  out.function_type = 1;

  // Record 7: data form (3I10, 3E13.5).
  const std::string_view form = records[6];
  const auto data_type = UffInteger(UffField(form, 0, 10));
  const auto count = UffInteger(UffField(form, 10, 10));
  const auto spacing = UffInteger(UffField(form, 20, 10));
  const auto minimum = UffReal(UffField(form, 30, 13));
  const auto increment = UffReal(UffField(form, 43, 13));
  if (!data_type || !count || !spacing || !minimum || !increment)
    cursor.ErrorAtLine(record_lines[6], index, kind, "bad header line: expected the data form (3I10, 3E13.5: ordinate data type, number of values, abscissa spacing, minimum, increment, z), got '" + std::string(TrimUff(form).substr(0, 80)) + "'");
  if (*data_type == 5 || *data_type == 6)
    cursor.ErrorAtLine(record_lines[6], index, kind, "complex ordinate data (type " + std::to_string(*data_type) + ") is not supported: strokelab reads real time series");
  if (*data_type != 2 && *data_type != 4)
    cursor.ErrorAtLine(record_lines[6], index, kind, "unknown ordinate data type " + std::to_string(*data_type) + " (2 real single, 4 real double)");
  if (*spacing == 0)
    cursor.ErrorAtLine(record_lines[6], index, kind, "uneven abscissa spacing is not supported: strokelab reads evenly sampled time series");
  if (*spacing != 1)
    cursor.ErrorAtLine(record_lines[6], index, kind, "unknown abscissa spacing " + std::to_string(*spacing) + " (1 even, 0 uneven)");
  if (*count < 1)
    cursor.ErrorAtLine(record_lines[6], index, kind, "number of values " + std::to_string(*count) + " (must be >= 1)");
  if (static_cast<unsigned long long>(*count) > cursor.bytes().size())
    cursor.ErrorAtLine(record_lines[6], index, kind, "truncated dataset: record 7 announces " + std::to_string(*count) + " values, the whole file holds " + std::to_string(cursor.bytes().size()) + " bytes");
  if (*increment <= 0 || !std::isfinite(1.0 / *increment))
    cursor.ErrorAtLine(record_lines[6], index, kind, "abscissa increment " + Num(*increment) + " s (must be > 0, with a finite rate)");
  out.abscissa_min_s = *minimum;
  out.increment_s = *increment;

  // Records 8 and 9: abscissa and ordinate characteristics.
  const UffAxisRecord abscissa = ParseUffAxis(records[7], record_lines[7], index, kind, cursor, "abscissa");
  if (abscissa.data_type != 0 && abscissa.data_type != 1 && abscissa.data_type != 17)
    cursor.ErrorAtLine(record_lines[7], index, kind, std::string("the abscissa is ") + DataTypeName(abscissa.data_type) + " (specific data type " + std::to_string(abscissa.data_type) + "), not time");
  if (!abscissa.units.empty() && abscissa.units != "s" && abscissa.units != "sec" && abscissa.units != "S")
    cursor.ErrorAtLine(record_lines[7], index, kind, "the abscissa's units are '" + abscissa.units + "'; strokelab reads time in seconds ('s')");
  const UffAxisRecord ordinate = ParseUffAxis(records[8], record_lines[8], index, kind, cursor, "ordinate");
  out.ordinate_data_type = static_cast<int>(std::clamp<long long>(ordinate.data_type, -1, 1000));
  out.ordinate_units = ordinate.units;

  const size_t n = static_cast<size_t>(*count);
  if (type.binary) {
    const size_t width = *data_type == 2 ? 4 : 8;
    if (type.header.bytes < 0 || static_cast<unsigned long long>(type.header.bytes) != n * width)
      cursor.ErrorAtLine(type_line, index, kind, "wrong record length: the header line announces " + std::to_string(type.header.bytes) + " bytes, record 7 " + std::to_string(n) + " values of " + std::to_string(width) + " bytes (" + std::to_string(n * width) + ")");
    const size_t start = cursor.pos();
    const size_t available = cursor.bytes().size() - start;
    if (n * width > available)
      cursor.ErrorAtByte(start + available, index, kind, "truncated dataset: the file ends " + std::to_string(available) + " bytes into its " + std::to_string(n * width) + " bytes of data");
    const bool swap = (type.header.byte_ordering == 1) != (std::endian::native == std::endian::little);
    out.values.resize(n);
    const char* p = cursor.bytes().data() + start;
    for (size_t i = 0; i < n; ++i, p += width) {
      unsigned char raw[8];
      std::memcpy(raw, p, width);
      if (swap) std::reverse(raw, raw + width);
      double value;
      if (width == 4) {
        float f;
        std::memcpy(&f, raw, 4);
        value = f;
      } else {
        std::memcpy(&value, raw, 8);
      }
      if (!std::isfinite(value)) cursor.ErrorAtByte(start + i * width, index, kind, "value " + std::to_string(i + 1) + " is not finite");
      out.values[i] = value;
    }
    cursor.SkipBytes(n * width);
    cursor.SkipLineEnd();
    const size_t end_byte = cursor.pos();
    const auto close = cursor.Next();
    if (!close || !IsUffDelimiter(*close))
      cursor.ErrorAtByte(end_byte, index, kind, "wrong record length: no closing -1 after its " + std::to_string(n * width) + " bytes of data (the header's byte count is wrong, or the data is longer)");
    return out;
  }

  out.values.reserve(n);
  while (true) {
    const auto line = cursor.Next();
    if (!line) {
      if (out.values.size() < n)
        cursor.ErrorAtLine(cursor.line(), index, kind, "truncated dataset: the file ends after " + std::to_string(out.values.size()) + " of its " + std::to_string(n) + " values");
      cursor.ErrorAtLine(cursor.line(), index, kind, "truncated dataset: the file ends before its closing -1");
    }
    if (IsUffDelimiter(*line)) {
      if (out.values.size() < n)
        cursor.ErrorAtLine(cursor.line(), index, kind, "wrong record length: the dataset ends after " + std::to_string(out.values.size()) + " of the " + std::to_string(n) + " values record 7 announces");
      return out;
    }
    std::string_view rest = *line;
    while (true) {
      rest = TrimUff(rest);
      if (rest.empty()) break;
      const size_t end = std::min(rest.find_first_of(" \t"), rest.size());
      const std::string_view token = rest.substr(0, end);
      rest.remove_prefix(end);
      if (out.values.size() == n)
        cursor.ErrorAtLine(cursor.line(), index, kind, "wrong record length: more than the " + std::to_string(n) + " values record 7 announces");
      const auto value = UffReal(token);
      if (!value) cursor.ErrorAtLine(cursor.line(), index, kind, "'" + std::string(token.substr(0, 40)) + "' is not a finite number");
      out.values.push_back(*value);
    }
  }
}

}  // namespace

UffFile ParseUff58(std::string_view bytes, const std::string& file) {
  UffFile out;
  UffCursor cursor(bytes, file);
  while (true) {
    std::optional<std::string_view> line;
    // Blank lines between datasets are allowed.
    do line = cursor.Next();
    while (line && TrimUff(*line).empty());
    if (!line) break;
    const size_t index = out.datasets.size() + 1;
    if (!IsUffDelimiter(*line))
      cursor.ErrorAtLine(cursor.line(), index, "?", "bad header line: expected -1 opening a dataset, got '" + std::string(TrimUff(*line).substr(0, 40)) + "'");
    const size_t open_line = cursor.line();
    const auto type_text = cursor.Next();
    if (!type_text) cursor.ErrorAtLine(open_line + 1, index, "?", "truncated dataset: the file ends after its opening -1");
    const UffTypeLine type = ParseUffTypeLine(*type_text, cursor.line(), index, cursor);
    UffFile::Entry entry{index, static_cast<int>(std::clamp<long long>(type.type, -1, 1'000'000)), open_line, -1};
    if (type.type == 58) {
      entry.series = static_cast<int>(out.series.size());
      out.series.push_back(ParseDataset58(cursor, type, index, open_line));
    } else {
      SkipUffDataset(cursor, type, index, open_line);
    }
    out.datasets.push_back(entry);
  }
  if (out.datasets.empty())
    throw InputError(file + ":1", "no UFF dataset (a universal file starts each dataset with a line holding -1)");
  return out;
}

}  // namespace strokelab
