// The open-world test of the diagnosis (diagnose.h, Unexplained): whether what a model leaves on the
// held-out records is noise, and if not, where it is. Public for its tests; DiagnoseCampaign runs it.
#pragma once

#include <Eigen/Dense>

#include <optional>
#include <span>
#include <string>
#include <vector>

#include "strokelab/diagnose/diagnose.h"
#include "strokelab/identify/fit.h"
#include "strokelab/model/model.h"

namespace strokelab::internal {

// kUnexplainedP is the test's size if the noise model held exactly (chi-square, by Wilson and
// Hilferty's approximation); its real rate on control campaigns (correct model, noise, hum, offsets,
// perturbed parameters) is measured by tests/diagnose/control_study.py and must stay below 1 in 20.
inline constexpr double kUnexplainedP = 1e-3;

// The held-out chi-square with the model's own parameter error counted (diagnose.h, Unexplained):
// with r the held-out residuals whitened by their noise, J the whitened slopes of each record's model
// harmonics in the model's free parameters (fit_orbit.h OrbitHarmonicSlopes), C = L L^T = (J_f^T J_f)^-1
// over the fit records (weighted as fits weigh them, by the noise alone) and U = J_h L,
//   chi2 = r^T (I + U U^T)^-1 r = r^T r - b^T (I + U^T U)^-1 b,   b = U^T r   (Woodbury),
// which is chi-square(R) for a correct model. Parameters the fit records do not identify (the fits'
// rule, sparse_covariance.h ErrorsFromJacobian) are left out: nothing bounds their error, and the test
// judges their part of the residuals as noise.
struct HeldOutLeverage {
  double chi2 = 0.0;           // over the held-out records, the parameters' error counted
  double expected_chi2 = 0.0;  // the plain held-out chi-square's mean for a correct model: R + trace(U^T U)
  std::vector<double> record_chi2;  // each record's own (matches' order; NaN for fit records)
};
// One record as the statistic sees it: its whitened residuals and the whitened slopes of its model
// harmonics in the free parameters (rows alike; no columns where the slopes could not be had).
struct RecordLinearisation {
  Eigen::VectorXd residuals;
  Eigen::MatrixXd slopes;
  bool heldout = false;
};
// The statistic from the records' linearisations: the fit records' slopes make C, the held-out ones'
// are judged (record_chi2 in `records`' order).
HeldOutLeverage LeverageOf(std::span<const RecordLinearisation> records);
// The same for `model`'s matches: each record's slopes from its matched orbit. `fields`: the free
// parameters of `model`'s fit (BuildProblem's). Empty when nothing is held out or `fields` is empty; a
// record whose slopes cannot be had (no periodic orbit, an engine's failure) is judged on noise alone.
std::optional<HeldOutLeverage> MeasureHeldOutLeverage(const ActuatorModel& model,
                                                      const std::vector<double ActuatorModel::*>& fields,
                                                      const std::vector<RecordMatch>& matches,
                                                      std::span<const RecordAnalysis> analyses, ResponseKind kind,
                                                      int orders);

// Whether the held-out records' plain chi-square, nothing counted for the parameters' error, passes
// the test already (then it passes with that error counted too: counting it only lowers the statistic).
bool HeldOutWithinNoise(const std::vector<RecordMatch>& matches);

// `matches`: a model on every record (RecordMatch::heldout marks the held-out ones); `analyses` the
// same records in the same order (their impacts); `parameters` the number the model fitted; `leverage`
// (may be null: the mean inflation 1 + P / M instead) its parameters' error at each record. Empty when
// the held-out chi-square is within noise at kUnexplainedP.
std::optional<Unexplained> FindUnexplained(const std::vector<RecordMatch>& matches,
                                           std::span<const RecordAnalysis> analyses, size_t parameters,
                                           const HeldOutLeverage* leverage = nullptr);

// Whether `model`, which misses (FindUnexplained), misses some record by more than the base model did
// beyond noise (both lists: the same records in the same order). A model that explains part of what the
// base misses, right up to its parameters' error e, changes a record's chi-square by
//   D = |n + e|^2 - |n + e + d|^2 = -|d|^2 - 2 (n + e).d
// (whitened residuals: n the noise, d the base model's error there). With (n + e).d / |d| normal of
// variance at most s (kWorseThanTheBaseVariance: the noise, and the parameters' error counted as large),
// P(D > t) = P(Z > (t + |d|^2) / (2 sqrt(s) |d|)) <= P(Z > sqrt(t / s)) whatever d (the least at
// |d|^2 = t): a record is beyond noise where D > s z^2, z the normal's upper kUnexplainedP / records
// quantile. A library effect fitted to part of a misfit it does not hold buys its gain on some records
// with a loss on others (gen2 10037, suspension creep in no library: a force factor named, the 6 Hz,
// 0.3 V record's chi-square 34 -> 151; gen2 9969, a stop on a flexure: c2 named at 3.3 times its truth,
// 1,668 -> 5,061). Returns why the model is not named ("misses ..."), or empty.
std::string WorseThanTheBase(const std::vector<RecordMatch>& base, const std::vector<RecordMatch>& model);
inline constexpr double kWorseThanTheBaseVariance = 2.0;

// The force `model` lacks over (x, v) (MissingForceSurface), from every record's measured and model
// harmonics in `matches` (response channel `kind`); missing_force.cc.
MissingForceSurface EstimateMissingForce(const ActuatorModel& model, const std::vector<RecordMatch>& matches,
                                         ResponseKind kind);
// The ringing of `record`'s residual after its impacts (Unexplained::Place's ring_* figures): the
// record less `model`'s steady state on the record's own grid, less its offset, mains hum and drive
// harmonics 1..orders, averaged over the drive periods; after the impacts, the strongest frequency
// above harmonic `orders` and the decay of its amplitude, cycle pair by cycle pair (ringing.cc).
void FindRinging(const Recording& record, const RecordAnalysis& analysis, const ActuatorModel& model, ResponseKind kind,
                 int orders, Unexplained::Place* place);

// The first `places` places' ringing in words for Unexplained::description: "; in rec rings at about
// N Hz ..." for the worst ringing record confirmed by another of a different drive frequency, or "".
std::string DescribeRinging(const Unexplained& unexplained, ResponseKind kind, size_t places);
// The places whose ringing the diagnosis looks for and describes (the worst first).
inline constexpr size_t kRingPlaces = 3;

// The open-world test above the fitted harmonics: they say nothing of what rings after the impacts at
// a frequency above harmonic `orders`. Every record with impacts is looked at (FindRinging, at
// `model`); where two of the kRingPlaces strongest rings are one mode's (DescribeRinging's
// confirmation: records of different drive frequencies, one frequency in Hz), the misfit is
// unexplained: places are the ringing records, strongest ring first, with the held-out figures of
// `matches` (a model of `parameters` fitted parameters), which the description calls within noise
// where they pass. Else empty.
std::optional<Unexplained> FindRingAboveHarmonics(std::span<const Recording> records,
                                                  std::span<const RecordAnalysis> analyses,
                                                  const std::vector<RecordMatch>& matches, const ActuatorModel& model,
                                                  ResponseKind kind, int orders, size_t parameters);

// The surface in words for Unexplained::description: "; ..." (its closest single term), or its note.
std::string DescribeMissingForce(const MissingForceSurface& surface);

}  // namespace strokelab::internal
