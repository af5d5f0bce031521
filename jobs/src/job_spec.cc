#include "strokelab/jobs/job_spec.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "strokelab/engines/engine.h"
#include "strokelab/model/model_json.h"
#include "strokelab/jobs/json_schema.h"

namespace strokelab::jobs {
namespace {

using nlohmann::json;

std::string FormatNumber(double x) {
  if (std::isfinite(x) && x == std::floor(x) && std::abs(x) < 1e15) return std::to_string(static_cast<long long>(x));
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, x);
  return std::string(buffer, result.ptr);
}

void CheckSchema(const json& job) {
  if (auto violation = ValidateAgainstSchema(BuiltInSchema("job"), job))
    throw InputError(violation->pointer, violation->message);
}

// The model of a job, with errors at the key the job used: core reports a physically wrong value
// under its JSON name ("/model/mass_kg") even when the job wrote the short key ("m_p").
ActuatorModel ModelFromJob(const json& job) {
  const json& model = job.at("model");
  if (model.is_object()) {
    for (const ParameterInfo& info : Parameters()) {
      if (std::string(info.key) != info.json_name && model.contains(info.key) && model.contains(info.json_name))
        throw InputError(std::string("/model/") + info.json_name,
                         std::string("gives the same parameter as ") + info.key + " (give one of them)");
    }
  }
  try {
    return ModelFromJson(model, "/model");
  } catch (const InputError& e) {
    std::string field = e.field();
    if (field.rfind("/model", 0) != 0) field = "/model";  // a preset error names "model"
    if (model.is_object() && field.rfind("/model/", 0) == 0) {
      const std::string key = field.substr(7);
      for (const ParameterInfo& info : Parameters())
        if (key == info.json_name && !model.contains(key) && model.contains(info.key))
          field = std::string("/model/") + info.key;
    }
    throw InputError(field, e.bare_message());
  }
}

// One linear or geometric axis of a validated grid: from, to, points; to >= from.
GridAxis ReadRangeAxis(const json& axis, const std::string& pointer, bool geometric) {
  const double from = axis.at("from").get<double>(), to = axis.at("to").get<double>();
  const int points = static_cast<int>(axis.at("points").get<double>());
  if (to < from) throw InputError(pointer + "/to", "must be >= from (" + FormatNumber(from) + ")");
  if (points > 1 && to == from) throw InputError(pointer + "/to", "must be > from when points > 1");
  return GridAxis{from, to, points, geometric};
}

// Paper Eq. 1: f_n = from x 1.02^(n-1) Hz, n = 1..points.
GridAxis ReadEq1Axis(const json& axis, const std::string& pointer) {
  if (axis.contains("to"))
    throw InputError(pointer + "/to",
                     "must be left out with spacing eq1 (the grid is from x 1.02^(n-1) for n = 1..points)");
  const double from = axis.value("from", kEq1StartHz);
  const int points = static_cast<int>(axis.at("points").get<double>());
  const double last = from * std::pow(kEq1Ratio, points - 1);
  if (!(last <= kMaxFrequencyHz)) {
    const int max_points = 1 + static_cast<int>(std::floor(std::log(kMaxFrequencyHz / from) / std::log(kEq1Ratio)));
    char last_text[32];
    std::snprintf(last_text, sizeof last_text, "%.5g", last);
    throw InputError(pointer + "/points", "with spacing eq1 the last frequency, from x 1.02^(points-1) = " +
                                              std::string(last_text) + " Hz, must be <= " + FormatNumber(kMaxFrequencyHz) +
                                              " Hz (at most " + std::to_string(max_points) + " points from " +
                                              FormatNumber(from) + " Hz)");
  }
  return GridAxis{from, last, points, true};
}

// A core SweepSpec::Validate field ("frequency_hz.to", "grid", "m_p") as a job pointer.
std::string PointerForSweepField(const std::string& field) {
  if (field.rfind("frequency_hz", 0) == 0 || field.rfind("amplitude_v", 0) == 0) {
    std::string pointer = "/grid/" + field;
    for (char& c : pointer)
      if (c == '.') c = '/';
    return pointer;
  }
  if (field == "grid") return "/grid";
  for (const ParameterInfo& info : Parameters())
    if (field == info.key) return std::string("/model/") + info.json_name;
  return "/" + field;
}

// A sweep job that passed the schema.
SweepSpec SweepFromSchemaValidJob(const json& job) {
  SweepSpec spec;
  const json& grid = job.at("grid");
  const json& frequency = grid.at("frequency_hz");
  const std::string spacing = frequency.value("spacing", std::string("linear"));
  spec.frequency_hz = spacing == "eq1" ? ReadEq1Axis(frequency, "/grid/frequency_hz")
                                       : ReadRangeAxis(frequency, "/grid/frequency_hz", spacing == "geometric");
  spec.amplitude_v = ReadRangeAxis(grid.at("amplitude_v"), "/grid/amplitude_v", false);
  CheckGridSize(spec.frequency_hz.points, spec.amplitude_v.points);
  spec.model = ModelFromJob(job);
  spec.thresholds = job.value("thresholds", true);
  spec.threads = 1;
  try {
    Validate(spec);  // everything above should have caught it: a safety net with the right pointer
  } catch (const InputError& e) {
    throw InputError(PointerForSweepField(e.field()), e.bare_message());
  }
  return spec;
}

// A simulate job that passed the schema; defaults as in `strokelab simulate` and jobs.cc.
void CheckSimulateJob(const json& job) {
  const ActuatorModel model = ModelFromJob(job);
  SimulationOptions options;
  options.duration_s = job.value("duration_s", options.duration_s);
  options.sample_rate_hz = job.value("sample_rate_hz", options.sample_rate_hz);
  const double samples = options.duration_s * options.sample_rate_hz;
  if (samples > kMaxRecordSamples)
    throw JobLimitError("/duration_s", "duration_s x sample_rate_hz = " + FormatNumber(samples) +
                                           " samples exceeds the limit of " + FormatNumber(kMaxRecordSamples) +
                                           " samples per record");
  try {
    Validate(options);
  } catch (const InputError& e) {
    throw InputError("/" + e.field(), e.bare_message());
  }
  try {
    (void)ChooseMethod(job.value("method", std::string("auto")), model);
  } catch (const InputError& e) {
    throw InputError("/method", e.bare_message());
  }
}

// A FitOptions or DiagnoseOptions field ("harmonic_orders", "heldout_every") as the pointer of the
// job option that sets it (FitOptionFields, DiagnoseOptionFields).
std::string PointerForOptionField(const std::string& field) {
  if (const OptionInfo<FitOptions>* info = FindOption(FitOptionFields(), field))
    return std::string("/options/") + info->job_name;
  if (const OptionInfo<DiagnoseOptions>* info = FindOption(DiagnoseOptionFields(), field))
    return std::string("/options/") + info->job_name;
  return "/options/" + field;
}

// Throws InputError at the option's pointer when IsValid names a wrong field.
template <typename Options>
void CheckOptions(const Options& options) {
  if (const std::optional<FieldError> error = options.IsValid())
    throw InputError(PointerForOptionField(error->field), error->message);
}

// The options of `table` that a job's (schema-valid) "options" object gives, into *out; the others
// keep their defaults.
template <typename Options>
void ReadJobOptions(const json& options, const std::vector<OptionInfo<Options>>& table, Options* out) {
  for (const OptionInfo<Options>& info : table)
    std::visit([&](auto member) { out->*member = options.value(info.job_name, out->*member); }, info.member);
}

// The FitOptions of a fit or diagnose job that passed the schema.
FitOptions FitFromSchemaValidJob(const json& job) {
  FitOptions fit;
  fit.model = ParseFitModel(job.value("model", std::string("paper")));
  ReadJobOptions(job.value("options", json::object()), FitOptionFields(), &fit);
  return fit;
}

DiagnoseOptions DiagnoseFromSchemaValidJob(const json& job) {
  DiagnoseOptions diagnose;
  diagnose.fit = FitFromSchemaValidJob(job);
  ReadJobOptions(job.value("options", json::object()), DiagnoseOptionFields(), &diagnose);
  return diagnose;
}

// The checks of a fit or diagnose job after the schema.
void CheckCampaignJob(const json& job) {
  const json& campaign = job.at("campaign");
  if (campaign.contains("path") == campaign.contains("id"))
    throw InputError("/campaign", "must give exactly one of path (under the server's data root) and id (an upload)");
  if (job.at("kind") == "fit") CheckOptions(FitFromSchemaValidJob(job));
  else CheckOptions(DiagnoseFromSchemaValidJob(job));
}

}  // namespace

void CheckGridSize(long long frequency_points, long long amplitude_points) {
  const long long total = frequency_points * amplitude_points;
  if (total > kMaxGridPoints)
    throw JobLimitError("/grid", "frequency points x amplitude points = " + std::to_string(frequency_points) + " x " +
                                     std::to_string(amplitude_points) + " = " + std::to_string(total) +
                                     " exceeds the limit of " + std::to_string(kMaxGridPoints) +
                                     " grid points per job");
}

void ValidateJob(const json& job) {
  CheckSchema(job);
  const std::string& kind = job.at("kind").get_ref<const std::string&>();
  if (kind == "sweep") {
    (void)SweepFromSchemaValidJob(job);
  } else if (kind == "simulate") {
    CheckSimulateJob(job);
  } else if (kind == "fit" || kind == "diagnose") {
    CheckCampaignJob(job);
  } else {
    // The schema's kind enum and this dispatch must list the same kinds.
    BrokenInvariant("job kind '" + kind + "' passed the schema but has no checks in job_spec.cc");
  }
}

SweepSpec SweepSpecFromJob(const json& job) {
  CheckSchema(job);
  if (job.at("kind") != "sweep") throw InputError("/kind", "must be sweep");
  return SweepFromSchemaValidJob(job);
}

FitOptions FitOptionsFromJob(const json& job) {
  ValidateJob(job);
  if (job.at("kind") != "fit" && job.at("kind") != "diagnose") throw InputError("/kind", "must be fit or diagnose");
  return FitFromSchemaValidJob(job);
}

DiagnoseOptions DiagnoseOptionsFromJob(const json& job) {
  ValidateJob(job);
  if (job.at("kind") != "diagnose") throw InputError("/kind", "must be diagnose");
  return DiagnoseFromSchemaValidJob(job);
}

}  // namespace strokelab::jobs
