// The DOP853 integration of variational_flow.h: steps with error control on the state and the
// sensitivity columns, switching surfaces located on the dense output, the step cut at each switch
// and the sensitivities' jump applied there.
//
// The two ends of a Hertzian contact are integrated over u = sqrt(p) instead of t. The stop force
// k_s p^1.5 makes the solution non-analytic in t where p = 0 (x ~ t^3.5 and the sensitivities ~ t^1.5
// after entry): an 8th-order step over or next to such a point is rejected until it is ~1e-10 s
// long, and the steps after it grow back by ~1.5x each (~100 tries per contact). With p = u^2 the
// solution is analytic in u (p^1.5 = u^3), and dt/du = 2u / p' is regular while the mass moves into
// or out of the stop (p' != 0). After entry, u grows from 0 while the time each step covers still
// grows (it stops growing as p' falls) and p' is above half its entry value; on the way out, once p
// is back under half its largest value, u falls to 0, which is the release (without contact damping
// the force vanishes exactly at p = 0). Time is then a component of the integrated vector (index n,
// after the layout's), and samples and time boundaries are found on its dense output. Where u fails
// as a chart (the mass turns round within the stop), the contact goes on over t.
#include "strokelab/engines/variational_flow.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <string>

#include "dop853_tableau.h"
#include "free_flight_map.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/illinois.h"
#include "variational_field.h"

namespace strokelab {
namespace {

// Step size control of Hairer, Norsett and Wanner, Sec. II.4 (as in their DOP853 code): the error
// estimate is of order 8 in h, the factor is bounded to [0.2, 10] with a safety factor of 0.9.
constexpr double kStepSafety = 0.9, kMinStepFactor = 0.2, kMaxStepFactor = 10.0;

// kStepSafety * error^(-1/8) by three square roots (std::pow was 3 % of a sweep's time).
double StepFactor(double error) { return kStepSafety / std::sqrt(std::sqrt(std::sqrt(error))); }

// The longest step, as a fraction of the shortest period of drive and suspension: at most one extremum
// of x per step, so that an apex shows a grazing contact the step's ends do not.
constexpr double kFlowMaxStepFraction = 1.0 / 20.0;

// An entry slower than this many length scales per shortest period grazes the stop: its contact is
// too brief for the change of variable to pay (and p' may turn at once), so it stays over t.
constexpr double kGrazingRate = 1e-3;
// The shortest step the flow resolves at time t, relative to t or to its largest step.
constexpr double kTimeResolution = 1e-14;

// Instants in (t0, t1) where the sine crosses the amplifier's limit: sin(w t + phi) = +-r, r = limit / V.
std::vector<double> ClippingKinks(const ActuatorModel& model, const SineDrive& drive, double t0, double t1) {
  std::vector<double> kinks;
  if (!model.HasAmplifierLimit() || drive.amplitude_v <= model.amplifier_limit_v) return kinks;
  const double omega = drive.AngularFrequency(), r = model.amplifier_limit_v / drive.amplitude_v;
  const double a = std::asin(r), two_pi = 2.0 * std::numbers::pi;
  const double angles[] = {a, std::numbers::pi - a, std::numbers::pi + a, two_pi - a};
  const double first_turn = std::floor((omega * t0 + drive.phase_rad) / two_pi);
  for (double turn = first_turn;; turn += 1.0) {
    bool past_end = false;
    for (double angle : angles) {
      const double t = (turn * two_pi + angle - drive.phase_rad) / omega;
      if (t >= t1) past_end = true;
      else if (t > t0) kinks.push_back(t);
    }
    if (past_end) break;
  }
  return kinks;
}

// The instants in (t0, t1) where a sampled drive is not smooth, in order: its samples t_k (the
// first-order hold's corners) and, between them, the straight line's crossings of +-limit.
std::vector<double> SampledDriveCorners(const ActuatorModel& model, const SampledDrive& drive, double t0, double t1) {
  std::vector<double> corners;
  const double fs = drive.sample_rate_hz;
  const size_t last = drive.voltage_v.size() - 1;
  const double first = std::max(0.0, std::floor(t0 * fs));
  for (size_t k = static_cast<size_t>(first); k <= last; ++k) {
    const double tk = static_cast<double>(k) / fs;
    if (tk >= t1) break;
    if (tk > t0) corners.push_back(tk);
    if (k == last || !model.HasAmplifierLimit()) continue;
    const double a = drive.voltage_v[k], b = drive.voltage_v[k + 1];
    for (const double level : {-model.amplifier_limit_v, model.amplifier_limit_v}) {
      if ((a - level) * (b - level) >= 0.0) continue;  // no crossing strictly inside
      const double t = tk + (level - a) / (b - a) / fs;
      if (t > t0 && t < t1) corners.push_back(t);
    }
  }
  std::sort(corners.begin(), corners.end());
  return corners;
}

// `boundaries` (in (t0, t1], sorted, t1 last) with each one where the drive crosses the amplifier's
// limit (the sides of the limit that the drive takes between it and its neighbours differ) split into
// an instant on the side before and one on the side after. The field jumps across the limit (the
// limit's column, and a sine's amplitude and frequency columns, are forced beyond it only), so a step
// whose end stage saw the drive on the other side (the crossing computed to rounding) would be rejected
// until it is short enough for its error estimate to pass. Each instant is taken where the drive lies
// kMarginUlps ulps of the limit clear of it, since a sine's stages compute the drive by angle addition
// from the step's start (its rounding differs from SineDrive::Voltage's), and within a quarter of the
// flow's time resolution of the crossing (kTimeResolution of t or of the largest step), so that Run
// passes the sliver between the two without a step.
std::vector<double> SplitLimitCrossings(const ActuatorModel& model, const variational::Drive& drive, double t0,
                                        double max_step_s, std::vector<double> boundaries) {
  constexpr int kMarginUlps = 32;
  const double limit_v = model.amplifier_limit_v;
  const double margin_v = kMarginUlps * (std::nextafter(limit_v, ActuatorModel::kNoLimit) - limit_v);
  auto beyond = [&](double t) { return std::abs(drive.Voltage(t)) > limit_v; };
  // From the crossing t towards `toward`, by doubling strides: the first instant clear on the side.
  auto clear_of = [&](double t, double toward, bool side_beyond) {
    const double cap = 0.25 * kTimeResolution * std::max(std::abs(t), max_step_s), direction = toward > t ? 1 : -1;
    double at = t;
    for (double stride = std::abs(std::nextafter(t, toward) - t); stride <= cap; stride *= 2) {
      const double u = std::abs(drive.Voltage(at));
      if (side_beyond ? u > limit_v + margin_v : u < limit_v - margin_v) break;
      at = t + direction * stride;
    }
    return at;
  };
  std::vector<double> split;
  for (size_t i = 0; i + 1 < boundaries.size(); ++i) {
    const double t = boundaries[i], before = i > 0 ? boundaries[i - 1] : t0, after = boundaries[i + 1];
    const bool side_before = beyond(0.5 * (before + t)), side_after = beyond(0.5 * (t + after));
    if (side_before == side_after) {
      split.push_back(t);
      continue;
    }
    split.push_back(clear_of(t, before, side_before));
    split.push_back(clear_of(t, after, side_after));
  }
  split.push_back(boundaries.back());
  return split;
}

// A root of g on the step's [0, 1] by the Illinois method (illinois.h), g(1) of the sign after the
// crossing and g(0) of the other sign or 0. Returns the end of the final bracket on g(1)'s side: the
// state there has crossed, so the new mode holds.
//
// g(0) = 0 happens where the step starts on the surface (a switch's state can be exactly on it, at the
// resolution of x). The crossing then is where g leaves the side it takes first: e.g. right after a
// grazing entry the stop force rises from 0 before it falls through 0 as the mass leaves, and a root
// at 0 would let go at once, enter again at once, and never advance. So the side g leaves 0 to is
// looked up at geometrically growing theta first.
template <typename G>
double LocateRootOnStep(const G& g, double g_start, double g_end) {
  double a = 0.0, b = 1.0, ga = g_start, gb = g_end;
  if (ga == 0.0) {
    for (double theta = 0x1p-50; theta < 1.0; theta *= 2.0) {
      const double value = g(theta);
      if (value == 0.0) continue;
      if ((value > 0) == (gb > 0)) return 0.0;  // it leaves 0 to the far side: the crossing is at the start
      a = theta;
      ga = value;
      break;
    }
    if (ga == 0.0) return 0.0;
  }
  IllinoisBracket bracket{a, b, ga, gb};
  for (int iteration = 0; iteration < 200 && bracket.Width() > 1e-15; ++iteration) {
    const double c = bracket.Next();
    const double gc = g(c);
    bracket.Update(c, gc);
    if (gc == 0.0) break;
  }
  return bracket.b;
}

// p' = dp/dt of a stop's penetration in the state y: -v for the lower stop, v for the upper.
double PenetrationRate(const variational::StopSurface& stop, const double* y) { return stop.upper ? y[1] : -y[1]; }

class FlowIntegrator {
 public:
  FlowIntegrator(const ActuatorModel& model, const variational::Drive& drive, const FlowRequest& request,
                 const FlowOptions& options)
      : field_(model, drive, request),
        drive_(drive),
        request_(request),
        options_(options),
        n_(field_.layout().size),
        width_(n_ + 1) {
    k_.assign(static_cast<size_t>(dop853::kExtendedStages) * width_, 0.0);
    y_.assign(width_, 0.0);
    y_new_.assign(width_, 0.0);
    stage_.assign(width_, 0.0);
    dense_.assign(static_cast<size_t>(dop853::kDenseTerms) * width_, 0.0);
    sample_y_.assign(width_, 0.0);
    // A sampled drive has no period: its steps end at every sample, and the suspension's period (or,
    // without one, the record) bounds them.
    double shortest_s = drive.sampled ? std::max(drive.sampled->DurationS(), 1.0 / drive.sampled->sample_rate_hz)
                                      : 1.0 / drive.sine.frequency_hz;
    if (model.stiffness_n_per_m > 0)
      shortest_s = std::min(shortest_s, 2.0 * std::numbers::pi * std::sqrt(model.mass_kg / model.stiffness_n_per_m));
    max_step_s_ = kFlowMaxStepFraction * shortest_s;
    // (The figures' extrema between samples are not sought by the exact map: they keep DOP853.)
    exact_free_flight_ = drive.sampled && options.exact_free_flight && !request.figures &&
                         variational::FreeFlightMap::Applies(model, request);
    shortest_period_s_ = shortest_s;
    // A column's absolute tolerances are the state's over the size of its perturbation: the length
    // scale for x0, the length scale times w for v0, |p| for a parameter (1 where p = 0).
    // (The coil's force: its size is the drive's force g V.)
    const variational::Layout& l = field_.layout();
    d_ = l.state_size;
    controlled_ = d_ * (1 + l.columns);
    // The speed scale: the length scale times the drive's angular frequency, or for a sampled drive
    // (no frequency) the shortest period's.
    const double omega = drive.sampled ? 2.0 * std::numbers::pi / shortest_s : drive.AngularFrequency();
    const double length_m = LengthScaleM(model), speed_m_per_s = length_m * omega;
    const double state_tolerance[] = {options.absolute_tolerance_m, options.absolute_tolerance_m_per_s,
                                      options.absolute_tolerance_n};
    const double state_size[] = {length_m, speed_m_per_s, std::abs(model.gain_n_per_v) * drive.PeakV()};
    absolute_tolerance_.assign(state_tolerance, state_tolerance + d_);
    for (int c = 0; c < l.columns; ++c) {
      double size = c < l.state_columns                      ? state_size[c]
                    : c == l.amplitude_column                ? drive.sine.amplitude_v
                    : c == l.frequency_column                ? drive.sine.frequency_hz
                                                             : std::abs(model.*request.parameters[c - l.state_columns]);
      if (!(size > 0) || !std::isfinite(size)) size = 1.0;
      const double looser = options.sensitivity_relative_tolerance / options.relative_tolerance;
      for (int i = 0; i < d_; ++i) absolute_tolerance_.push_back(looser * state_tolerance[i] / size);
    }
  }

  FlowResult Run(State start, double t0, double t1);

 private:
  const ActuatorModel& model() const { return field_.model(); }
  double* K(int stage) { return &k_[static_cast<size_t>(stage) * width_]; }
  double* DenseTerm(int i) { return &dense_[static_cast<size_t>(i) * width_]; }
  // Components integrated: the layout's, and time as the last one over u (see the top).
  int Active() const { return phase_.active ? width_ : n_; }
  // Stage s's argument y + h sum_j a_sj k_j into stage_, and the field there into dy.
  void StageState(int s, double h);
  void EvaluateStage(int s, double t, double h, const double* y, double* dy);
  // One DOP853 step of size h from (t, y_) with K(0) = f(t, y_); y_new_, K(12) = f(t + h, y_new_).
  // Returns the scaled error norm.
  double Step(double t, double h);
  // The dense output's coefficients over the step just taken (three more stages), once per step.
  void PrepareDense(double t, double h);
  // The interpolated component i at theta in [0, 1] of the step.
  double Interpolate(int i, double theta) const;
  // The state in the dense output at theta.
  State InterpolateState(double theta) const;
  void Note(double t, const State& y);
  // The requested samples at instants up to t_until within the step just taken from t (size h; over
  // u, t and h are the independent variable's and the instants are found on time's dense output).
  void Sample(double t, double h, double t_until);
  // The requested samples inside the step just taken over time from t to t_end, and those at t_end
  // from its end state and rate (no dense output: a sampled drive's steps end at its samples).
  void SampleTimeStep(double t, double h, double t_end);
  // Appends the sample at ts from the packed components y (the state, and the columns when the
  // request asks for their values at the samples); `dy`, the field there when known.
  void RecordSample(double ts, const double* y, const double* dy = nullptr);
  // Steps from the sample instant t to the next one, `boundary`, by the exact free-flight map where
  // it applies, the drive's hold does not cross the amplifier's limit (FreeFlightMap::Covers) and no
  // stop can be met in between; false where it does not (the state unchanged; the samples at t are
  // recorded unless the interval is not a whole one or crosses the limit, and DOP853's step records
  // them then).
  bool ExactStep(double t, double boundary);
  double ThetaAt(double t, double h, double time_s);
  // Whether a Hertzian contact's end is integrated over u: `entry` after an entry switch, else the
  // release.
  bool RootPhaseApplies(bool entry) const;
  // Integrates the contact end from y_ at time t over u (see the top) until it is left, the stop
  // releases, or time reaches `boundary`; y_ and K(0) are then over t again. Returns the time
  // reached; *h is the time step to go on with.
  double RunRootPhase(double t, double boundary, const variational::StopSurface& stop, double direction, double* h);
  // Cuts the step at theta, switches the mode across `surface`, applies the jump.
  void Switch(double t, double h, double theta, const variational::StopSurface& surface, bool entry);
  // Locates the first switch in the step just taken (and notes its apex); if there is one, cuts the
  // step there (Switch) and returns true.
  bool HandleEvents(double t, double h);

  variational::Field field_;
  variational::Drive drive_;
  const FlowRequest& request_;
  const FlowOptions& options_;
  int n_;
  int width_;  // n_ and time (over u)
  int d_ = 2;  // the state's size (Layout::state_size)
  std::vector<double> k_, y_, y_new_, stage_, dense_;
  std::vector<double> sample_y_, sample_dy_;  // a sample's interpolated components and the field there
  double max_step_s_ = 0.0, shortest_period_s_ = 0.0;
  int controlled_ = 2;                      // components under error control: the state and the columns
  std::vector<double> absolute_tolerance_;  // per controlled component
  ContactMode mode_;
  std::vector<variational::StopSurface> stops_;  // the penetration surface of each stop present
  double switch_time_ = 0.0;    // the instant of the last switch [s]
  variational::StopSurface last_switch_;  // and its surface,
  bool last_switch_entry_ = false;        // whether it entered a stop
  double largest_penetration_m_ = 0.0;    // p's largest value at step ends in the current contact
  bool release_over_u_failed_ = false;    // in the current contact: the release stays over t
  // A contact end integrated over u = u_start + direction * sigma (sigma the independent variable).
  struct RootPhase {
    bool active = false;
    variational::StopSurface stop;
    double direction = 1.0;  // +1: after entry, u grows from 0; -1: before release, u falls to 0
    double u_start = 0.0;    // [m^0.5]
  } phase_;
  bool exact_free_flight_ = false;                     // the options allow it and the model has it
  std::optional<variational::FreeFlightMap> free_map_;  // made at the first exact step
  double step_cos_ = 1.0, step_sin_ = 0.0;  // cos(wt), sin(wt) at the start of the step being taken
  bool dense_ready_ = false;               // PrepareDense ran for the step just taken
  int next_sample_ = 0;
  FlowResult result_;
};

void FlowIntegrator::EvaluateStage(int s, double t, double h, const double* y, double* dy) {
  if (phase_.active) {  // t is sigma here; time is y[n_]
    const double u = phase_.u_start + phase_.direction * (t + dop853::kC[s] * h);
    const double dt_dsigma = phase_.direction * 2.0 * u / PenetrationRate(phase_.stop, y);  // dt/du du/dsigma
    field_.Evaluate(y[n_], y, dy, mode_);
    // A stage where the mass turned round (p' of the wrong sign) is off the phase's chart: the step
    // is rejected (a NaN error).
    const double factor = dt_dsigma >= 0 ? dt_dsigma : std::numeric_limits<double>::quiet_NaN();
    for (int i = 0; i < n_; ++i) dy[i] *= factor;
    dy[n_] = factor;
    return;
  }
  // One sin and cos at the step's start (Step), rotated to the stage's node.
  const double t_stage = t + dop853::kC[s] * h, theta = field_.omega_rad_per_s() * dop853::kC[s] * h;
  const bool quadratures = dop853::kStageIsWeighted[s];
  if (!(std::abs(theta) <= 0.5)) {
    const double wt = field_.omega_rad_per_s() * t_stage;
    field_.Evaluate(t_stage, std::cos(wt), std::sin(wt), y, dy, mode_, quadratures);
    return;
  }
  double c, sn;
  variational::SmallAngleCosSin(theta, &c, &sn);
  field_.Evaluate(t_stage, step_cos_ * c - step_sin_ * sn, step_sin_ * c + step_cos_ * sn, y, dy, mode_, quadratures);
}

// out = y + h sum_j a_sj k_j over the nonzero a_sj (half of DOP853's are zero), k_j at k + j n.
// N > 0: the component count known at compile time (the sweep's common sizes), which lets the
// compiler keep the sums in registers; N = 0: any count n.
template <int N>
void AccumulateStage(int s, double h, const double* y, const double* k, int n, int stride, double* out) {
  const int count = N > 0 ? N : n;
  double sum[N > 0 ? N : 1];
  double* acc = N > 0 ? sum : out;
  for (int i = 0; i < count; ++i) acc[i] = y[i];
  for (int j = 0; j < s; ++j) {
    const double a = dop853::kA[s][j];
    if (a == 0.0) continue;
    const double ha = h * a;
    const double* kj = k + static_cast<size_t>(j) * stride;
    for (int i = 0; i < count; ++i) acc[i] += ha * kj[i];
  }
  if (N > 0)
    for (int i = 0; i < count; ++i) out[i] = acc[i];
}

void FlowIntegrator::StageState(int s, double h) {
  // The harmonic integrals (from controlled_ on) feed nothing back into the field: only the step's
  // end (row kStages, the weights b) needs them, not the stages inside it. With a fit's Jacobian
  // they are most of the components (2 (d + P)(N + 1) of them for P parameters and N harmonics).
  // Over u, time (the last component) is needed at every stage: all are summed.
  const int needed = phase_.active || s == dop853::kStages ? Active() : controlled_;
  // Rounded up to a size compiled for (Apply's 2, Linearize's 8 with a drive column or the first
  // harmonic, Trace's 10) where the components are there: summing a harmonic integral more is cheap.
  // (A loop compiled for the monodromy's 6 made a smooth 200 x 200 sweep 20 % slower than the loop
  // of any size: no size but these three is compiled.)
  if (!phase_.active) {
    for (const int compiled : {2, 8, 10}) {
      if (needed > compiled || compiled > Active()) continue;
      if (compiled == 2) return AccumulateStage<2>(s, h, y_.data(), K(0), 2, width_, stage_.data());
      if (compiled == 8) return AccumulateStage<8>(s, h, y_.data(), K(0), 8, width_, stage_.data());
      return AccumulateStage<10>(s, h, y_.data(), K(0), 10, width_, stage_.data());
    }
  }
  AccumulateStage<0>(s, h, y_.data(), K(0), needed, width_, stage_.data());
}

double FlowIntegrator::Step(double t, double h) {
  dense_ready_ = false;
  if (!phase_.active) {
    step_cos_ = std::cos(field_.omega_rad_per_s() * t);
    step_sin_ = std::sin(field_.omega_rad_per_s() * t);
  }
  for (int s = 1; s < dop853::kStages; ++s) {
    StageState(s, h);
    EvaluateStage(s, t, h, stage_.data(), K(s));
  }
  StageState(dop853::kStages, h);  // row 12 of a holds the weights b: the 8th-order solution
  y_new_.swap(stage_);
  EvaluateStage(dop853::kStages, t, h, y_new_.data(), K(dop853::kStages));  // c = 1: the step's end
  // Error norm over the state and the sensitivity columns (Hairer, Norsett and Wanner, Sec. II.10, the
  // DOP853 estimate): a column is less smooth than the state where a force's derivative is (Hertzian
  // contact's p^(1/2) at entry), and controlling the state alone left 0.1 % errors in the monodromy.
  // Over u, time is controlled too, to the state's relative tolerance of the shortest period.
  double err5 = 0.0, err3 = 0.0;
  auto add = [&](int i, double scale) {
    double e5 = 0.0, e3 = 0.0;
    for (int j = 0; j <= dop853::kStages; ++j) {
      e5 += dop853::kE5[j] * K(j)[i];
      e3 += dop853::kE3[j] * K(j)[i];
    }
    err5 += (e5 / scale) * (e5 / scale);
    err3 += (e3 / scale) * (e3 / scale);
  };
  for (int i = 0; i < controlled_; ++i) {
    const double relative = i < d_ ? options_.relative_tolerance : options_.sensitivity_relative_tolerance;
    add(i, absolute_tolerance_[i] + relative * std::max(std::abs(y_[i]), std::abs(y_new_[i])));
  }
  if (phase_.active) add(n_, options_.relative_tolerance * shortest_period_s_);
  if (err5 == 0.0 && err3 == 0.0) return 0.0;
  const int controlled = controlled_ + (phase_.active ? 1 : 0);
  const double error = std::abs(h) * err5 / std::sqrt((err5 + 0.01 * err3) * controlled);
  return std::isfinite(error) ? error : std::numeric_limits<double>::infinity();
}

void FlowIntegrator::PrepareDense(double t, double h) {
  // (step_cos_, step_sin_ still hold the step's start: Step set them.)
  if (dense_ready_) return;
  dense_ready_ = true;
  for (int s = dop853::kStages + 1; s < dop853::kExtendedStages; ++s) {
    StageState(s, h);
    EvaluateStage(s, t, h, stage_.data(), K(s));
  }
  for (int i = 0; i < Active(); ++i) {
    const double delta = y_new_[i] - y_[i];
    DenseTerm(0)[i] = delta;
    DenseTerm(1)[i] = h * K(0)[i] - delta;
    DenseTerm(2)[i] = 2.0 * delta - h * (K(dop853::kStages)[i] + K(0)[i]);
    for (int d = 0; d < dop853::kDenseTerms - 3; ++d) {
      double sum = 0.0;
      // (zero coefficients skipped: a quadrature has no derivative at stages 1-4, kStageIsWeighted)
      for (int j = 0; j < dop853::kExtendedStages; ++j)
        if (dop853::kD[d][j] != 0.0) sum += dop853::kD[d][j] * K(j)[i];
      DenseTerm(3 + d)[i] = h * sum;
    }
  }
}

double FlowIntegrator::Interpolate(int i, double theta) const {
  // y_old + F0 th + F1 th (1-th) + F2 th^2 (1-th) + ..., nested as in the DOP853 code's CONTD8.
  double value = 0.0;
  for (int term = dop853::kDenseTerms - 1; term >= 0; --term) {
    value += dense_[static_cast<size_t>(term) * width_ + i];
    value *= term % 2 == 0 ? theta : 1.0 - theta;
  }
  return y_[i] + value;
}

State FlowIntegrator::InterpolateState(double theta) const {
  return {Interpolate(0, theta), Interpolate(1, theta), d_ > 2 ? Interpolate(2, theta) : 0.0};
}

void FlowIntegrator::Note(double t, const State& y) {
  result_.min_displacement_m = std::min(result_.min_displacement_m, y.x_m);
  result_.max_displacement_m = std::max(result_.max_displacement_m, y.x_m);
  if (request_.figures) {
    const double packed[] = {y.x_m, y.v_m_per_s, y.coil_force_n};
    result_.peak_force_n = std::max(result_.peak_force_n, std::abs(field_.Force(t, packed, mode_)));
  }
}

void FlowIntegrator::Sample(double t, double h, double t_until) {
  const int count = request_.sample_count;
  while (next_sample_ < count) {
    const double ts = request_.sample_start_s + next_sample_ * request_.sample_interval_s;
    if (ts > t_until) return;
    PrepareDense(t, h);
    const double theta = ThetaAt(t, h, ts);
    const int components = request_.sample_sensitivities ? controlled_ : d_;
    for (int i = 0; i < components; ++i) sample_y_[i] = Interpolate(i, theta);
    RecordSample(ts, sample_y_.data());
    ++next_sample_;
  }
}

void FlowIntegrator::SampleTimeStep(double t, double h, double t_end) {
  // Within a billionth of the interval of t_end: the step's end, where the dense output equals y_new_
  // (its terms vanish at theta = 1 but the first, y_new_ - y_) and K(kStages) is the field (first same
  // as last). It would cost the three stages of PrepareDense and a field evaluation per sample.
  const double at_end = 1e-9 * request_.sample_interval_s;
  Sample(t, h, t_end - at_end);
  for (; next_sample_ < request_.sample_count; ++next_sample_) {
    const double ts = request_.sample_start_s + next_sample_ * request_.sample_interval_s;
    if (ts > t_end + at_end) return;
    RecordSample(ts, y_new_.data(), K(dop853::kStages));
  }
}

void FlowIntegrator::RecordSample(double ts, const double* y, const double* dy) {
  result_.samples.push_back(variational::StateOf(y, d_));
  if (!request_.sample_sensitivities) {
    result_.sample_force_n.push_back(dy ? model().mass_kg * dy[1] : field_.Force(ts, y, mode_));
    return;
  }
  // The field at the sample gives x'' and each column's x'' (variational_field.h): the force m_p x''
  // and its derivatives, d(m_p x'')/d m_p = x'' + m_p dx''/dm_p for the mass.
  if (dy) {
    sample_dy_.assign(dy, dy + n_);
  } else {
    sample_dy_.assign(width_, 0.0);
    field_.Evaluate(ts, y, sample_dy_.data(), mode_);
  }
  const variational::Layout& l = field_.layout();
  const double mass = model().mass_kg;
  result_.sample_force_n.push_back(mass * sample_dy_[1]);
  for (int c = 0; c < l.columns; ++c) {
    const int i = l.Column(c);
    const bool is_mass = c >= l.state_columns && c - l.state_columns < l.parameter_columns &&
                         request_.parameters[c - l.state_columns] == &ActuatorModel::mass_kg;
    result_.sample_slopes.push_back(y[i]);
    result_.sample_slopes.push_back(y[i + 1]);
    result_.sample_slopes.push_back(mass * sample_dy_[i + 1] + (is_mass ? sample_dy_[1] : 0.0));
  }
}

bool FlowIntegrator::ExactStep(double t, double boundary) {
  if (!exact_free_flight_ || mode_.Any()) return false;
  const double interval = 1.0 / drive_.sampled->sample_rate_hz, rounding = 1e-9 * interval;
  if (std::abs(boundary - t - interval) > rounding) return false;  // a clipping corner or a partial interval
  if (!free_map_) {
    // Each component's size: its absolute tolerance, in proportion, with x's at the length scale.
    std::vector<double> size(absolute_tolerance_.begin(), absolute_tolerance_.begin() + n_);
    const double per_tolerance = LengthScaleM(model()) / absolute_tolerance_[0], peak_v = drive_.PeakV();
    for (double& s : size) s *= per_tolerance;
    free_map_.emplace(model(), request_, interval, size, peak_v > 0 ? peak_v : 1.0);
  }
  if (!free_map_->Covers(drive_.Voltage(t), drive_.Voltage(boundary))) return false;  // it crosses the limit
  auto next_sample_s = [&] { return request_.sample_start_s + next_sample_ * request_.sample_interval_s; };
  for (; next_sample_ < request_.sample_count && next_sample_s() <= t + rounding; ++next_sample_)
    RecordSample(next_sample_s(), y_.data(), K(0));
  // A sample strictly inside the interval needs the dense output.
  if (next_sample_ < request_.sample_count && next_sample_s() < boundary - rounding) return false;
  double* dy_end = K(dop853::kStages);
  free_map_->Advance(y_.data(), drive_.Voltage(t), drive_.Voltage(boundary), y_new_.data());
  field_.Evaluate(boundary, y_new_.data(), dy_end, mode_);
  if (!std::isfinite(y_new_[0]) || !std::isfinite(y_new_[1])) return false;  // DOP853 reports it
  // No stop is met inside the interval: x'' is affine in (x, v, u) there, so it stays within its
  // ends' values up to the motion's own small change, and x departs from the chord between its ends
  // by at most max|x''| h^2 / 8. Both ends clear of every stop by 4 times that bound.
  const double margin = 0.5 * interval * interval * std::max(std::abs(K(0)[1]), std::abs(dy_end[1]));
  for (const variational::StopSurface& stop : stops_)
    if (!(stop.Value(model(), y_[0], y_[1]) < -margin && stop.Value(model(), y_new_[0], y_new_[1]) < -margin))
      return false;
  if (result_.steps >= options_.max_steps) return false;  // DOP853's step throws on the budget
  ++result_.steps;
  ++result_.exact_steps;
  y_.swap(y_new_);
  std::copy_n(dy_end, n_, K(0));
  Note(boundary, variational::StateOf(y_.data(), d_));
  for (; next_sample_ < request_.sample_count && next_sample_s() <= boundary + rounding; ++next_sample_)
    RecordSample(next_sample_s(), y_.data(), K(0));
  return true;
}

double FlowIntegrator::ThetaAt(double t, double h, double time_s) {
  if (!phase_.active) return (time_s - t) / h;
  // Time grows over the step (dt/du has the phase's sign): its root on the dense output.
  const double start = y_[n_] - time_s, end = y_new_[n_] - time_s;
  if (end <= 0.0) return 1.0;
  if (start >= 0.0) return 0.0;
  return LocateRootOnStep([&](double theta) { return Interpolate(n_, theta) - time_s; }, start, end);
}

void FlowIntegrator::Switch(double t, double h, double theta, const variational::StopSurface& surface, bool entry) {
  const double t_switch = t + theta * h;
  Sample(t, h, t_switch);  // in the mode before the switch
  switch_time_ = t_switch;
  for (int i = 0; i < n_; ++i) y_new_[i] = Interpolate(i, theta);
  const double x = y_new_[0], v = y_new_[1];
  const ActuatorModel& m = model();
  const ContactMode before = mode_;
  ContactMode after = mode_;
  (surface.upper ? after.upper : after.lower) = entry;
  const double a_before = field_.Force(t_switch, y_new_.data(), before) / m.mass_kg;
  const double jump = field_.Force(t_switch, y_new_.data(), after) / m.mass_kg - a_before;  // only x'' can jump
  double dh_dx, dh_dv;
  surface.Gradient(m, x, v, &dh_dx, &dh_dv);
  const double rate = dh_dx * v + dh_dv * a_before;  // dh/dt along the flow before the switch
  const variational::Layout& l = field_.layout();
  if (jump != 0.0 && std::abs(rate) > 0.0) {
    for (int c = 0; c < l.columns; ++c) {
      const int i = l.Column(c);
      double dh = dh_dx * y_new_[i] + dh_dv * y_new_[i + 1];
      if (c >= l.state_columns && c < l.state_columns + l.parameter_columns)
        dh += surface.ParameterDerivative(m, request_.parameters[c - l.state_columns], x, v);
      const double dtau = -dh / rate;
      y_new_[i + 1] -= jump * dtau;
    }
  }
  mode_ = after;
  last_switch_ = surface;
  last_switch_entry_ = entry;
  if (entry) {
    ++result_.contacts;
    largest_penetration_m_ = 0.0;
    release_over_u_failed_ = false;
  }
  y_.swap(y_new_);
  field_.Evaluate(t_switch, y_.data(), K(0), mode_);
  Note(t_switch, variational::StateOf(y_.data(), d_));
}

bool FlowIntegrator::HandleEvents(double t, double h) {
  auto interpolated = [&](const variational::StopSurface& surface, double theta) {
    PrepareDense(t, h);
    return surface.Value(model(), Interpolate(0, theta), Interpolate(1, theta));
  };
  double best_theta = 2.0;
  variational::StopSurface best_surface;
  bool best_entry = false;
  auto consider = [&](double theta, const variational::StopSurface& surface, bool entry) {
    if (theta >= best_theta) return;
    best_theta = theta;
    best_surface = surface;
    best_entry = entry;
  };
  const double x0 = y_[0], v0 = y_[1], x1 = y_new_[0], v1 = y_new_[1];
  for (const variational::StopSurface& penetration : stops_) {
    const variational::StopSurface force{penetration.upper, true};
    auto root = [&](const variational::StopSurface& surface, double g0, double g1) {
      return LocateRootOnStep([&](double theta) { return interpolated(surface, theta); }, g0, g1);
    };
    const double p0 = penetration.Value(model(), x0, v0), p1 = penetration.Value(model(), x1, v1);
    const double f0 = force.Value(model(), x0, v0), f1 = force.Value(model(), x1, v1);
    if (penetration.upper ? mode_.upper : mode_.lower) {
      if (f0 >= 0 && f1 < 0) consider(root(force, f0, f1), force, false);  // the stop lets go
      continue;
    }
    if (p0 <= 0 && p1 > 0) consider(root(penetration, p0, p1), penetration, true);  // the mass enters
    // A damped stop that let go while p > 0 is pressed again when its force rises through 0.
    // (Approaching from outside, k_s p + c_s p' turns positive while p < 0: that is not a press.)
    if (model().contact_damping_n_s_per_m != 0.0 && f0 <= 0 && f1 > 0 && p1 > 0) {
      const double theta = root(force, f0, f1);
      if (interpolated(penetration, theta) > 0) consider(theta, force, true);
    }
  }
  // An apex of x: an extremum for the figures, and a grazing contact that entered and left a stop
  // within the step if the stop's penetration is positive there.
  const bool watch_apex = request_.figures || !stops_.empty();
  if (watch_apex && ((v0 < 0 && v1 >= 0) || (v0 > 0 && v1 <= 0))) {
    auto velocity = [&](double theta) {
      PrepareDense(t, h);
      return Interpolate(1, theta);
    };
    const double theta_apex = v1 == 0.0 ? 1.0 : LocateRootOnStep(velocity, v0, v1);
    if (theta_apex < best_theta) {
      const State apex = InterpolateState(theta_apex);
      const double x_apex = apex.x_m, v_apex = apex.v_m_per_s;
      Note(t + theta_apex * h, apex);
      for (const variational::StopSurface& penetration : stops_) {
        if (penetration.upper ? mode_.upper : mode_.lower) continue;
        const double p0 = penetration.Value(model(), x0, v0), p_apex = penetration.Value(model(), x_apex, v_apex);
        if (!(p0 <= 0 && p_apex > 0)) continue;
        const double theta = theta_apex * LocateRootOnStep([&](double u) { return interpolated(penetration, u * theta_apex); },
                                                     p0, p_apex);
        consider(theta, penetration, true);
      }
    }
  }
  if (best_theta > 1.0) return false;
  Switch(t, h, best_theta, best_surface, best_entry);
  return true;
}

bool FlowIntegrator::RootPhaseApplies(bool entry) const {
  const ActuatorModel& m = model();
  if (m.contact_law != ContactLaw::kHertzian) return false;
  // With contact damping the force vanishes at p > 0 on the way out, where the solution is smooth.
  if (!entry && (m.contact_damping_n_s_per_m != 0.0 || release_over_u_failed_)) return false;
  return true;
}

double FlowIntegrator::RunRootPhase(double t, double boundary, const variational::StopSurface& stop, double direction,
                                    double* h_time) {
  const double entry_rate = direction > 0 ? PenetrationRate(stop, y_.data()) : 0.0;
  const double p_start = stop.Value(model(), y_[0], y_[1]);
  phase_ = {true, stop, direction, direction > 0 ? 0.0 : std::sqrt(std::max(p_start, 0.0))};
  // First step: near u = 0, dt = 2 u du / p', so a time step h covers du ~ sqrt(h p'); after entry at
  // most a quarter of sqrt(p_max), p_max = (5 m p'^2 / (4 k_s))^(2/5) the deepest penetration of a
  // free Hertzian impact at that speed (Johnson, Contact Mechanics, 1985, Sec. 11.4).
  const double rate = std::abs(PenetrationRate(stop, y_.data()));
  double h;
  if (direction > 0) {
    const double p_max = std::pow(1.25 * model().mass_kg * rate * rate / model().contact_stiffness, 0.4);
    h = std::min(std::sqrt(*h_time * rate), 0.25 * std::sqrt(p_max));
  } else {
    h = std::min(phase_.u_start, *h_time * rate / (2.0 * phase_.u_start));
  }
  double sigma = 0.0;
  y_[n_] = t;
  EvaluateStage(0, sigma, 0.0, y_.data(), K(0));
  auto leave = [&](double time_s) {
    phase_.active = false;
    field_.Evaluate(time_s, y_.data(), K(0), mode_);
    return time_s;
  };
  bool rejected_last = false;
  int rejections_in_row = 0;
  double last_dt = 0.0;  // the time the last accepted step covered
  for (;;) {
    double h_try = h;
    const bool to_release = direction < 0 && sigma + h_try >= phase_.u_start;
    if (to_release) h_try = phase_.u_start - sigma;
    if (++result_.steps > options_.max_steps)
      throw NumericalError("the variational flow spent its budget of " + std::to_string(options_.max_steps) +
                           " steps at t = " + std::to_string(t) + " s in a Hertzian contact");
    const double error = h_try > 0 ? Step(sigma, h_try) : std::numeric_limits<double>::infinity();
    if (!(error <= 1.0)) {
      ++result_.rejected_steps;
      // Where p' nears 0 within the phase (the mass turns round in the stop), u is no chart: go on over t.
      if (++rejections_in_row > 12 || !(h_try > 1e-12 * phase_.u_start)) {
        if (direction < 0) release_over_u_failed_ = true;
        return leave(t);
      }
      h = h_try * (std::isfinite(error) ? std::max(kMinStepFactor, StepFactor(error)) : kMinStepFactor);
      rejected_last = true;
      continue;
    }
    rejections_in_row = 0;
    double factor = error == 0.0 ? kMaxStepFactor : std::min(kMaxStepFactor, StepFactor(error));
    if (rejected_last) factor = std::min(factor, 1.0);
    rejected_last = false;
    const double t_end = y_new_[n_];
    if (t_end >= boundary) {  // cut at the boundary
      PrepareDense(sigma, h_try);
      const double theta = ThetaAt(sigma, h_try, boundary);
      Sample(sigma, h_try, boundary);
      for (int i = 0; i < n_; ++i) y_new_[i] = Interpolate(i, theta);
      y_.swap(y_new_);
      *h_time = std::max(boundary - t, 1e-3 * max_step_s_);
      return leave(boundary);
    }
    Sample(sigma, h_try, t_end);
    const double dt = t_end - t;
    *h_time = dt * factor;
    t = t_end;
    sigma += h_try;
    y_.swap(y_new_);
    std::copy_n(K(dop853::kStages), width_, K(0));
    if (to_release) {  // p = 0: the stop lets go, with no jump (its force is 0 there)
      (stop.upper ? mode_.upper : mode_.lower) = false;
      Note(t, variational::StateOf(y_.data(), d_));
      return leave(t);
    }
    // After entry, u pays while the time per step grows; it stops growing as p' falls (dt/du = 2u/p'),
    // and t is then far enough from the entry for its own steps.
    if (direction > 0 && (dt < 1.2 * last_dt || PenetrationRate(stop, y_.data()) <= 0.5 * entry_rate)) return leave(t);
    last_dt = dt;
    h = h_try * factor;
  }
}

FlowResult FlowIntegrator::Run(State start, double t0, double t1) {
  const variational::Layout& l = field_.layout();
  y_[0] = start.x_m;
  y_[1] = start.v_m_per_s;
  if (d_ > 2) y_[2] = start.coil_force_n;
  for (int c = 0; c < l.state_columns; ++c) y_[l.Column(c) + c] = 1.0;  // s(t0) = I
  mode_ = StartingMode(model(), start.x_m, start.v_m_per_s);
  if (model().HasLowerStop()) stops_.push_back({false, false});
  if (model().HasUpperStop()) stops_.push_back({true, false});
  result_.min_displacement_m = result_.max_displacement_m = start.x_m;
  Note(t0, start);
  field_.Evaluate(t0, y_.data(), K(0), mode_);

  std::vector<double> boundaries = drive_.sampled ? SampledDriveCorners(model(), *drive_.sampled, t0, t1)
                                                 : ClippingKinks(model(), drive_.sine, t0, t1);
  boundaries.push_back(t1);
  if (model().HasAmplifierLimit())
    boundaries = SplitLimitCrossings(model(), drive_, t0, max_step_s_, std::move(boundaries));
  size_t next_boundary = 0;
  double t = t0;
  double h = options_.initial_step_s > 0 ? options_.initial_step_s : 0.25 * max_step_s_;
  bool rejected_last = false;
  // The shortest step t resolves: a step below it means the solution is not finite or not resolvable.
  auto resolution = [&] { return kTimeResolution * std::max(std::abs(t), max_step_s_); };
  while (t < t1) {
    // A switch on a boundary (a stop met at a sample instant of a sampled drive) leaves t on it up to
    // rounding, and a crossing of the amplifier's limit is two boundaries a few ulps apart: the
    // boundary is reached, and a step to it would be one t cannot resolve. K(0) is the field there
    // (across the limit it jumps).
    while (std::abs(boundaries[next_boundary] - t) <= resolution()) {
      if (boundaries[next_boundary] != t) {
        t = boundaries[next_boundary];
        field_.Evaluate(t, y_.data(), K(0), mode_);
      }
      if (++next_boundary == boundaries.size()) break;
    }
    if (t >= t1) break;
    const double boundary = boundaries[next_boundary];
    if (ExactStep(t, boundary)) {
      t = boundary;
      ++next_boundary;
      continue;
    }
    double h_try = std::min(h, max_step_s_);
    const bool to_boundary = t + h_try >= boundary;
    if (to_boundary) h_try = boundary - t;
    if (++result_.steps > options_.max_steps)
      throw NumericalError("the variational flow spent its budget of " + std::to_string(options_.max_steps) +
                           " steps at t = " + std::to_string(t) + " s of " + std::to_string(t1) + " s (drive " +
                           drive_.Describe() + "; from x = " + std::to_string(start.x_m) + " m, v = " + std::to_string(start.v_m_per_s) +
                           " m/s)");
    if (!(h_try > resolution()))
      throw NumericalError("the variational flow's step fell below the resolution of t at t = " + std::to_string(t) +
                           " s (the solution is not finite or not resolvable)");
    const double error = Step(t, h_try);
    if (!(error <= 1.0)) {
      ++result_.rejected_steps;
      h = h_try * (std::isfinite(error) ? std::max(kMinStepFactor, StepFactor(error)) : kMinStepFactor);
      rejected_last = true;
      continue;
    }
    double factor = error == 0.0 ? kMaxStepFactor : std::min(kMaxStepFactor, StepFactor(error));
    if (rejected_last) factor = std::min(factor, 1.0);
    rejected_last = false;
    h = to_boundary ? std::max(h, h_try * factor) : h_try * factor;
    if (HandleEvents(t, h_try)) {
      t = switch_time_;  // Switch moved y_ to the switch instant
      if (last_switch_entry_ && !last_switch_.force && RootPhaseApplies(true) &&
          std::abs(y_[1]) > kGrazingRate * LengthScaleM(model()) / shortest_period_s_) {
        t = RunRootPhase(t, boundary, last_switch_, 1.0, &h);
        if (t >= boundary) ++next_boundary;
      }
      continue;
    }
    const double t_end = to_boundary ? boundary : t + h_try;
    SampleTimeStep(t, h_try, t_end);
    t = t_end;
    if (to_boundary) ++next_boundary;
    y_.swap(y_new_);
    std::copy_n(K(dop853::kStages), n_, K(0));  // first same as last
    // On the way out of a Hertzian stop, past half its largest penetration: the release over u.
    for (const variational::StopSurface& penetration : stops_) {
      if (!(penetration.upper ? mode_.upper : mode_.lower) || t >= t1) continue;
      const double p = penetration.Value(model(), y_[0], y_[1]);
      largest_penetration_m_ = std::max(largest_penetration_m_, p);
      const double rate = PenetrationRate(penetration, y_.data());
      if (rate < 0 && p > 0 && p <= 0.5 * largest_penetration_m_ && RootPhaseApplies(false)) {
        const double next = boundaries[next_boundary];
        t = RunRootPhase(t, next, penetration, -1.0, &h);
        if (t >= next) ++next_boundary;
      }
    }
  }
  result_.end = variational::StateOf(y_.data(), d_);
  Note(t1, result_.end);
  for (; next_sample_ < request_.sample_count; ++next_sample_) RecordSample(t1, y_.data());  // rounding past t1
  result_.end_rate = variational::StateOf(K(0), d_);  // f(t1, y(t1)): the last step's first-same-as-last stage
  for (int c = 0; c < l.columns; ++c) result_.columns.push_back(variational::StateOf(&y_[l.Column(c)], d_));
  for (int k = 0; k < l.harmonics; ++k) result_.harmonic_integrals.emplace_back(y_[l.Quadrature(k)], y_[l.Quadrature(k) + 1]);
  if (l.harmonic_sensitivities) {
    result_.harmonic_sensitivities.resize(l.columns);
    for (int c = 0; c < l.columns; ++c)
      for (int k = 0; k < l.harmonics; ++k)
        result_.harmonic_sensitivities[c].emplace_back(y_[l.QuadratureSensitivity(c, k)],
                                                       y_[l.QuadratureSensitivity(c, k) + 1]);
  }
  result_.last_step_s = h;
  return result_;
}

FlowResult FlowOver(const ActuatorModel& model, const variational::Drive& drive, State start, double t0_s,
                    double t1_s, const FlowRequest& request, const FlowOptions& options) {
  Validate(model);
  Validate(options);
  if (!std::isfinite(start.x_m) || !std::isfinite(start.v_m_per_s) || !std::isfinite(start.coil_force_n))
    throw InputError("initial", "must be finite");
  if (!std::isfinite(t0_s) || !std::isfinite(t1_s) || !(t1_s >= t0_s))
    throw InputError("t1_s", "the interval must be finite with t1 >= t0");
  if (request.harmonics < 0) throw InputError("harmonics", "must be >= 0");
  if (request.sample_count < 0) throw InputError("sample_count", "must be >= 0");
  if (request.sample_count > 0) {
    const double last_s = request.sample_start_s + (request.sample_count - 1) * request.sample_interval_s;
    if (!(request.sample_start_s >= t0_s) || !(request.sample_interval_s > 0) || !(last_s <= t1_s * (1 + 1e-12)))
      throw InputError("sample_start_s", "the samples must lie within [t0, t1] at a positive interval");
  }
  return FlowIntegrator(model, drive, request, options).Run(start, t0_s, t1_s);
}

}  // namespace

FlowResult Flow(const ActuatorModel& model, const SineDrive& drive, State start, double t0_s, double t1_s,
                const FlowRequest& request, const FlowOptions& options) {
  Validate(drive);
  return FlowOver(model, variational::Drive{drive, nullptr}, start, t0_s, t1_s, request, options);
}

FlowResult Flow(const ActuatorModel& model, const SampledDrive& drive, State start, double t0_s, double t1_s,
                const FlowRequest& request, const FlowOptions& options) {
  Validate(drive);
  // Harmonics and the drive's amplitude and frequency belong to a sine.
  if (request.harmonics > 0) throw InputError("harmonics", "a sampled drive has no drive frequency: must be 0");
  if (request.drive_amplitude || request.drive_frequency)
    throw InputError("drive_amplitude", "a sampled drive has no amplitude or frequency to take derivatives by");
  return FlowOver(model, variational::Drive{SineDrive{}, &drive}, start, t0_s, t1_s, request, options);
}

std::optional<FieldError> FlowOptions::IsValid() const {
  if (!(relative_tolerance > 0) || !(relative_tolerance < 1))
    return FieldError{"relative_tolerance", "must lie in (0, 1)"};
  if (!(sensitivity_relative_tolerance > 0) || !(sensitivity_relative_tolerance < 1))
    return FieldError{"sensitivity_relative_tolerance", "must lie in (0, 1)"};
  if (!(absolute_tolerance_m > 0) || !std::isfinite(absolute_tolerance_m))
    return FieldError{"absolute_tolerance_m", "must be a finite number > 0"};
  if (!(absolute_tolerance_m_per_s > 0) || !std::isfinite(absolute_tolerance_m_per_s))
    return FieldError{"absolute_tolerance_m_per_s", "must be a finite number > 0"};
  if (!(absolute_tolerance_n > 0) || !std::isfinite(absolute_tolerance_n))
    return FieldError{"absolute_tolerance_n", "must be a finite number > 0"};
  if (!(initial_step_s >= 0) || !std::isfinite(initial_step_s))
    return FieldError{"initial_step_s", "must be a finite number >= 0"};
  if (max_steps < 1) return FieldError{"max_steps", "must be >= 1"};
  return std::nullopt;
}

}  // namespace strokelab
