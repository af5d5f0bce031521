#include "regression.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>

#include "strokelab/base/errors.h"
#include "strokelab/base/json_parse.h"
#include "strokelab/jobs/jobs.h"

namespace strokelab::cli::regression {
namespace {

using nlohmann::json;

constexpr double kInf = std::numeric_limits<double>::infinity();
const char* const kKeyFields[] = {"frequency_hz", "amplitude_v", "branch"};
const char* const kTables[] = {"points", "jumps", "thresholds", "records"};

// Unknown fields: numbers to 1e-9 relative, anything else exactly.
const Tolerance kFallback = Tolerance::Numeric(1e-9, 0.0);

bool IsNull(const json& value) {
  return value.is_null() || (value.is_number_float() && !std::isfinite(value.get<double>()));
}

std::string Number(double value, int digits = 10) {
  char text[40];
  std::snprintf(text, sizeof text, "%.*g", digits, value);
  return text;
}

std::string Short(const json& value) { return IsNull(value) ? "null" : value.dump(); }

// The exact key of a row (its key fields at full precision) for matching.
std::string MatchKey(const json& row) {
  std::string key;
  for (const char* field : kKeyFields) {
    key += '|';
    auto it = row.find(field);
    if (it == row.end()) continue;
    key += IsNull(*it) ? std::string("null") : it->is_number() ? Number(it->get<double>(), 17) : it->dump();
  }
  return key;
}

std::string Escape(const std::string& token) {  // a JSON pointer reference token
  std::string out;
  for (char c : token) out += c == '~' ? "~0" : c == '/' ? "~1" : std::string(1, c);
  return out;
}

Tolerance ParseRule(const json& rule, const Tolerance& base, const std::string& pointer) {
  if (rule.is_string()) {
    if (rule == "exact") return Tolerance::Exact();
    if (rule == "ignore") return Tolerance::Ignore();
    throw InputError(pointer, "expected \"exact\", \"ignore\" or {\"relative\": R, \"absolute\": A}");
  }
  if (!rule.is_object())
    throw InputError(pointer, "expected \"exact\", \"ignore\" or {\"relative\": R, \"absolute\": A}");
  Tolerance out = Tolerance::Numeric(0.0, 0.0, base.angle);
  bool numeric = false;
  for (const auto& [key, value] : rule.items()) {
    const std::string at = pointer + "/" + Escape(key);
    if (key == "relative" || key == "absolute") {
      if (!value.is_number() || !std::isfinite(value.get<double>()) || value.get<double>() < 0)
        throw InputError(at, "must be a number >= 0");
      (key == "relative" ? out.relative : out.absolute) = value.get<double>();
      numeric = true;
    } else if (key == "exact" || key == "ignore") {
      if (value != true) throw InputError(at, "must be true (leave it out otherwise)");
      if (rule.size() != 1) throw InputError(at, "cannot be combined with other keys");
      return key == "exact" ? Tolerance::Exact() : Tolerance::Ignore();
    } else {
      throw InputError(at, "unknown key (known: relative, absolute, exact, ignore)");
    }
  }
  if (!numeric) throw InputError(pointer, "give relative and/or absolute");
  return out;
}

void CompareRow(const std::string& table, const std::string& label, const json& baseline, const json& now,
                const Tolerances& tolerances, Comparison& out) {
  const auto note = [&](const std::string& where, const ValueCheck& check) {
    if (check.absolute == 0.0) return;
    if (!out.worst || check.used > out.worst->check.used ||
        (check.used == out.worst->check.used && check.relative > out.worst->check.relative))
      out.worst = Worst{where, check};
  };
  for (const auto& [field, value] : baseline.items()) {
    const Tolerance tolerance = tolerances.For(table, field);
    if (tolerance.kind == Tolerance::Kind::kIgnore) continue;
    const std::string where = label + "." + field;
    auto it = now.find(field);
    if (it == now.end()) {
      out.regressions.push_back(where + ": missing now (baseline " + Short(value) + ")");
      continue;
    }
    const ValueCheck check = CompareValue(value, *it, tolerance);
    note(where, check);
    if (check.pass) continue;
    std::string line = where + ": " + Short(*it) + " now, " + Short(value) + " in the baseline";
    if (std::isfinite(check.absolute)) {
      line += std::isfinite(check.relative) ? ": relative deviation " + Number(check.relative, 2)
                                            : ": deviation " + Number(check.absolute, 2);
      line += " beyond " + tolerance.Describe();
    } else {
      line += " (" + tolerance.Describe() + ")";
    }
    out.regressions.push_back(line);
  }
  for (const auto& [field, value] : now.items()) {
    if (baseline.contains(field) || tolerances.For(table, field).kind == Tolerance::Kind::kIgnore) continue;
    out.regressions.push_back(label + "." + field + ": new field, not in the baseline (now " + Short(value) + ")");
  }
}

const json& Rows(const json& tables, const std::string& table) {
  static const json kEmpty = json::array();
  auto it = tables.find(table);
  return it == tables.end() ? kEmpty : *it;
}

void CheckTables(const json& tables, const std::string& where) {
  if (!tables.is_object()) throw InputError(where, "must be an object of tables");
  for (const auto& [name, rows] : tables.items()) {
    if (!rows.is_array()) throw InputError(where + "/" + Escape(name), "must be an array of rows");
    for (size_t i = 0; i < rows.size(); ++i)
      if (!rows[i].is_object()) throw InputError(where + "/" + Escape(name) + "/" + std::to_string(i), "must be an object");
  }
}

}  // namespace

std::string Tolerance::Describe() const {
  switch (kind) {
    case Kind::kExact: return "exact";
    case Kind::kIgnore: return "ignored";
    case Kind::kNumeric: break;
  }
  std::string text;
  if (relative > 0) text = "relative " + Number(relative, 3);
  if (absolute > 0 || relative == 0) text += (text.empty() ? "" : ", ") + std::string("absolute ") + Number(absolute, 3);
  if (angle) text += " (angle)";
  return "tolerance " + text;
}

Tolerances Tolerances::Defaults() {
  Tolerances t;
  auto& r = t.rules_;
  // Grid coordinates, labels, integers and flags: any change is a change of behaviour.
  for (const char* field : {"frequency_hz", "amplitude_v", "branch", "stable", "period", "contacts_per_period",
                            "contacts", "method", "from_kind", "to_kind"})
    r[field] = Tolerance::Exact();
  // Steady-state harmonics and forces [N/V, N]: converged to ~1e-12 relative by Newton; 1e-9 leaves
  // room for another compiler or CPU. The floor keeps a component near zero (h_re_n_per_v at resonance)
  // from turning rounding into a large relative deviation.
  r["h_re_n_per_v"] = Tolerance::Numeric(1e-9, 1e-12);
  r["h_im_n_per_v"] = Tolerance::Numeric(1e-9, 1e-12);
  r["first_harmonic_force_n"] = Tolerance::Numeric(1e-9, 1e-12);
  r["peak_force_n"] = Tolerance::Numeric(1e-9, 1e-12);
  r["first_harmonic_phase_rad"] = Tolerance::Numeric(0.0, 1e-9, /*angle=*/true);
  // Displacements [m], ~1e-3 m: 1e-12 m absolute (a relative tolerance would be meaningless at 0).
  r["min_displacement_m"] = Tolerance::Numeric(0.0, 1e-12);
  r["max_displacement_m"] = Tolerance::Numeric(0.0, 1e-12);
  // Floquet multiplier magnitude (eigenvalues of the monodromy matrix), contact duration [ms].
  r["max_multiplier"] = Tolerance::Numeric(1e-8, 1e-12);
  r["mean_contact_ms"] = Tolerance::Numeric(1e-9, 1e-9);
  // Located by root-finding on the branch (folds, grazing): their own tolerances set these.
  r["bistable_from_hz"] = Tolerance::Numeric(1e-7, 0.0);
  r["bistable_to_hz"] = Tolerance::Numeric(1e-7, 0.0);
  r["grazing_amplitude_v"] = Tolerance::Numeric(1e-8, 0.0);
  r["lowest_contact_amplitude_v"] = Tolerance::Numeric(1e-8, 0.0);
  // Wall times and rates depend on the machine.
  for (const char* field : {"wall_time_s", "elapsed_s", "points_per_second"}) r[field] = Tolerance::Ignore();
  return t;
}

std::set<std::string> Tolerances::KnownFields() const {
  std::set<std::string> fields;
  for (const auto& [key, rule] : rules_)
    if (key.find('.') == std::string::npos) fields.insert(key);
  return fields;
}

void Tolerances::Apply(const json& overrides, const std::string& pointer) {
  if (!overrides.is_object())
    throw InputError(pointer, "must be an object {FIELD: {\"relative\": R, \"absolute\": A} | \"exact\" | \"ignore\"}");
  const std::set<std::string> known = KnownFields();
  std::map<std::string, Tolerance> applied;
  for (const auto& [key, rule] : overrides.items()) {
    const std::string at = pointer + "/" + Escape(key);
    const size_t dot = key.find('.');
    const std::string field = dot == std::string::npos ? key : key.substr(dot + 1);
    if (dot != std::string::npos) {
      const std::string table = key.substr(0, dot);
      bool table_known = false;
      for (const char* t : kTables) table_known |= table == t;
      if (!table_known) throw InputError(at, "unknown table '" + table + "' (known: points, jumps, thresholds, records)");
    }
    if (!known.count(field)) {
      std::string list;
      for (const std::string& f : known) list += (list.empty() ? "" : ", ") + f;
      throw InputError(at, "'" + field + "' is not a result field (known: " + list + ")");
    }
    const Tolerance base = For(dot == std::string::npos ? "" : key.substr(0, dot), field);
    applied[key] = ParseRule(rule, base, at);
  }
  for (auto& [key, rule] : applied) rules_[key] = rule;
}

Tolerance Tolerances::For(const std::string& table, const std::string& field) const {
  if (auto it = rules_.find(table + "." + field); it != rules_.end()) return it->second;
  if (auto it = rules_.find(field); it != rules_.end()) return it->second;
  return kFallback;
}

ValueCheck CompareValue(const json& baseline, const json& now, const Tolerance& tolerance) {
  ValueCheck check;
  if (tolerance.kind == Tolerance::Kind::kIgnore) return check;
  const bool null_b = IsNull(baseline), null_n = IsNull(now);
  if (null_b || null_n) {
    if (null_b && null_n) return check;
    return {false, kInf, kInf, kInf};
  }
  if (!baseline.is_number() || !now.is_number()) {
    if (baseline == now) return check;
    return {false, kInf, kInf, kInf};
  }
  if (baseline.is_number_integer() && now.is_number_integer() && baseline.get<int64_t>() == now.get<int64_t>())
    return check;
  const double b = baseline.get<double>(), n = now.get<double>();
  double diff = n - b;
  if (tolerance.angle) diff = std::remainder(diff, 2 * std::numbers::pi);
  check.absolute = std::abs(diff);
  if (check.absolute == 0.0) return check;
  check.relative = b != 0.0 ? check.absolute / std::abs(b) : kInf;
  const double allowed =
      tolerance.kind == Tolerance::Kind::kExact ? 0.0 : std::max(tolerance.absolute, tolerance.relative * std::abs(b));
  check.used = allowed > 0 ? check.absolute / allowed : kInf;
  check.pass = check.absolute <= allowed;
  return check;
}

std::string RowLabel(const std::string& table, const json& row, size_t occurrence) {
  std::string label;
  const auto add = [&](const std::string& part) {
    if (!label.empty()) label += ", ";
    label += part;
  };
  if (auto it = row.find("frequency_hz"); it != row.end() && it->is_number())
    add(std::string("f=").append(Number(it->get<double>())).append(" Hz"));
  if (auto it = row.find("amplitude_v"); it != row.end() && it->is_number())
    add(std::string("V=").append(Number(it->get<double>())).append(" V"));
  if (auto it = row.find("branch"); it != row.end() && it->is_string()) add(it->get<std::string>());
  if (occurrence > 0) add(std::string("#").append(std::to_string(occurrence + 1)));
  return table + "[" + label + "]";
}

Comparison CompareTables(const json& baseline, const json& now, const Tolerances& tolerances) {
  CheckTables(baseline, "tables");
  CheckTables(now, "tables");
  Comparison out;
  std::set<std::string> names;
  for (const auto& [name, rows] : baseline.items()) names.insert(name);
  for (const auto& [name, rows] : now.items()) names.insert(name);
  for (const std::string& table : names) {
    const json& old_rows = Rows(baseline, table);
    const json& new_rows = Rows(now, table);
    // Current rows by key and order among equal keys.
    std::map<std::string, size_t> seen;
    std::map<std::pair<std::string, size_t>, size_t> index;
    for (size_t i = 0; i < new_rows.size(); ++i) {
      const std::string key = MatchKey(new_rows[i]);
      index[{key, seen[key]++}] = i;
    }
    seen.clear();
    std::vector<bool> matched(new_rows.size(), false);
    for (const json& row : old_rows) {
      const std::string key = MatchKey(row);
      const size_t occurrence = seen[key]++;
      const std::string label = RowLabel(table, row, occurrence);
      auto it = index.find({key, occurrence});
      if (it == index.end()) {
        out.regressions.push_back(label + ": missing row (in the baseline, not in the results)");
        continue;
      }
      matched[it->second] = true;
      ++out.rows_compared;
      CompareRow(table, label, row, new_rows[it->second], tolerances, out);
    }
    seen.clear();
    for (size_t i = 0; i < new_rows.size(); ++i) {
      const std::string key = MatchKey(new_rows[i]);
      const size_t occurrence = seen[key]++;
      if (!matched[i])
        out.regressions.push_back(RowLabel(table, new_rows[i], occurrence) + ": extra row (in the results, not in the baseline)");
    }
  }
  return out;
}

json Normalized(const json& value) { return ParseJson(value.dump()); }

std::string FormatBaseline(const json& job, const std::string& code_version, const json& tables) {
  std::ostringstream out;
  out << "{\n  \"written_by\": \"strokelab regress --update\",\n  \"code_version\": " << json(code_version).dump()
      << ",\n  \"job\": " << job.dump() << ",\n  \"tables\": {";
  bool first_table = true;
  for (const auto& [name, rows] : tables.items()) {
    out << (first_table ? "" : ",") << "\n    " << json(name).dump() << ": [";
    for (size_t i = 0; i < rows.size(); ++i) out << (i ? "," : "") << "\n      " << rows[i].dump();
    out << (rows.empty() ? "]" : "\n    ]");
    first_table = false;
  }
  out << (first_table ? "}" : "\n  }") << "\n}\n";
  return out.str();
}

void CheckBaseline(const json& baseline, const std::string& file) {
  if (!baseline.is_object()) throw InputError(file, "a baseline must be a JSON object (rewrite it with --update)");
  if (!baseline.contains("tables")) throw InputError(file, "no \"tables\" (rewrite it with --update)");
  if (!baseline.contains("job") || !baseline["job"].is_object())
    throw InputError(file, "no \"job\" object (rewrite it with --update)");
  try {
    CheckTables(baseline["tables"], "/tables");
  } catch (const InputError& e) {
    throw InputError(file + ": " + e.field(), e.bare_message());
  }
}

std::string JobKey(const json& job) {
  json without_name = job;
  if (without_name.is_object()) without_name.erase("name");
  return jobs::ContentKey(without_name.dump());
}

std::string TablesKey(const json& tables) { return jobs::ContentKey(Normalized(tables).dump()); }

std::vector<LedgerEntry> ReadLedger(const std::string& path) {
  std::vector<LedgerEntry> ledger;
  std::ifstream in(path);
  if (!in) return ledger;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    LedgerEntry entry;
    std::string extra;
    if (!(fields >> entry.code_version >> entry.job_key >> entry.tables_key >> entry.file) || (fields >> extra))
      throw InputError(path + ":" + std::to_string(number), "expected CODE_VERSION JOB_KEY TABLES_KEY FILE");
    if (FindEntry(ledger, entry.code_version, entry.job_key))
      throw InputError(path + ":" + std::to_string(number),
                       "a second line for " + entry.code_version + " and the job of " + entry.file +
                           " (one version has one result per job)");
    ledger.push_back(std::move(entry));
  }
  return ledger;
}

std::string FormatLedgerLine(const LedgerEntry& entry) {
  return entry.code_version + " " + entry.job_key + " " + entry.tables_key + " " + entry.file + "\n";
}

std::optional<LedgerEntry> FindEntry(const std::vector<LedgerEntry>& ledger, const std::string& code_version,
                                     const std::string& job_key) {
  for (const LedgerEntry& entry : ledger)
    if (entry.code_version == code_version && entry.job_key == job_key) return entry;
  return std::nullopt;
}

}  // namespace strokelab::cli::regression
