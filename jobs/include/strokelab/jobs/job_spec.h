// Job specs (schema/job.schema.json) checked at the edge of the service and turned into core types.
//
// ValidateJob is the one check a submitted job goes through: the JSON Schema (types, ranges, enums,
// unknown fields; json_schema.h), then what a schema cannot say (below). Every failure throws
// strokelab::InputError whose field() is the JSON pointer of the offending field in the job
// ("/grid/amplitude_v/to") and whose bare_message() is one short sentence ("must be >= 0.001");
// the HTTP layer puts them into {"error": {"code", "message", "field"}}. A job that is too large
// throws JobLimitError, an InputError whose message names the limit, so that the HTTP layer can
// give it its own code.
//
// Checks in code, after the schema:
//   sweep     grid axes: to >= from, and to > from when points > 1 (pointer: .../to);
//             spacing "eq1": "to" must be left out, and the last frequency must be <= 10 kHz;
//             frequency points x amplitude points <= kMaxGridPoints (pointer: /grid);
//   simulate  duration_s x sample_rate_hz >= 2 samples and <= kMaxRecordSamples (pointer:
//             /duration_s); method "exact" needs a piecewise-linear model (pointer: /method;
//             the default, "auto", takes exact or cvode by the model: ChooseMethod, engine.h);
//   both      the model makes physical sense (core Validate; pointer /model/KEY with KEY as the job
//             wrote it, short key or JSON name), and no parameter is given twice (as m_p and mass_kg).
//   fit,      campaign: exactly one of path and id (pointer /campaign); options: FitOptions::IsValid
//   diagnose  and DiagnoseOptions::IsValid (pointer /options/NAME with the job's option name). Whether
//             the campaign exists and is valid is checked when the job is planned (jobs.h), where the
//             server's directories are known.
//
// Frequency spacing "eq1" is paper Eq. 1, w(n) = 10 pi 1.02^(n-1) rad/s: the grid is
// f_n = from x 1.02^(n-1) Hz for n = 1..points, i.e. GridAxis{from, from x 1.02^(points-1), points,
// geometric}. "from" defaults to the paper's 5 Hz (so {"spacing": "eq1", "points": 117} is the
// paper's grid, 5 .. 49.7 Hz, as `strokelab sweep --grid eq1`); "to" follows from from and points
// and is rejected if given.
#pragma once

#include <nlohmann/json.hpp>

#include "strokelab/diagnose/diagnose.h"
#include "strokelab/base/errors.h"
#include "strokelab/identify/fit.h"
#include "strokelab/sweep/sweep.h"

namespace strokelab::jobs {

// Caps on job sizes (issue 4, point 5). Per-axis caps (2000 points) are in the schema.
inline constexpr long long kMaxGridPoints = 200'000;         // frequency x amplitude points of one sweep
inline constexpr double kMaxRecordSamples = 10'000'000;      // samples of one simulate record (~250 MB)
inline constexpr double kEq1StartHz = 5.0;                   // paper Eq. 1: w(1) = 10 pi rad/s
inline constexpr double kEq1Ratio = 1.02;                    // paper Eq. 1 step, dimensionless
inline constexpr double kMaxFrequencyHz = 1e4;               // as the schema's frequency maximum

// A job over a size limit: bad input like any InputError, with the limit named in the message.
class JobLimitError : public InputError {
 public:
  using InputError::InputError;
};

// Schema, then the checks above. Throws InputError (or JobLimitError) naming the JSON pointer.
void ValidateJob(const nlohmann::json& job);

// A sweep job as a core SweepSpec (validated first, as ValidateJob; a job of another kind is an
// InputError at /kind). threads is left at 1: the service runs a sweep as separate tasks.
SweepSpec SweepSpecFromJob(const nlohmann::json& job);

// The options of a fit or diagnose job as core types (validated first, as ValidateJob; a job of
// another kind is an InputError at /kind). Defaults as `strokelab fit` and `strokelab diagnose`.
FitOptions FitOptionsFromJob(const nlohmann::json& job);
DiagnoseOptions DiagnoseOptionsFromJob(const nlohmann::json& job);

// A valid job as it runs (src/job_resolved.cc): the submitted spec with every default and preset
// spelled out. sweep: "model" as ModelToJson (every parameter), each grid axis as {from, to, points,
// spacing (linear | geometric; eq1 is geometric), values: every grid value, as the results carry
// it}, "thresholds"; simulate: "model", "duration_s", "sample_rate_hz", "method" as run ("cvode
// (auto: ...)"); fit, diagnose: "model" (the fit model's name) and "options", every option by its
// job name. Throws as ValidateJob on a job that is not valid.
nlohmann::json ResolvedJob(const nlohmann::json& job);

// Throws JobLimitError at /grid when frequency_points x amplitude_points > kMaxGridPoints.
void CheckGridSize(long long frequency_points, long long amplitude_points);

}  // namespace strokelab::jobs
