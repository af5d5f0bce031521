// The fit's model side, shared by the fit (fit_refine.cc) and the diagnosis (diagnose*.cc): a model's
// periodic steady state at a record's estimated drive, its harmonics in the record's response units,
// and what the record's sampling makes of them.
#pragma once

#include <complex>
#include <optional>
#include <vector>

#include "strokelab/identify/campaign.h"
#include "strokelab/engines/engine.h"
#include "strokelab/identify/fit.h"
#include "strokelab/model/model.h"

namespace strokelab::internal {

// A periodic orbit to start the next shooting from.
struct Anchor {
  State start;
  int period = 1;  // 0: aperiodic
};

struct ModelOrbit {
  Anchor anchor;
  bool stable = true;
  double contacts_per_period = 0.0;
  std::vector<std::complex<double>> harmonics;  // response units, relative to the drive phase
};

// How hard SolveOrbit looks for the steady state.
enum class OrbitSearch {
  // For the cost function, at a bounded price: Newton on the anchor's period from the anchor; if it
  // fails (or the anchor is aperiodic), a fixed number of plain periods from the anchor and the
  // harmonics from there, a bounded stand-in that keeps the evaluation defined where the model has no
  // periodic orbit near the anchor.
  kNearby,
  // For anchors: Newton, and the attractor (SolveAttractor: long plain iteration, period search)
  // when Newton fails or finds an unstable orbit.
  kAttractor,
  // For branch choice: the attractor whose basin holds the anchor (SettledAttractor), which may differ
  // from the one kAttractor's early Newton finds where attractors coexist.
  kSettled,
};

// C_h of the response of `kind` from C_h of x at harmonic h of omega [rad/s] (f = m_p x'').
std::complex<double> ResponseHarmonic(std::complex<double> x_h, int h, double omega, ResponseKind kind,
                                      double mass_kg);

// The steady state of `model` at the record's drive, from `anchor`; nullopt when its harmonics are
// not finite. Throws NumericalError when an engine fails.
std::optional<ModelOrbit> SolveOrbit(const ActuatorModel& model, const RecordAnalysis& record, const Anchor& anchor,
                                     ResponseKind kind, int orders, OrbitSearch search);

// A periodic orbit's response harmonics with their exact derivatives in model parameters, from the
// variational flow (engines/variational_flow.h) over `period` periods from `start` (on the orbit):
// the orbit y* solves P(y*, p) = y*, so dy*/dp = (I - M)^{-1} dP/dp (M the monodromy), and
//   dC_h/dp = dC_h/dy0 . dy*/dp + dC_h/dp|y0.
// With period = 0 (no periodic orbit: `start` on a settled aperiodic motion, harmonics over
// kAperiodicPeriods) only the second term: the derivative of a fixed stretch of the motion. With no
// parameters, the harmonics alone (no monodromy, no sensitivities: a far smaller flow).
struct OrbitSlopes {
  std::vector<std::complex<double>> harmonics;               // response units, relative to the drive
  std::vector<std::vector<std::complex<double>>> d_harmonics;  // [j][h - 1]: d C_h / d parameters[j]
};
OrbitSlopes OrbitHarmonicSlopes(const ActuatorModel& model, const RecordAnalysis& record, State start, int period,
                                ResponseKind kind, int orders, const std::vector<double ActuatorModel::*>& parameters);

// sum_h |C_h - model_h|^2 and sum_h |C_h|^2 over the record's usable harmonics.
double MismatchSquared(const RecordAnalysis& record, const std::vector<std::complex<double>>& model);
double PowerOf(const RecordAnalysis& record);
// Real residuals a record's harmonics 1..orders give a fit: 2 per usable harmonic (a masked one has
// weight 0 and is no degree of freedom of the residual variance).
size_t FittedResiduals(const RecordAnalysis& record, int orders);

// Moves `anchor` to the orbit SolveOrbit (kAttractor) finds from it for `model`; keeps it when none
// is found or an engine fails.
void MoveAnchor(const ActuatorModel& model, const RecordAnalysis& record, ResponseKind kind, int orders,
                Anchor* anchor);

// The stable orbit that matches the record best among the attractors reached (kAttractor and kSettled)
// from the clipped linear start, from rest, from half the linear start and from the stops (a record
// where attractors coexist may sit on any of them).
std::optional<ModelOrbit> BestMatchingOrbit(const ActuatorModel& model, const RecordAnalysis& record,
                                            ResponseKind kind, int orders);

// The mean displacement [m] over one period of a period-1 orbit at `drive` (its harmonics leave it
// out), from 256 samples of the variational flow's dense output; 0 for orbits of another period.
double OrbitMeanDisplacement(const ActuatorModel& model, const SineDrive& drive, const Anchor& anchor);

// The model's response on the record's own sample grid over its analysis window (samples
// window.begin .. window.end of a record of window.end samples; earlier samples are the orbit too),
// in response units, from a period-1 orbit (the exact engine; the variational flow's dense output for
// models that are not piecewise linear). Empty for orbits of another period.
std::vector<double> OrbitOnRecordGrid(const ActuatorModel& model, const RecordAnalysis& a, const ModelOrbit& orbit,
                                      ResponseKind kind);

// Whether every drive period of the record's window starts at one position between two samples
// (fs / f a whole number: 5 and 8 Hz at 51.2 kHz), so that every period samples an impact's kinks at
// the same place. The chi-square then moves unevenly where a kink crosses a sample, and the paper
// fit's standard errors understate (fit.cc warns; README, the paper fit's errors).
bool SamplesEveryPeriodAlike(const RecordAnalysis& record);

// What the record's sampling and least-squares fit make of the model's response, less the orbit's
// continuous-time harmonics (fit_orbit.cc), and the variance that the sampling adds to the record's
// harmonics where the response jumps. Zero for orbits of period other than 1.
struct SampledCorrection {
  std::vector<std::complex<double>> harmonics;  // added to the orbit's C_h [response units]
  double jitter_variance = 0.0;                 // per Re and Im of a harmonic [response units^2]
};
SampledCorrection SamplingCorrection(const ActuatorModel& model, const RecordAnalysis& a, const ModelOrbit& orbit,
                                     ResponseKind kind, int orders);
// The variance of Re and Im of the record's harmonics about the model's: its noise's and the jitter.
// For judging a model only (per-record and held-out chi-squares): fits weigh, and candidates are
// compared, by the noise alone. The jitter is the model's own, and a fit that weighed by it bought a
// small chi-square with a large one (a stop at the resolution's stiffness with c_s = 1200 N s/m, on a
// campaign with a concealed second stop).
inline double HarmonicVariance(const RecordAnalysis& a, const SampledCorrection& sampled) {
  return a.harmonic_se * a.harmonic_se + sampled.jitter_variance;
}

}  // namespace strokelab::internal
