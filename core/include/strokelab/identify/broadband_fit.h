// Output-error fit of a model to broadband records (noise, multisine, sweep, any measured voltage) by
// their time series, with multiple shooting:
//
//   each record is cut into segments of segment_s; each segment's initial state is an unknown, and
//   the model is flowed over the segment driven by the first-order hold of the measured voltage
//   (variational_flow.h, SampledDrive), with its exact sensitivities at every sample. Residuals, one
//   per sample, are (y_n - offset - hum(t_n) - r(t_n)) / sigma, r the model's response of the
//   campaign's kind (blocked force m_p x'', acceleration, velocity or displacement) and sigma the
//   record's white-noise level; the segments join through continuity residuals (end state of one
//   segment minus the start of the next) weighted so that a gap of 1e-6 of the model's length scale
//   costs as much as one noise standard error. Offset and mains hum (50 and 60 Hz, kHumOrders orders
//   each) are per-record unknowns, as for stepped sines.
//
// Multiple shooting keeps a long record's problem well posed: a segment's sensitivities do not grow
// over the record, and a poor start value cannot send the orbit into another attractor for the rest
// of it (H. G. Bock and K. J. Plitt, "A multiple shooting algorithm for direct solution of optimal
// control problems", IFAC Proceedings 17(2), 1984; for output-error identification, e.g. A. H.
// Ribeiro et al., "On the smoothness of nonlinear system identification", Automatica 121, 2020).
//
// One nonlinear least-squares problem (Ceres, Levenberg-Marquardt, sparse normal equations): converged
// means Ceres' own convergence test. Standard errors are from the true Jacobian at the solution,
// (J^T J)^-1 restricted to the model's parameters (the segments' states, offsets and hum eliminated),
// scaled by the residual variance SSR / (M - P_total).
//
// Known limit: records with hard impacts (force spikes hundreds of noise levels high) make the misfit
// rugged, and a start 10 % from the truth in the stop's parameters can end in a valley away from the
// optimum. Such a fit is reported as rejected (its chi-square far beyond the noise), never as a result.
//
// The voltage channel is taken as the drive (its DC offset, if any, is part of it), and the response's
// sensitivity as written: with a nominal sensitivity only ratios are identifiable (fit.h).
#pragma once

#include <span>
#include <string>
#include <vector>

#include "strokelab/identify/campaign.h"
#include "strokelab/identify/extended_fit.h"

namespace strokelab::internal {

struct BroadbandFitResult;

struct BroadbandFitOptions {
  double segment_s = 0.25;     // shooting segment length [s]; a record shorter than one is one segment
  int max_iterations = 100;    // Ceres iterations
  double max_seconds = 120.0;  // wall time [s]
  int threads = 0;             // Ceres' evaluation threads; 0: one per core
  // Keep each record's residual and the model's state at every sample (BroadbandRecordFit's series):
  // the diagnosis's signatures and held-out figures read them.
  bool keep_series = false;
  // A fit of the same records with the same segment_s whose segment starts, offsets and hum this fit
  // starts from, at its final continuity weight (may be null). From a model that the warm start's
  // fitted, the misfit can then only go down: where the records hold impacts, starts fitted afresh at
  // another model can settle in a valley of their own (an impact missed or made up).
  const BroadbandFitResult* warm_start = nullptr;
  // Each record's white-noise level, one per record in order, and how many samples it was estimated
  // from (the rejection limit counts that estimate's spread). Empty: estimated from each record
  // (ResponseNoiseRms). The diagnosis estimates it once from the whole record, whose parts it
  // fits and evaluates: four times the samples make the held-out test's limit tighter.
  struct NoiseLevel {
    double rms = 0.0;  // [response units]
    size_t samples = 0;
  };
  std::vector<NoiseLevel> noise;
  // Stepped-sine records fitted jointly with the broadband ones (a mixed campaign): each record's
  // harmonics 1..stepped_orders over their standard error, the extended fit's residuals with their exact
  // Jacobian (extended_fit.h), in the same problem and sharing the model's parameters. Each starts on its
  // best-matching orbit of the start model and follows it after every accepted step; the sampling
  // corrections are frozen during a solve and refreshed between solves until the parameters stay.
  std::vector<const RecordAnalysis*> stepped;
  int stepped_orders = 10;
};

// How the fitted model matches one stepped-sine record of a joint fit.
struct SteppedRecordFit {
  std::string name;
  double chi2 = 0.0;     // sum |(C_h - C_h^model) / se|^2 over the fitted harmonics
  size_t residuals = 0;  // two per usable harmonic: chi2 / residuals ~1 when only noise remains
};

// How the fitted model matches one record.
struct BroadbandRecordFit {
  std::string name;
  double noise_rms = 0.0;      // sigma [response units]: the white-noise level estimated from the record
  double offset = 0.0;         // fitted response offset [response units]
  double hum_amplitude = 0.0;  // the largest fitted hum component [response units]
  double nrmse_initial = 0.0;  // rms(residual) / rms(response - offset) at the start model
  double nrmse = 0.0;          // the same at the fitted model
  double chi2_per_sample = 0.0;  // sum (residual / sigma)^2 / samples: ~1 when only noise remains
  size_t segments = 0;
  // With BroadbandFitOptions::keep_series, per sample at the fitted unknowns: the residual y - offset -
  // hum - r [response units], and the model's displacement and velocity.
  std::vector<double> residual, x_m, v_m_per_s;
};

struct BroadbandFitResult {
  ExtendedFitResult fit;  // parameters, covariance, convergence, chi-square (M: the samples)
  // The records reject the fitted model: chi-square beyond its 1e-3 upper tail, the spread of the noise
  // levels it is scaled by included (the report says so).
  bool rejected = false;
  double dof = 0.0;         // the samples less every fitted unknown that is not tied by continuity
  double chi2_limit = 0.0;  // rejected beyond it: that 1e-3 tail
  std::vector<BroadbandRecordFit> records;
  std::vector<SteppedRecordFit> stepped;  // BroadbandFitOptions::stepped's, in order
  // The fitted unknowns besides the parameters (BroadbandFitOptions::warm_start): every segment's start
  // state, records in order (SegmentFirsts), and each record's offset and hum.
  std::vector<State> segment_starts;
  std::vector<std::vector<double>> nuisance;
};

// n var(sigma_est / sigma) of FourthDifferenceNoiseRms on n samples of white Gaussian noise: 2.52, 2.61
// and 2.41 at n = 2048, 8192 and 51200 (2000 draws each; the test checks it).
inline constexpr double kNoiseEstimateVariance = 2.5;

// White-noise rms of a record's channel from its fourth differences, which remove a signal whose band
// lies far below the sample rate: 1.4826 MAD(y[n-2] - 4 y[n-1] + 6 y[n] - 4 y[n+1] + y[n+2]) / sqrt(70)
// (the median absolute deviation is blind to the few samples of an impact).
double FourthDifferenceNoiseRms(std::span<const double> samples);
// The noise level a fit weights a record's response by: FourthDifferenceNoiseRms, or 1e-9 of the
// response's rms for a noiseless (synthetic) record.
double ResponseNoiseRms(std::span<const double> response);

// The samples of an impact: where the response's fourth difference stands out of its noise (70 sigma^2
// for white noise of rms sigma) by more than 8 standard deviations, and the two samples either side.
std::vector<bool> ImpactSamples(std::span<const double> y, double sigma);

// Where the records' impacts set in, as `model` without its stops sees them: for each impact after at
// least 10 ms without one, a stop position [m]. The stop-free model's start is fitted to the samples
// before the impact (up to 0.5 s of them; the offset at the record's mean, no hum): up to an impact the
// model follows the record. Then the position where a stop (on the side the motion is, with `model`'s
// contact law and stiffness) makes the model's flow from that start best match the 16 samples from 4
// before the impact's first mark (ImpactSamples): the best of a grid over where the stop-free motion
// passes in those samples, refined by golden-section search; where that lands on the grid's end, the
// stop-free displacement at the first fourth difference that stands out. Negative values tell the lower
// stop's position, positive ones an upper stop's. Records in order, each's impacts in time. Throws
// InputError as FitBroadband on a bad record, or on a bad model.
std::vector<double> ImpactOnsetsM(std::span<const Recording* const> records, ResponseKind kind,
                                  const ActuatorModel& model, const BroadbandFitOptions& options = {});

// The first sample of each shooting segment of a record of `samples` (segments of segment_s; the last
// ends at the record's end and takes a tail shorter than half a segment).
std::vector<size_t> SegmentFirsts(size_t samples, double sample_rate_hz, double segment_s);

// Fits problem.parameters to the broadband `records` of a campaign whose response is of `kind` (and to
// options.stepped's stepped-sine records with them). With no free parameters it evaluates problem.base:
// only the segments' starts, offsets and hum are fitted (the diagnosis's held-out records), and the
// result's parameters and covariance are empty. The chi-square, residual count and degrees of freedom
// count the stepped records' harmonics with the samples.
// Throws InputError naming a record that is not broadband, too short (fewer than 16 samples) or not
// finite, or bad options; NumericalError when the start model has no steady state at a stepped record.
BroadbandFitResult FitBroadband(std::span<const Recording* const> records, ResponseKind kind,
                                const ExtendedProblem& problem, const BroadbandFitOptions& options = {});

}  // namespace strokelab::internal
