// Reading and writing campaign directories (strokelab/recordings.h). The CSV reader reads each file
// in one piece and parses cells with std::from_chars; records are read on several threads and the
// first failing record (in manifest order) is the one reported, so errors do not depend on timing.
#include "strokelab/data/recordings.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string_view>
#include <system_error>
#include <vector>

#include "strokelab/base/errors.h"
#include "strokelab/base/parallel_for.h"
#include "format_number.h"

namespace strokelab {
namespace {

using data_internal::Num;

namespace fs = std::filesystem;
using nlohmann::json;

constexpr ResponseKind kResponseKinds[] = {ResponseKind::kForce, ResponseKind::kAcceleration, ResponseKind::kVelocity,
                                           ResponseKind::kDisplacement};

// A rate estimated from a time column printed to a few digits: 6 significant digits.
std::string Rate(double value) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.6g", value);
  return buffer;
}

std::string Quote(std::string_view text) {
  std::string out = "'";
  out.append(text);
  return out += "'";
}

// ---- Reading a whole file ----------------------------------------------------------------------

// The file's bytes; false if it cannot be opened or read.
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

// ---- Manifest ----------------------------------------------------------------------------------

[[noreturn]] void ManifestError(const std::string& pointer, const std::string& message) {
  throw InputError(std::string(kManifestName) + (pointer.empty() ? "" : ":" + pointer), message);
}

struct Channels {
  std::string voltage_column;
  std::string response_column;
  ResponseKind kind = ResponseKind::kForce;
  double sensitivity = 0.0;  // sensor volts per physical unit
  bool nominal = false;
};

struct RecordSpec {
  std::string file;
  std::string pointer;  // "/records/3"
  double sample_rate_hz = 0.0;
  bool rate_from_record = false;
  bool broadband = false;
  double frequency_hz = 0.0;
  double amplitude_v = 0.0;
};

const json* Find(const json& object, const char* key) {
  const auto it = object.find(key);
  return it == object.end() ? nullptr : &*it;
}

std::string TypeName(const json& value) { return value.type_name(); }

double RequirePositiveRate(const json& value, const std::string& pointer) {
  if (!value.is_number()) ManifestError(pointer, "expected a number [Hz], got " + TypeName(value));
  const double rate = value.get<double>();
  if (!std::isfinite(rate) || rate <= 0) ManifestError(pointer, "must be a finite number > 0, got " + Num(rate));
  return rate;
}

std::string ChannelColumn(const json& channel, const std::string& pointer) {
  if (!channel.is_object()) ManifestError(pointer, "expected an object {\"column\": ..., \"unit\": \"V\"}");
  const json* column = Find(channel, "column");
  if (!column) ManifestError(pointer + "/column", "missing: the CSV column that holds this channel");
  if (!column->is_string() || column->get<std::string>().empty())
    ManifestError(pointer + "/column", "expected a non-empty column name");
  const std::string name = column->get<std::string>();
  if (name == "time_s") ManifestError(pointer + "/column", "'time_s' is the time column, not a channel");
  if (const json* unit = Find(channel, "unit")) {
    if (!unit->is_string() || unit->get<std::string>() != "V")
      ManifestError(pointer + "/unit", "channels are recorded in volts (\"V\"), got " + unit->dump());
  }
  return name;
}

Channels ParseChannels(const json& manifest) {
  const json* channels = Find(manifest, "channels");
  if (!channels) ManifestError("/channels", "missing: expected \"voltage\" and one response channel");
  if (!channels->is_object()) ManifestError("/channels", "expected an object naming the channels");
  Channels out;
  bool have_voltage = false, have_response = false;
  std::string response_name;
  for (const auto& [name, channel] : channels->items()) {
    const std::string pointer = "/channels/" + name;
    if (name == "voltage") {
      out.voltage_column = ChannelColumn(channel, pointer);
      have_voltage = true;
      continue;
    }
    ResponseKind kind;
    try {
      kind = ParseResponseKind(name);
    } catch (const InputError&) {
      ManifestError(pointer,
                    "unknown channel '" + name + "' (known: voltage, force, acceleration, velocity, displacement)");
    }
    if (have_response)
      ManifestError(pointer, "a second response channel ('" + response_name +
                                 "' is one already); a campaign records exactly one");
    have_response = true;
    response_name = name;
    out.kind = kind;
    out.response_column = ChannelColumn(channel, pointer);
    for (ResponseKind other : kResponseKinds) {
      if (other != kind && Find(channel, SensitivityKey(other)))
        ManifestError(pointer + "/" + SensitivityKey(other), std::string("is the key of ") + ToString(other) +
                                                                 " channels; a " + name + " channel takes " +
                                                                 SensitivityKey(kind));
    }
    const json* sensitivity = Find(channel, SensitivityKey(kind));
    if (!sensitivity) ManifestError(pointer, std::string("missing ") + SensitivityKey(kind));
    const std::string sensitivity_pointer = pointer + "/" + SensitivityKey(kind);
    if (!sensitivity->is_number())
      ManifestError(sensitivity_pointer, "expected a number, got " + TypeName(*sensitivity));
    out.sensitivity = sensitivity->get<double>();
    if (!std::isfinite(out.sensitivity) || out.sensitivity == 0)
      ManifestError(sensitivity_pointer, "must be a finite number other than 0, got " + Num(out.sensitivity));
    if (const json* nominal = Find(channel, "nominal")) {
      if (!nominal->is_boolean()) ManifestError(pointer + "/nominal", "expected true or false");
      out.nominal = nominal->get<bool>();
    }
  }
  if (!have_voltage) ManifestError("/channels", "no 'voltage' channel");
  if (!have_response)
    ManifestError("/channels", "no response channel (one of force, acceleration, velocity, displacement)");
  if (out.voltage_column == out.response_column)
    ManifestError("/channels/" + response_name + "/column",
                  "'" + out.response_column + "' is the voltage channel's column too");
  return out;
}

// A relative path inside the campaign directory.
void CheckFileName(const std::string& file, const std::string& pointer) {
  const fs::path path(file);
  if (path.is_absolute() || path.has_root_name() || path.has_root_directory())
    ManifestError(pointer, "'" + file + "' is not a path relative to the campaign directory");
  for (const fs::path& part : path) {
    if (part == "..") ManifestError(pointer, "'" + file + "' leaves the campaign directory");
  }
  if (file.back() == '/') ManifestError(pointer, "'" + file + "' names a directory");
}

std::vector<RecordSpec> ParseRecords(const json& manifest, double sample_rate_hz) {
  const json* records = Find(manifest, "records");
  if (!records) ManifestError("/records", "missing: expected a list of records");
  if (!records->is_array()) ManifestError("/records", "expected a list of records");
  if (records->empty()) ManifestError("/records", "no records");
  std::vector<RecordSpec> out;
  std::map<std::string, std::string> files;  // file -> pointer of its first use
  for (size_t i = 0; i < records->size(); ++i) {
    const json& record = (*records)[i];
    RecordSpec spec;
    spec.pointer = "/records/" + std::to_string(i);
    if (!record.is_object()) ManifestError(spec.pointer, "expected an object {\"file\": ..., ...}");
    const json* file = Find(record, "file");
    if (!file) ManifestError(spec.pointer + "/file", "missing: the record's CSV file");
    if (!file->is_string() || file->get<std::string>().empty())
      ManifestError(spec.pointer + "/file", "expected a file name");
    spec.file = file->get<std::string>();
    CheckFileName(spec.file, spec.pointer + "/file");
    const std::string normal = fs::path(spec.file).lexically_normal().string();
    if (const auto [it, fresh] = files.emplace(normal, spec.pointer); !fresh)
      ManifestError(spec.pointer + "/file", "duplicate file name '" + spec.file + "' (also " + it->second + ")");

    spec.sample_rate_hz = sample_rate_hz;
    if (const json* rate = Find(record, "sample_rate_hz")) {
      spec.sample_rate_hz = RequirePositiveRate(*rate, spec.pointer + "/sample_rate_hz");
      spec.rate_from_record = true;
    }
    if (const json* excitation = Find(record, "excitation")) {
      const std::string text = excitation->is_string() ? excitation->get<std::string>() : excitation->dump();
      if (text == "broadband")
        spec.broadband = true;
      else if (text != "stepped-sine" && text != "stepped_sine" && text != "sine")
        ManifestError(spec.pointer + "/excitation",
                      "unknown excitation " + Quote(text) + " (known: stepped-sine, broadband)");
    }
    const json* frequency = Find(record, "drive_frequency_hz");
    const json* amplitude = Find(record, "drive_amplitude_v");
    if (spec.broadband) {
      if (frequency)
        ManifestError(spec.pointer + "/drive_frequency_hz", "a broadband record has no nominal drive frequency");
    } else {
      if (!frequency)
        ManifestError(spec.pointer + "/drive_frequency_hz",
                      "missing (a stepped-sine step; write \"excitation\": \"broadband\" for other drives)");
      if (!frequency->is_number())
        ManifestError(spec.pointer + "/drive_frequency_hz", "expected a number [Hz], got " + TypeName(*frequency));
      spec.frequency_hz = frequency->get<double>();
      if (!std::isfinite(spec.frequency_hz) || spec.frequency_hz <= 0)
        ManifestError(spec.pointer + "/drive_frequency_hz",
                      "must be a finite number > 0, got " + Num(spec.frequency_hz));
      if (!amplitude) ManifestError(spec.pointer + "/drive_amplitude_v", "missing (a stepped-sine step)");
    }
    if (amplitude) {
      if (!amplitude->is_number())
        ManifestError(spec.pointer + "/drive_amplitude_v", "expected a number [V], got " + TypeName(*amplitude));
      spec.amplitude_v = amplitude->get<double>();
      if (!std::isfinite(spec.amplitude_v) || spec.amplitude_v < 0)
        ManifestError(spec.pointer + "/drive_amplitude_v",
                      "must be a finite number >= 0, got " + Num(spec.amplitude_v));
    }
    out.push_back(std::move(spec));
  }
  return out;
}

// ---- CSV ---------------------------------------------------------------------------------------

class CsvError {
 public:
  explicit CsvError(const std::string& file) : file_(file) {}
  [[noreturn]] void At(size_t line, const std::string& message) const {
    throw InputError(file_ + ":" + std::to_string(line), message);
  }

 private:
  const std::string& file_;
};

bool IsBlank(char c) { return c == ' ' || c == '\t'; }

std::string_view Trim(std::string_view text) {
  while (!text.empty() && IsBlank(text.front())) text.remove_prefix(1);
  while (!text.empty() && IsBlank(text.back())) text.remove_suffix(1);
  return text;
}

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

// ---- Writing -----------------------------------------------------------------------------------

// Integral values as JSON integers (51200, not 51200.0), as the rig writes them.
json ManifestNumber(double value) {
  if (std::abs(value) < 1e15 && value == std::floor(value)) return json(static_cast<std::int64_t>(value));
  return json(value);
}

void AppendNumber(std::string* out, double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value, std::chars_format::general, 10);
  out->append(buffer, result.ptr);
}

void WriteFile(const fs::path& path, std::string_view text) {
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (!file) throw std::runtime_error("cannot open '" + path.string() + "' for writing: " + std::strerror(errno));
  const size_t written = std::fwrite(text.data(), 1, text.size(), file);
  const int closed = std::fclose(file);
  if (written != text.size() || closed != 0)
    throw std::runtime_error("writing '" + path.string() + "' failed: " + std::strerror(errno));
}

void CheckColumnName(const std::string& name, const char* field) {
  if (name.empty()) throw InputError(field, "must not be empty");
  if (name.find_first_of(",\"\r\n") != std::string::npos)
    throw InputError(field, "'" + name + "' holds a comma, quote or line break");
  if (name == "time_s") throw InputError(field, "'time_s' is the time column");
  if (Trim(name) != name) throw InputError(field, "'" + name + "' starts or ends with a blank");
}

}  // namespace

const char* SensitivityKey(ResponseKind kind) {
  switch (kind) {
    case ResponseKind::kForce: return "sensitivity_V_per_N";
    case ResponseKind::kAcceleration: return "sensitivity_V_per_m_s2";
    case ResponseKind::kVelocity: return "sensitivity_V_per_m_s";
    case ResponseKind::kDisplacement: return "sensitivity_V_per_m";
  }
  return "sensitivity";
}

double DefaultSensitivity(ResponseKind kind) {
  switch (kind) {
    case ResponseKind::kForce: return 0.02248;
    case ResponseKind::kAcceleration: return 0.0102;
    case ResponseKind::kVelocity: return 1.0;
    case ResponseKind::kDisplacement: return 1000.0;
  }
  return 1.0;
}

Campaign ReadCampaign(const fs::path& dir) {
  if (!fs::is_directory(dir)) throw InputError(dir.string(), "not a campaign directory (it does not exist)");
  const fs::path manifest_path = dir / kManifestName;
  if (!fs::is_regular_file(manifest_path)) ManifestError("", "not found in " + dir.string());
  std::string manifest_text;
  if (!ReadWholeFile(manifest_path, &manifest_text)) ManifestError("", "cannot be read");
  json manifest;
  try {
    manifest = json::parse(manifest_text);
  } catch (const json::parse_error& e) {
    // e.byte counts characters read, the offending one (or the end of input) included.
    const size_t before = std::min(e.byte > 0 ? e.byte - 1 : 0, manifest_text.size());
    const size_t line = 1 + static_cast<size_t>(std::count(manifest_text.begin(),
                                                           manifest_text.begin() + static_cast<long>(before), '\n'));
    std::string what = e.what();
    // "[json.exception.parse_error.101] parse error at line 3, column 5: syntax error ..." -> after the position.
    if (const size_t colon = what.find(": "); colon != std::string::npos) what = what.substr(colon + 2);
    throw InputError(std::string(kManifestName) + ":" + std::to_string(line), "not valid JSON: " + what);
  } catch (const json::exception& e) {
    // Not a syntax error: a number beyond a double ("1e400", out_of_range 406), which has no position.
    std::string what = e.what();
    if (const size_t bracket = what.find("] "); bracket != std::string::npos) what = what.substr(bracket + 2);
    throw InputError(kManifestName, "not valid JSON: " + what);
  }
  if (!manifest.is_object()) ManifestError("", "expected a JSON object");
  const json* format = Find(manifest, "format");
  if (!format) ManifestError("/format", std::string("missing; expected \"") + kRecordingsFormat + "\"");
  if (!format->is_string() || format->get<std::string>() != kRecordingsFormat)
    ManifestError("/format", "unsupported format " + format->dump() + " (expected \"" + kRecordingsFormat + "\")");
  Campaign campaign;
  if (const json* actuator = Find(manifest, "actuator")) {
    if (!actuator->is_string()) ManifestError("/actuator", "expected a string");
    campaign.actuator = actuator->get<std::string>();
  }
  const json* rate = Find(manifest, "sample_rate_hz");
  if (!rate) ManifestError("/sample_rate_hz", "missing: the sample rate [Hz]");
  const double sample_rate_hz = RequirePositiveRate(*rate, "/sample_rate_hz");
  const Channels channels = ParseChannels(manifest);
  campaign.response = channels.kind;
  campaign.absolute_scale = !channels.nominal;
  const std::vector<RecordSpec> specs = ParseRecords(manifest, sample_rate_hz);
  for (const RecordSpec& spec : specs) {
    if (!fs::is_regular_file(dir / spec.file))
      ManifestError(spec.pointer + "/file", "file '" + spec.file + "' not found in " + dir.string());
  }

  // The records, on up to one thread per core; the first failure in manifest order is reported.
  campaign.records.resize(specs.size());
  ParallelFor(specs.size(), [&](size_t i) { campaign.records[i] = ReadRecord(dir, specs[i], channels); });
  return campaign;
}

void Validate(const WriteOptions& options) {
  if (!std::isfinite(options.sensitivity))
    throw InputError("sensitivity", "must be a finite number (0: the default), got " + Num(options.sensitivity));
  CheckColumnName(options.voltage_column, "voltage_column");
  if (!options.response_column.empty()) {
    CheckColumnName(options.response_column, "response_column");
    if (options.response_column == options.voltage_column)
      throw InputError("response_column", "is the voltage column too");
  }
}

void WriteCampaign(const Campaign& campaign, const fs::path& dir, const WriteOptions& options) {
  Validate(options);
  const double sensitivity = options.sensitivity != 0 ? options.sensitivity : DefaultSensitivity(campaign.response);
  const std::string response_column = options.response_column.empty()
                                          ? std::string(ToString(campaign.response)) + "_sensor_V"
                                          : options.response_column;
  if (response_column == options.voltage_column) throw InputError("response_column", "is the voltage column too");
  if (campaign.records.empty()) throw InputError("records", "no records to write");

  // File names and checks before anything is written.
  std::vector<std::string> files;
  std::map<std::string, size_t> seen;
  for (size_t i = 0; i < campaign.records.size(); ++i) {
    const Recording& record = campaign.records[i];
    const std::string field = "records/" + std::to_string(i);
    std::string file = record.name;
    if (file.empty() || options.rename_records) {
      char name[32];
      std::snprintf(name, sizeof name, "rec_%03zu.csv", i + 1);
      file = name;
    }
    try {
      CheckFileName(file, "");
    } catch (const InputError& e) {
      throw InputError(field + "/name", e.bare_message());
    }
    if (const auto [it, fresh] = seen.emplace(fs::path(file).lexically_normal().string(), i); !fresh)
      throw InputError(field + "/name",
                       "file name '" + file + "' is also that of records/" + std::to_string(it->second));
    if (file == kManifestName) throw InputError(field + "/name", "a record cannot be called manifest.json");
    if (!std::isfinite(record.sample_rate_hz) || record.sample_rate_hz <= 0)
      throw InputError(field + "/sample_rate_hz", "must be a finite number > 0, got " + Num(record.sample_rate_hz));
    if (record.voltage_v.size() != record.response.size())
      throw InputError(field, "voltage and response have different lengths (" +
                                  std::to_string(record.voltage_v.size()) + " and " +
                                  std::to_string(record.response.size()) + ")");
    if (record.voltage_v.size() < 2) throw InputError(field, "a record needs at least 2 samples");
    for (size_t n = 0; n < record.size(); ++n) {
      if (!std::isfinite(record.voltage_v[n]) || !std::isfinite(record.response[n] * sensitivity))
        throw InputError(field, "non-finite sample " + std::to_string(n));
    }
    if (!record.broadband && (!std::isfinite(record.nominal_frequency_hz) || record.nominal_frequency_hz <= 0))
      throw InputError(field + "/nominal_frequency_hz", "a stepped-sine record needs a frequency > 0");
    if (!std::isfinite(record.nominal_amplitude_v) || record.nominal_amplitude_v < 0)
      throw InputError(field + "/nominal_amplitude_v", "must be a finite number >= 0");
    files.push_back(file);
  }

  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw std::runtime_error("cannot create '" + dir.string() + "': " + ec.message());

  const double sample_rate_hz = campaign.records.front().sample_rate_hz;
  nlohmann::ordered_json voltage = {
      {"column", options.voltage_column}, {"unit", "V"}, {"note", "drive voltage measured before the power amplifier"}};
  nlohmann::ordered_json response = {
      {"column", response_column}, {"unit", "V"}, {SensitivityKey(campaign.response), ManifestNumber(sensitivity)}};
  if (!campaign.absolute_scale) response["nominal"] = true;
  std::string manifest = "{\n";
  manifest += "  \"format\": " + json(kRecordingsFormat).dump() + ",\n";
  manifest += "  \"actuator\": " + json(options.actuator.empty() ? campaign.actuator : options.actuator).dump() + ",\n";
  manifest += "  \"sample_rate_hz\": " + ManifestNumber(sample_rate_hz).dump() + ",\n";
  manifest += "  \"channels\": {\n";
  manifest += "    \"voltage\": " + voltage.dump() + ",\n";
  manifest += "    " + json(ToString(campaign.response)).dump() + ": " + response.dump() + "\n";
  manifest += "  },\n  \"records\": [\n";
  for (size_t i = 0; i < campaign.records.size(); ++i) {
    const Recording& record = campaign.records[i];
    nlohmann::ordered_json entry = {{"file", files[i]}};
    if (record.broadband) {
      entry["excitation"] = "broadband";
      if (record.nominal_amplitude_v > 0) entry["drive_amplitude_v"] = ManifestNumber(record.nominal_amplitude_v);
    } else {
      entry["drive_frequency_hz"] = ManifestNumber(record.nominal_frequency_hz);
      entry["drive_amplitude_v"] = ManifestNumber(record.nominal_amplitude_v);
    }
    if (record.sample_rate_hz != sample_rate_hz) entry["sample_rate_hz"] = ManifestNumber(record.sample_rate_hz);
    manifest += "    " + entry.dump() + (i + 1 < campaign.records.size() ? ",\n" : "\n");
  }
  manifest += "  ]\n}\n";

  std::string text;
  for (size_t i = 0; i < campaign.records.size(); ++i) {
    const Recording& record = campaign.records[i];
    text.clear();
    text.reserve(record.size() * 48 + 64);
    text += "time_s," + options.voltage_column + "," + response_column + "\n";
    for (size_t n = 0; n < record.size(); ++n) {
      AppendNumber(&text, static_cast<double>(n) / record.sample_rate_hz);
      text += ',';
      AppendNumber(&text, record.voltage_v[n]);
      text += ',';
      AppendNumber(&text, record.response[n] * sensitivity);
      text += '\n';
    }
    const fs::path path = dir / files[i];
    if (path.has_parent_path()) fs::create_directories(path.parent_path(), ec);
    WriteFile(path, text);
  }
  WriteFile(dir / kManifestName, manifest);
}

}  // namespace strokelab
