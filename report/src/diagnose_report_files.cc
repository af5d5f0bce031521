// The diagnosis report's folder (diagnose_report.h): index.html, the CSV tables, model.json, and the
// number formatting shared by the page and the figures.
#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <fstream>
#include <numeric>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <utility>

#include "diagnose_report_internal.h"
#include "strokelab/report/csv_table.h"
#include "strokelab/report/diagnose_report.h"
#include "strokelab/report/diagnosis_maps.h"
#include "strokelab/model/model_json.h"

namespace strokelab::report {
namespace diagnose_internal {

std::string Num(double value, int digits) {
  if (!std::isfinite(value)) return "-";
  // Whole numbers below a million read better written out than as 1.685e+04.
  if (std::abs(value) >= std::pow(10.0, digits) && std::abs(value) < 1e6) return Format("%.0f", value);
  return Format("%.*g", digits, value);
}

std::string ValueSe(double value, double standard_error) {
  if (!std::isfinite(value)) return "-";
  if (!(standard_error > 0) || !std::isfinite(standard_error)) return Num(value);
  // Two significant digits of the error and the value to the same decimal place; values far from 1
  // as (m +- s)e+NN, so that value and error share one exponent.
  const int se_exponent = static_cast<int>(std::floor(std::log10(standard_error)));
  const int exponent = value == 0 ? se_exponent : static_cast<int>(std::floor(std::log10(std::abs(value))));
  if (exponent >= -2 && exponent <= 4) {
    const int decimals = std::clamp(1 - se_exponent, 0, 10);
    return Format("%.*f \u00b1 %.*f", decimals, value, decimals, standard_error);
  }
  const double scale = std::pow(10.0, exponent);
  const int decimals = std::clamp(exponent - se_exponent + 1, 0, 10);
  return Format("(%.*f \u00b1 %.*f)e%+03d", decimals, value / scale, decimals, standard_error / scale, exponent);
}

const char* EffectId(Effect effect) { return Info(effect).id; }  // the library's ids (diagnose.h)

std::string EffectIds(const std::vector<Effect>& effects) {
  std::string text;
  for (Effect e : effects) text += (text.empty() ? "" : " + ") + std::string(EffectId(e));
  return text.empty() ? "-" : text;
}

AmplitudeLevels GroupAmplitudes(const std::vector<RecordMatch>& records) {
  // Amplitudes within 3 % of a level's smallest belong to it: the estimated drive scatters by far less,
  // and stepped-sine levels are far more apart.
  constexpr double kLevelTolerance = 0.03;
  AmplitudeLevels levels{std::vector<size_t>(records.size(), static_cast<size_t>(-1)), {}};
  std::vector<size_t> order(records.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return records[a].amplitude_v < records[b].amplitude_v; });
  double start = NAN, sum = 0;
  size_t count = 0;
  for (size_t i : order) {
    const double v = records[i].amplitude_v;
    if (!std::isfinite(v)) continue;
    if (count == 0 || v > start * (1 + kLevelTolerance)) {
      if (count) levels.amplitude_v.push_back(sum / static_cast<double>(count));
      start = v;
      sum = 0;
      count = 0;
    }
    levels.level_of[i] = levels.amplitude_v.size();
    sum += v;
    ++count;
  }
  if (count) levels.amplitude_v.push_back(sum / static_cast<double>(count));
  return levels;
}

namespace {

// A CSV field: quoted when it holds a separator, a quote or a line break.
std::string Field(const std::string& text) {
  if (text.find_first_of(",\"\n\r") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

}  // namespace

std::string Cell(double value) { return std::isfinite(value) ? Format("%.10g", value) : std::string(); }

void WriteRows(const std::filesystem::path& path, const std::vector<std::vector<std::string>>& rows) {
  std::ofstream out(path);
  for (const auto& row : rows) {
    for (size_t i = 0; i < row.size(); ++i) out << (i ? "," : "") << Field(row[i]);
    out << "\n";
  }
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

void WriteCandidates(const std::vector<CandidateFit>& candidates, int chosen, const std::filesystem::path& path) {
  std::vector<std::vector<std::string>> rows = {
      {"label", "chosen", "fitted", "converged", "heldout_gain", "fit_gain", "nrmse", "heldout_nrmse", "chi2",
       "heldout_chi2", "residual_variance", "passes", "wall_time_s", "decision", "note"}};
  for (size_t i = 0; i < candidates.size(); ++i) {
    const CandidateFit& c = candidates[i];
    rows.push_back({c.label, static_cast<int>(i) == chosen ? "1" : "0", c.fitted ? "1" : "0",
                    c.converged ? "1" : "0", Cell(c.heldout_gain), Cell(c.fit_gain), Cell(c.figures.nrmse),
                    Cell(c.figures.heldout_nrmse), Cell(c.figures.chi2), Cell(c.figures.heldout_chi2),
                    Cell(c.figures.residual_variance), std::to_string(c.passes), Cell(c.seconds), c.decision,
                    c.note});
  }
  WriteRows(path, rows);
}

// The candidates' effect parameters, one per row (a parameter's unit is its own, so it is a column).
void WriteCandidateParameters(const std::vector<CandidateFit>& candidates, const std::filesystem::path& path) {
  std::vector<std::vector<std::string>> rows = {{"candidate", "parameter", "value", "standard_error", "unit"}};
  for (const CandidateFit& c : candidates) {
    for (const FitParameter& p : c.effect_parameters)
      rows.push_back({c.label, p.name, Cell(p.value), p.fixed ? std::string() : Cell(p.standard_error), p.unit});
  }
  WriteRows(path, rows);
}

void WriteText(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

void CreateReportDirectory(const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw std::runtime_error("cannot create " + dir.string() + ": " + ec.message());
}

// Both models' maps, when both were swept.
namespace {

bool HaveBothMaps(const DiagnosisMaps* maps) { return maps && maps->note.empty() && maps->base && maps->diagnosed; }

void WriteThresholdShifts(const DiagnosisMaps* maps, const std::filesystem::path& path) {
  const std::vector<std::string> columns = {
      "frequency_hz",          "grazing_base_v",           "grazing_diagnosed_v",
      "grazing_shift_v",       "grazing_shift_percent",    "lowest_contact_base_v",
      "lowest_contact_diagnosed_v", "lowest_contact_shift_v", "lowest_contact_shift_percent"};
  std::vector<std::vector<double>> values(columns.size());
  if (HaveBothMaps(maps)) {
    for (const ThresholdShift& t : ThresholdShifts(*maps->base, *maps->diagnosed)) {
      const double row[] = {t.frequency_hz,          t.base_grazing_v,           t.diagnosed_grazing_v,
                            t.GrazingShiftV(),       t.GrazingShiftPercent(),    t.base_lowest_contact_v,
                            t.diagnosed_lowest_contact_v, t.LowestContactShiftV(), t.LowestContactShiftPercent()};
      for (size_t k = 0; k < columns.size(); ++k) values[k].push_back(row[k]);
    }
  }
  CsvTable table(columns);
  for (size_t k = 0; k < columns.size(); ++k) table.SetColumn(columns[k], values[k]);
  table.Write(path);
}

void WriteJumpIntervals(const DiagnosisMaps* maps, const std::filesystem::path& path) {
  std::vector<std::vector<std::string>> rows = {
      {"model", "amplitude_v", "bistable_from_hz", "bistable_to_hz", "from_kind", "to_kind"}};
  if (HaveBothMaps(maps)) {
    for (const auto& [name, result] : {std::pair{"base", &*maps->base}, std::pair{"diagnosed", &*maps->diagnosed}}) {
      for (const JumpInterval& j : result->jump)
        rows.push_back({name, Cell(j.amplitude_v), Cell(j.bistable_from_hz), Cell(j.bistable_to_hz), j.from_kind,
                        j.to_kind});
    }
  }
  WriteRows(path, rows);
}


}  // namespace

void WriteSharedFiles(const std::vector<CandidateFit>& candidates, int chosen, const DiagnosisMaps* maps,
                      const ActuatorModel& model, const std::filesystem::path& dir) {
  WriteCandidates(candidates, chosen, dir / "candidates.csv");
  WriteCandidateParameters(candidates, dir / "candidate_parameters.csv");
  WriteThresholdShifts(maps, dir / "threshold_shift.csv");
  WriteJumpIntervals(maps, dir / "jump_intervals.csv");
  WriteText(dir / "model.json", ModelToJson(model).dump(2) + "\n");
}

}  // namespace diagnose_internal

namespace {

using namespace diagnose_internal;

void WriteRecords(const Diagnosis& d, const std::filesystem::path& path) {
  std::vector<std::vector<std::string>> rows = {
      {"name", "frequency_hz", "amplitude_v", "heldout", "clear", "nrmse_before", "chi2_before", "model_period_before",
       "contacts_per_period_before", "nrmse_after", "chi2_after", "model_period_after", "contacts_per_period_after"}};
  for (size_t i = 0; i < d.before.size(); ++i) {
    const RecordMatch& b = d.before[i];
    std::vector<std::string> row = {b.name,           Cell(b.frequency_hz), Cell(b.amplitude_v),
                                    b.heldout ? "1" : "0", b.clear ? "1" : "0", Cell(b.nrmse),
                                    Cell(b.chi2),     std::to_string(b.model_period), Cell(b.model_contacts_per_period)};
    if (i < d.after.size()) {
      const RecordMatch& a = d.after[i];
      row.insert(row.end(),
                 {Cell(a.nrmse), Cell(a.chi2), std::to_string(a.model_period), Cell(a.model_contacts_per_period)});
    } else {
      row.resize(rows[0].size());
    }
    rows.push_back(std::move(row));
  }
  WriteRows(path, rows);
}

void WriteLevels(const Diagnosis& d, const std::filesystem::path& path) {
  const std::vector<std::string> columns = {"amplitude_v",           "clear_records",        "resonance_hz",
                                            "resonance_se_hz",       "second_harmonic_ratio", "third_harmonic_ratio",
                                            "mean_contact_time_s"};
  std::vector<std::vector<double>> values(columns.size());
  for (const Signatures::Level& l : d.signatures.levels) {
    const double row[] = {l.amplitude_v,           static_cast<double>(l.clear_records), l.resonance_hz,
                          l.resonance_se_hz,       l.second_harmonic_ratio,            l.third_harmonic_ratio,
                          l.mean_contact_time_s};
    for (size_t k = 0; k < columns.size(); ++k) values[k].push_back(row[k]);
  }
  CsvTable table(columns);
  for (size_t k = 0; k < columns.size(); ++k) table.SetColumn(columns[k], values[k]);
  table.Write(path);
}

}  // namespace

const std::vector<std::string>& DiagnosisReportFiles() {
  static const std::vector<std::string> files = {
      "index.html",          "records.csv",         "candidates.csv", "candidate_parameters.csv", "levels.csv",
      "threshold_shift.csv", "jump_intervals.csv",  "model.json"};
  return files;
}

void WriteDiagnosisReport(const Diagnosis& d, const std::filesystem::path& dir, const DiagnosisMaps* maps) {
  CreateReportDirectory(dir);
  WriteText(dir / "index.html", DiagnosisHtml(d, maps));
  WriteRecords(d, dir / "records.csv");
  WriteLevels(d, dir / "levels.csv");
  WriteSharedFiles(d.candidates, d.chosen, maps, d.model, dir);
}

}  // namespace strokelab::report
