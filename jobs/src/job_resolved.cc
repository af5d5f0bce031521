// A job as it runs (job_spec.h ResolvedJob): the submitted spec with every default and preset
// spelled out, so that a job's status says what it computed.
#include <nlohmann/json.hpp>
#include <string>
#include <variant>
#include <vector>

#include "strokelab/base/json_number.h"
#include "strokelab/engines/engine.h"
#include "strokelab/jobs/job_spec.h"
#include "strokelab/model/model_json.h"

namespace strokelab::jobs {
namespace {

using nlohmann::json;

// One axis as it runs: its range, spacing and every value (as Values() gives them: the numbers the
// results carry and an amplitude query must name).
json AxisJson(const GridAxis& axis) {
  return {{"from", JsonNumber(axis.from)},
          {"to", JsonNumber(axis.to)},
          {"points", axis.points},
          {"spacing", axis.geometric ? "geometric" : "linear"},
          {"values", JsonNumbers(axis.Values())}};
}

// Every option of `table`, by its job name, at the value `options` holds.
template <typename Options>
void AddOptions(const std::vector<OptionInfo<Options>>& table, const Options& options, json* out) {
  for (const OptionInfo<Options>& info : table)
    std::visit([&](auto member) { (*out)[info.job_name] = options.*member; }, info.member);
}

}  // namespace

json ResolvedJob(const json& job) {
  // SweepSpecFromJob, FitOptionsFromJob and DiagnoseOptionsFromJob validate the job themselves: the
  // schema is checked once (it is most of the cost of GET /v1/jobs/{id}).
  const std::string kind = job.is_object() && job.contains("kind") && job["kind"].is_string() ? job["kind"] : "";
  if (kind != "sweep" && kind != "fit" && kind != "diagnose") ValidateJob(job);
  json resolved = job;
  if (kind == "sweep") {
    const SweepSpec spec = SweepSpecFromJob(job);
    resolved["model"] = ModelToJson(spec.model);
    resolved["grid"] = {{"frequency_hz", AxisJson(spec.frequency_hz)}, {"amplitude_v", AxisJson(spec.amplitude_v)}};
    resolved["thresholds"] = spec.thresholds;
  } else if (kind == "simulate") {
    const ActuatorModel model = ModelFromJson(job.at("model"), "/model");
    resolved["model"] = ModelToJson(model);
    resolved["duration_s"] = job.value("duration_s", SimulationOptions{}.duration_s);
    resolved["sample_rate_hz"] = job.value("sample_rate_hz", SimulationOptions{}.sample_rate_hz);
    resolved["method"] = ChooseMethod(job.value("method", std::string("auto")), model).Describe();
  } else {
    json options = json::object();
    if (kind == "fit") {
      AddOptions(FitOptionFields(), FitOptionsFromJob(job), &options);
    } else {
      const DiagnoseOptions diagnose = DiagnoseOptionsFromJob(job);
      AddOptions(FitOptionFields(), diagnose.fit, &options);
      AddOptions(DiagnoseOptionFields(), diagnose, &options);
    }
    resolved["model"] = job.value("model", std::string("paper"));
    resolved["options"] = std::move(options);
  }
  return resolved;
}

}  // namespace strokelab::jobs
