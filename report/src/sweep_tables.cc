// The column tables of a sweep's results and the JSON and CSV written from them (sweep_tables.h).
#include "strokelab/report/sweep_tables.h"

#include <cmath>

#include "strokelab/base/errors.h"
#include "strokelab/report/csv_table.h"  // CsvNumber

namespace strokelab::report {
namespace {

using nlohmann::json;

Branch ParseBranch(const std::string& text) {
  if (text == "up") return Branch::kUp;
  if (text == "down") return Branch::kDown;
  if (text == "unstable") return Branch::kUnstable;
  throw InputError("branch", "must be up, down or unstable, not '" + text + "'");
}

// The columns of a row type, spelled with the member each one reads and writes.
#define STROKELAB_NUMBER(Row, member) \
  {#member, ColumnKind::kNumber, [](const Row& r) { return json(r.member); }, \
   [](Row& r, const json& v) { r.member = v.get<double>(); }}
#define STROKELAB_TEXT(Row, member) \
  {#member, ColumnKind::kText, [](const Row& r) { return json(r.member); }, \
   [](Row& r, const json& v) { r.member = v.get<std::string>(); }}

// The value of a column as written: non-finite numbers as null, an aperiodic orbit as "aperiodic".
template <class Row>
json Written(const Column<Row>& column, const Row& row) {
  json value = column.get(row);
  if (column.kind == ColumnKind::kNumber && !std::isfinite(value.get<double>())) return nullptr;
  if (column.kind == ColumnKind::kPeriod && value.get<int>() <= 0) return "aperiodic";
  return value;
}

// Whether `value` is of the column's kind as written (the inverse of Written).
template <class Row>
bool OfKind(const Column<Row>& column, const json& value) {
  switch (column.kind) {
    case ColumnKind::kNumber: return value.is_number() || value.is_null();
    case ColumnKind::kPeriod: return value.is_number_integer() || value == "aperiodic";
    case ColumnKind::kFlag: return value.is_boolean();
    case ColumnKind::kText: return value.is_string();
  }
  return false;
}

const char* KindName(ColumnKind kind) {
  switch (kind) {
    case ColumnKind::kNumber: return "a number or null";
    case ColumnKind::kPeriod: return "an integer or \"aperiodic\"";
    case ColumnKind::kFlag: return "true or false";
    case ColumnKind::kText: return "a string";
  }
  return "?";
}

}  // namespace

template <>
const std::vector<Column<SweepPoint>>& Columns() {
  using P = SweepPoint;
  static const std::vector<Column<P>> columns = {
      STROKELAB_NUMBER(P, frequency_hz),
      STROKELAB_NUMBER(P, amplitude_v),
      {"branch", ColumnKind::kText, [](const P& p) { return json(ToString(p.branch)); },
       [](P& p, const json& v) { p.branch = ParseBranch(v.get<std::string>()); }},
      {"stable", ColumnKind::kFlag, [](const P& p) { return json(p.stable); },
       [](P& p, const json& v) { p.stable = v.get<bool>(); }},
      {"period", ColumnKind::kPeriod, [](const P& p) { return json(p.period); },
       [](P& p, const json& v) { p.period = v.is_number_integer() ? v.get<int>() : 0; }},
      STROKELAB_NUMBER(P, first_harmonic_force_n),
      STROKELAB_NUMBER(P, first_harmonic_phase_rad),
      {"h_re_n_per_v", ColumnKind::kNumber, [](const P& p) { return json(p.h.real()); },
       [](P& p, const json& v) { p.h.real(v.get<double>()); }},
      {"h_im_n_per_v", ColumnKind::kNumber, [](const P& p) { return json(p.h.imag()); },
       [](P& p, const json& v) { p.h.imag(v.get<double>()); }},
      STROKELAB_NUMBER(P, min_displacement_m),
      STROKELAB_NUMBER(P, max_displacement_m),
      STROKELAB_NUMBER(P, peak_force_n),
      STROKELAB_NUMBER(P, contacts_per_period),
      STROKELAB_NUMBER(P, max_multiplier),
  };
  return columns;
}

template <>
const std::vector<Column<SaturationThreshold>>& Columns() {
  using T = SaturationThreshold;
  static const std::vector<Column<T>> columns = {
      STROKELAB_NUMBER(T, frequency_hz),
      STROKELAB_NUMBER(T, grazing_amplitude_v),
      STROKELAB_NUMBER(T, lowest_contact_amplitude_v),
  };
  return columns;
}

template <>
const std::vector<Column<JumpInterval>>& Columns() {
  using J = JumpInterval;
  static const std::vector<Column<J>> columns = {
      STROKELAB_NUMBER(J, amplitude_v),   STROKELAB_NUMBER(J, bistable_from_hz), STROKELAB_NUMBER(J, bistable_to_hz),
      STROKELAB_TEXT(J, from_kind), STROKELAB_TEXT(J, to_kind),
  };
  return columns;
}

#undef STROKELAB_NUMBER
#undef STROKELAB_TEXT

template <class Row>
json RowToJson(const Row& row) {
  json out = json::object();
  for (const Column<Row>& column : Columns<Row>()) out[column.name] = Written(column, row);
  return out;
}

template <class Row>
std::vector<std::string> ColumnNames() {
  std::vector<std::string> names;
  for (const Column<Row>& column : Columns<Row>()) names.emplace_back(column.name);
  return names;
}

template <class Row>
void AppendCells(const Row& row, std::vector<json>& cells) {
  for (const Column<Row>& column : Columns<Row>()) cells.push_back(Written(column, row));
}

template <class Row>
Row RowFromJson(const json& in) {
  if (!in.is_object()) throw InputError("row", "expected a JSON object");
  Row row;
  for (const Column<Row>& column : Columns<Row>()) {
    const auto it = in.find(column.name);
    if (it == in.end()) throw InputError(column.name, "is missing");
    if (!OfKind(column, *it)) throw InputError(column.name, std::string("expected ") + KindName(column.kind));
    column.set(row, it->is_null() ? json(NAN) : *it);
  }
  return row;
}

template <class Row>
std::string CsvHeader() {
  std::string line;
  for (const Column<Row>& column : Columns<Row>()) line += (line.empty() ? "" : ",") + std::string(column.name);
  return line + "\n";
}

template <class Row>
std::string CsvLine(const Row& row) {
  std::string line;
  bool first = true;
  for (const Column<Row>& column : Columns<Row>()) {
    if (!first) line += ",";
    first = false;
    const json value = Written(column, row);
    switch (column.kind) {
      case ColumnKind::kNumber:
        if (!value.is_null()) line += CsvNumber(value.get<double>());
        break;
      case ColumnKind::kPeriod:
        if (value.is_number_integer()) line += std::to_string(value.get<int>());
        break;
      case ColumnKind::kFlag: line += value.get<bool>() ? "1" : "0"; break;
      case ColumnKind::kText: {
        const std::string text = value.get<std::string>();
        if (text.find_first_of(",\"\n") == std::string::npos) {
          line += text;
        } else {  // RFC 4180 quoting
          line += "\"";
          for (char c : text) line += c == '"' ? std::string("\"\"") : std::string(1, c);
          line += "\"";
        }
        break;
      }
    }
  }
  return line + "\n";
}

#define STROKELAB_TABLE(Row)                                    \
  template json RowToJson<Row>(const Row&);                     \
  template std::vector<std::string> ColumnNames<Row>();         \
  template void AppendCells<Row>(const Row&, std::vector<json>&); \
  template Row RowFromJson<Row>(const json&);                   \
  template std::string CsvHeader<Row>();                        \
  template std::string CsvLine<Row>(const Row&);
STROKELAB_TABLE(SweepPoint)
STROKELAB_TABLE(SaturationThreshold)
STROKELAB_TABLE(JumpInterval)
#undef STROKELAB_TABLE

}  // namespace strokelab::report
