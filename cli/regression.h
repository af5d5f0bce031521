// The comparison behind `strokelab regress`: a job's result tables against a stored baseline,
// row by row and field by field, with a tolerance per field.
//
// Tables are JSON objects {TABLE: [ROW, ...]} with each ROW a JSON object (the service's result
// rows: tables "points", "jumps", "thresholds", "records"). Rows are matched by table and key: the
// values of "frequency_hz", "amplitude_v" and "branch" that the row has, compared exactly, and the
// row's order among rows with equal keys (the second jump interval at 0.4 V matches the second).
// A baseline row without a partner is a missing row, a current row without one an extra row; both
// are regressions, as is a field present on one side only.
//
// A value passes when
//   ignore:   always (wall times);
//   exact:    numbers equal as doubles, anything else equal as JSON;
//   numeric:  |now - baseline| <= max(absolute, relative x |baseline|), with the difference of an
//             angle field (phases) wrapped into [-pi, pi]; non-numbers as exact.
// null stands for a non-finite number (the JSON written never holds NaN or inf, and a NaN or inf
// in memory is treated as null): null equals null, and null against a number is a regression.
//
// Defaults by field name are in Tolerances::Defaults() (regression.cc); a field not listed there
// gets numeric, relative 1e-9, absolute 0. A job file's "tolerances" object overrides them:
//   {"first_harmonic_force_n": {"relative": 1e-6},          // replaces the whole rule
//    "points.peak_force_n": {"relative": 1e-6, "absolute": 1e-9},   // one table only
//    "max_multiplier": "ignore", "contacts": "exact"}
// An override replaces the default rule of its field (a part left out is 0); a "TABLE.FIELD" key
// wins over a "FIELD" key. Field names must be result fields known to the defaults, so that a typo
// is an error rather than a silently unused tolerance.
#pragma once

#include <cstddef>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace strokelab::cli::regression {

struct Tolerance {
  enum class Kind { kExact, kNumeric, kIgnore };
  Kind kind = Kind::kNumeric;
  double relative = 0.0;  // of |baseline|, dimensionless
  double absolute = 0.0;  // in the field's unit
  bool angle = false;     // a phase [rad]: differences are wrapped into [-pi, pi]

  static Tolerance Exact() { return {Kind::kExact, 0, 0, false}; }
  static Tolerance Ignore() { return {Kind::kIgnore, 0, 0, false}; }
  static Tolerance Numeric(double relative, double absolute, bool angle = false) {
    return {Kind::kNumeric, relative, absolute, angle};
  }
  // "exact", "ignored", "relative 1e-09, absolute 1e-12".
  std::string Describe() const;
};

class Tolerances {
 public:
  // The defaults by field name (see regression.cc for the list and the reasons).
  static Tolerances Defaults();

  // Applies a job file's "tolerances" object. Throws InputError naming the JSON pointer of the bad
  // entry (`pointer` is the object's own pointer, "/tolerances").
  void Apply(const nlohmann::json& overrides, const std::string& pointer = "/tolerances");

  // The rule for a field of a table: "TABLE.FIELD", else "FIELD", else the fallback.
  Tolerance For(const std::string& table, const std::string& field) const;

  // Field names with a default rule (what "tolerances" may name).
  std::set<std::string> KnownFields() const;

 private:
  std::map<std::string, Tolerance> rules_;  // by "FIELD" or "TABLE.FIELD"
};

// One value compared under a tolerance.
struct ValueCheck {
  bool pass = true;
  double absolute = 0.0;  // |now - baseline| (wrapped for angles); inf for a null/type mismatch
  double relative = 0.0;  // absolute / |baseline|; inf when the baseline is 0 and they differ
  double used = 0.0;      // absolute / allowed deviation; inf when nothing is allowed and they differ
};
ValueCheck CompareValue(const nlohmann::json& baseline, const nlohmann::json& now, const Tolerance& tolerance);

// The value that came closest to (or furthest past) its tolerance.
struct Worst {
  std::string where;  // "points[f=8 Hz, V=0.5 V, up].h_re_n_per_v"
  ValueCheck check;
};

struct Comparison {
  size_t rows_compared = 0;              // baseline rows that found their partner
  std::vector<std::string> regressions;  // one line each, in table and baseline row order
  std::optional<Worst> worst;            // among values that differ at all; none: identical
  bool Passed() const { return regressions.empty(); }
};

// Compares current tables with baseline tables (both {TABLE: [ROW...]}). Throws InputError naming
// "tables/TABLE/INDEX" when a table is not an array of objects.
Comparison CompareTables(const nlohmann::json& baseline, const nlohmann::json& now, const Tolerances& tolerances);

// The JSON as written and read back: non-finite numbers become null (round-trips through text).
nlohmann::json Normalized(const nlohmann::json& value);

// "points[f=8 Hz, V=0.5 V, up]" (plus " #2" for the third row with equal keys).
std::string RowLabel(const std::string& table, const nlohmann::json& row, size_t occurrence);

// A baseline file's text: {"written_by", "code_version", "job", "tables"}, one row a line so that
// changes read well in a diff.
std::string FormatBaseline(const nlohmann::json& job, const std::string& code_version, const nlohmann::json& tables);

// Checks a parsed baseline's shape (an object with "tables": {TABLE: [object...]} and a "job"
// object); throws InputError naming `file` and the offending part.
void CheckBaseline(const nlohmann::json& baseline, const std::string& file);

// The results ledger, `results-ledger.txt` in the baseline directory (regress/README.md, "Results
// version"): one line per baseline written, "CODE_VERSION JOB_KEY TABLES_KEY FILE". A job's results
// may change only with the version, since the version is in every task's cache key: results written
// under one version for one job have one TABLES_KEY.
inline constexpr const char* kLedgerFile = "results-ledger.txt";

struct LedgerEntry {
  std::string code_version;  // "strokelab-0.4.0"
  std::string job_key;       // JobKey of the baseline's job
  std::string tables_key;    // TablesKey of its tables
  std::string file;          // the baseline's file name, for the reader
};

// Digests (jobs::ContentKey) of a job without its "name" (a new name is not a new job) and of
// result tables as written (Normalized).
std::string JobKey(const nlohmann::json& job);
std::string TablesKey(const nlohmann::json& tables);

// The ledger's entries; none when the file does not exist. Throws InputError naming "FILE:LINE" for
// a line that is not four fields or that repeats a version and job already listed.
std::vector<LedgerEntry> ReadLedger(const std::string& path);
std::string FormatLedgerLine(const LedgerEntry& entry);

// The entry for this version and job, if any.
std::optional<LedgerEntry> FindEntry(const std::vector<LedgerEntry>& ledger, const std::string& code_version,
                                     const std::string& job_key);

}  // namespace strokelab::cli::regression
