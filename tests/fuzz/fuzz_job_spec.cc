// libFuzzer harness: a job as POST /v1/jobs receives it. The input is parsed as JSON; a document
// goes through ValidateJob (JSON Schema, then the checks in code), the sweep conversion and
// PlanTasks, as the service does before storing a job.
//
// The contract checked (job_spec.h): bad input throws strokelab::InputError and nothing else. Any
// other exception (a json::type_error from a field the schema should have vetted, std::out_of_range,
// ...) escapes and libFuzzer reports it as a crash, as it does sanitizer reports.
#include <cstddef>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string_view>

#include "strokelab/base/errors.h"
#include "strokelab/jobs/job_spec.h"
#include "strokelab/jobs/jobs.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using nlohmann::json;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  // Not JSON: the service answers 400 bad_json before any of the code under test runs.
  const json job = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (job.is_discarded()) return 0;
  try {
    strokelab::jobs::ValidateJob(job);
    if (job.at("kind") == "sweep") {
      const strokelab::SweepSpec spec = strokelab::jobs::SweepSpecFromJob(job);
      (void)spec.frequency_hz.Values();
      (void)spec.amplitude_v.Values();
    }
    // No campaign directories: fit and diagnose jobs are refused here with an InputError.
    (void)strokelab::jobs::PlanTasks(job);
  } catch (const strokelab::InputError&) {
    // The expected outcome for most inputs (JobLimitError is one too).
  }
  return 0;
}
