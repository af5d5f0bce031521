// What a fit or diagnose job's status warns of, a few words each (the job's "warnings", shown by the
// web page in amber): such a job may succeed as a computation and still leave a doubtful model, and
// then must not read as a plain success. Stored with the task's result as rows of table "warnings"
// ({"warning": ...}; jobs.h).
#pragma once

#include <string>
#include <vector>

#include "strokelab/diagnose/broadband_diagnose.h"
#include "strokelab/diagnose/diagnose.h"
#include "strokelab/identify/broadband_fit.h"
#include "strokelab/identify/fit.h"
#include "strokelab/jobs/task.h"

namespace strokelab::jobs {

// "fit did not converge" (the refinement ran and did not converge), "k_s held at a bound" (per
// parameter the refinement left on a bound of its range, as its warnings name it).
std::vector<std::string> FitWarnings(const FitResult& fit);

// Of a broadband or joint fit (broadband_fit.h): "fit did not converge", "the records reject the fit"
// (its chi-square beyond the 1e-3 tail of noise alone), "k_s held at a bound" (per parameter that ended
// on a bound of its range).
std::vector<std::string> BroadbandFitWarnings(const strokelab::internal::BroadbandFitResult& fit);

// Of the diagnosed model's fit: the chosen candidate's ("fit did not converge (cubic_stiffness)",
// "k_s held at a bound", "k3 not identifiable"), or the base fit's (FitWarnings) when nothing is
// missing.
std::vector<std::string> DiagnosisWarnings(const Diagnosis& diagnosis);

// The same for a broadband diagnosis: the chosen candidate's, or its base fit's (BroadbandFitWarnings).
std::vector<std::string> BroadbandDiagnosisWarnings(const BroadbandDiagnosis& diagnosis);

// The warnings as result rows of table "warnings" ({"warning": ...}).
std::vector<ResultRow> WarningRows(const std::vector<std::string>& warnings);

}  // namespace strokelab::jobs
