// The output-error fit of broadband records by multiple shooting (identify/broadband_fit.h).
#include "strokelab/identify/broadband_fit.h"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <numbers>

#include "orbit_cost.h"
#include "step_callback.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/nan.h"
#include "strokelab/base/parallel_for.h"
#include "strokelab/engines/variational_flow.h"
#include "strokelab/identify/fit.h"
#include "strokelab/identify/fit_orbit.h"
#include "strokelab/identify/sparse_covariance.h"

namespace strokelab::internal {
namespace {

// The continuity residuals: a gap between segments of this fraction of the length scale costs one
// noise standard error. The fit tightens it in steps (a penalty continuation): from a start model that
// misses the records, the segments' ends lie far from the next starts, and at the final weight alone
// closing those gaps is all the first steps would do, wherever that takes the parameters.
constexpr double kContinuityGaps[] = {1e-2, 1e-4, 1e-6};
constexpr double kMainsHz[] = {50.0, 60.0};
// Per record: the response's offset, then sin and cos of each mains order.
constexpr int kNuisance = 1 + 2 * 2 * kHumOrders;
// ImpactOnsetsM: an impact counts when at least kOnsetQuietS without one precede it (enough samples
// to fit the two start components to, about a tenth of the natural period), and the start is fitted
// to at most kOnsetWindowS before it. The window sets how well the start's x is known: in a force
// record x shows as k_p x against the drive's m_p x'', so over a fraction of the natural period it is
// hard to tell from the offset. On the paper's model (seed 45, 8,192 Hz), with 0.1 s three of six onsets
// were within 0.25 % of d, with 0.5 s (five natural periods) within 0.04 %.
constexpr double kOnsetQuietS = 0.01;
constexpr double kOnsetWindowS = 0.5;
// An onset's stop is matched to the samples from kOnsetBefore before the impact's first mark to
// kOnsetAfter after it (the first mark is up to 4 samples before the contact; a linear contact at the
// data sheet's k_s lasts 0.5 ms, 4 samples at 8,192 Hz), over a grid of kOnsetGrid steps, then
// kOnsetSections golden sections (0.618^30 = 5e-7 of a step).
constexpr size_t kOnsetBefore = 4, kOnsetAfter = 12;
constexpr int kOnsetGrid = 32;
constexpr int kOnsetSections = 30;
// A segment's start is matched to its first impact (MatchFirstImpact) at the best of this many instants
// of entry.
constexpr size_t kEntryCandidates = 5;
// ... and at an entry speed among kEntrySpeeds from kEntrySpeedRange[0] to [1] times the state's speed
// scale L w_n (9102's 9 N impact at 0.7 V rms entered at about 0.7 of it).
constexpr int kEntrySpeeds = 24;
constexpr double kEntrySpeedRange[] = {0.05, 5.0};
// A joint fit with stepped-sine records: at most this many solves at the final continuity weight, each
// with the sampling corrections refreshed (extended_fit.h's passes).
constexpr int kJointPasses = 8;

// The unit of each state component: the solver sees x / L, v / (L w_n) and F_e / (k_p L).
struct StateScale {
  double unit[3] = {1.0, 1.0, 1.0};
  explicit StateScale(const ActuatorModel& m) {
    const double length = LengthScaleM(m);
    const double omega = m.stiffness_n_per_m > 0 ? std::sqrt(m.stiffness_n_per_m / m.mass_kg) : 2.0 * std::numbers::pi;
    unit[0] = length;
    unit[1] = length * omega;
    unit[2] = std::max(m.stiffness_n_per_m, 1.0) * length;
  }
  // The state of the d scaled components `scaled`, and back.
  State Unscaled(const double* scaled, int d) const {
    return {scaled[0] * unit[0], scaled[1] * unit[1], d > 2 ? scaled[2] * unit[2] : 0.0};
  }
  void Scale(const State& y, int d, double* scaled) const {
    const double values[3] = {y.x_m, y.v_m_per_s, y.coil_force_n};
    for (int c = 0; c < d; ++c) scaled[c] = values[c] / unit[c];
  }
};

// The offset and hum basis at sample n of a record sampled at fs: column j of kNuisance.
double NuisanceBasis(int j, size_t n, double fs) {
  if (j == 0) return 1.0;
  const int k = j - 1, mains = k / (2 * kHumOrders), order = (k % (2 * kHumOrders)) / 2 + 1;
  const double phase = 2.0 * std::numbers::pi * kMainsHz[mains] * order * static_cast<double>(n) / fs;
  return k % 2 == 0 ? std::sin(phase) : std::cos(phase);
}

struct RecordData {
  const Recording* record = nullptr;
  SampledDrive drive;
  double sigma = 1.0;
  std::vector<bool> impact;  // samples within 2 of a fourth difference beyond 8 of its noise level
};

struct Segment {
  size_t record = 0;
  size_t first = 0, end = 0;  // samples [first, end)
  bool last = false;          // the record's last segment: no continuity residual
  double T0(double fs) const { return static_cast<double>(first) / fs; }
  double T1(double fs) const { return static_cast<double>(last ? end - 1 : end) / fs; }
};

// The slope of the model's response of `kind` at sample n of a flow per column c (ResponseOf's).
double ResponseSlope(const FlowResult& flow, ResponseKind kind, const ActuatorModel& m, size_t n, size_t columns,
                     size_t c, bool is_mass) {
  const double* s = &flow.sample_slopes[(n * columns + c) * 3];
  switch (kind) {
    case ResponseKind::kForce: return s[2];
    case ResponseKind::kAcceleration:  // (f / m_p)' = f' / m_p - f / m_p^2 for the mass
      return s[2] / m.mass_kg - (is_mass ? flow.sample_force_n[n] / (m.mass_kg * m.mass_kg) : 0.0);
    case ResponseKind::kVelocity: return s[1];
    case ResponseKind::kDisplacement: return s[0];
  }
  return kNaN;
}

// Each record's drive, noise level and impacts, and its segments appended to *segments. Throws
// InputError naming a record that is not broadband, too short or not finite.
std::vector<RecordData> RecordsData(std::span<const Recording* const> records, const BroadbandFitOptions& options,
                                    std::vector<Segment>* segments) {
  std::vector<RecordData> data(records.size());
  for (size_t r = 0; r < records.size(); ++r) {
    const Recording& rec = *records[r];
    if (!rec.broadband) throw InputError(rec.name, "is a stepped-sine record: fit it with the stepped-sine fit");
    if (rec.size() < 16 || rec.response.size() != rec.size())
      throw InputError(rec.name, "needs at least 16 samples in both channels");
    for (size_t n = 0; n < rec.size(); ++n)
      if (!std::isfinite(rec.voltage_v[n]) || !std::isfinite(rec.response[n]))
        throw InputError(rec.name, "sample " + std::to_string(n) + " is not finite");
    data[r].record = &rec;
    data[r].drive = SampledDrive{rec.sample_rate_hz, rec.voltage_v};
    data[r].sigma = options.noise.empty() ? ResponseNoiseRms(rec.response) : options.noise[r].rms;
    data[r].impact = ImpactSamples(rec.response, data[r].sigma);
    const std::vector<size_t> firsts = SegmentFirsts(rec.size(), rec.sample_rate_hz, options.segment_s);
    for (size_t k = 0; k < firsts.size(); ++k) {
      Segment s;
      s.record = r;
      s.first = firsts[k];
      s.last = k + 1 == firsts.size();
      s.end = s.last ? rec.size() : firsts[k + 1];
      segments->push_back(s);
    }
  }
  return data;
}

// One segment's residuals: its samples, then (unless last) the continuity gap to the next segment's
// start. Parameter blocks: theta (P), the segment's start (d), the record's nuisance (kNuisance), and
// the next segment's start (d) unless last.
class SegmentCost : public ceres::CostFunction {
 public:
  SegmentCost(const ExtendedProblem& problem, ResponseKind kind, const RecordData& data, const Segment& segment,
              const StateScale& scale, int state_size, const double* continuity_gap)
      : problem_(problem), kind_(kind), data_(data), segment_(segment), scale_(scale), d_(state_size),
        continuity_gap_(continuity_gap) {
    for (const FreeParameter& p : problem.parameters) fields_.push_back(p.field);
    const int p = static_cast<int>(problem.parameters.size());
    mutable_parameter_block_sizes()->push_back(p);
    mutable_parameter_block_sizes()->push_back(d_);
    mutable_parameter_block_sizes()->push_back(kNuisance);
    if (!segment.last) mutable_parameter_block_sizes()->push_back(d_);
    set_num_residuals(static_cast<int>(segment.end - segment.first) + (segment.last ? 0 : d_));
  }

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const double* theta = parameters[0];
    const ActuatorModel model = problem_.Decode(theta);
    const State start = scale_.Unscaled(parameters[1], d_);
    const Recording& record = *data_.record;
    const double fs = record.sample_rate_hz;
    const size_t samples = segment_.end - segment_.first;
    FlowRequest request;
    request.sample_count = static_cast<int>(samples);
    request.sample_start_s = segment_.T0(fs);
    request.sample_interval_s = 1.0 / fs;
    if (jacobians) {
      request.monodromy = true;
      request.parameters = fields_;
      request.sample_sensitivities = true;
    }
    FlowResult flow;
    try {
      flow = Flow(model, data_.drive, start, segment_.T0(fs), segment_.T1(fs), request);
    } catch (const std::exception&) {  // a model out of range (InputError) or a flow that fails
      return false;
    }
    const int p = static_cast<int>(fields_.size());
    const size_t columns = static_cast<size_t>(d_ + p);
    const double* nuisance = parameters[2];
    for (size_t i = 0; i < samples; ++i) {
      const size_t n = segment_.first + i;
      const double inverse_sigma = 1.0 / data_.sigma;
      double predicted = ResponseOf(kind_, model.mass_kg, flow.samples[i], flow.sample_force_n[i]);
      for (int j = 0; j < kNuisance; ++j) predicted += nuisance[j] * NuisanceBasis(j, n, fs);
      residuals[i] = (record.response[n] - predicted) * inverse_sigma;
      if (!jacobians) continue;
      if (jacobians[0])
        for (int c = 0; c < p; ++c)
          jacobians[0][i * p + c] = -ResponseSlope(flow, kind_, model, i, columns, d_ + c,
                                                   fields_[c] == &ActuatorModel::mass_kg) *
                                    problem_.parameters[c].ValuePerTheta(theta[c]) * inverse_sigma;
      if (jacobians[1])
        for (int c = 0; c < d_; ++c)
          jacobians[1][i * d_ + c] = -ResponseSlope(flow, kind_, model, i, columns, c, false) * scale_.unit[c] * inverse_sigma;
      if (jacobians[2])
        for (int j = 0; j < kNuisance; ++j) jacobians[2][i * kNuisance + j] = -NuisanceBasis(j, n, fs) * inverse_sigma;
      if (!segment_.last && jacobians[3])  // a sample does not depend on the next segment's start
        for (int c = 0; c < d_; ++c) jacobians[3][i * d_ + c] = 0.0;
    }
    if (segment_.last) return true;
    // The gap to the next segment's start, in units of the continuity gap of each component's scale.
    const double* next = parameters[3];
    const double end[3] = {flow.end.x_m, flow.end.v_m_per_s, flow.end.coil_force_n};
    for (int k = 0; k < d_; ++k) {
      const double weight = 1.0 / (*continuity_gap_ * scale_.unit[k]);
      const size_t row = samples + k;
      residuals[row] = (end[k] - next[k] * scale_.unit[k]) * weight;
      if (!jacobians) continue;
      auto component = [&](const State& s) { return k == 0 ? s.x_m : k == 1 ? s.v_m_per_s : s.coil_force_n; };
      if (jacobians[0])
        for (int c = 0; c < p; ++c)
          jacobians[0][row * p + c] =
              component(flow.columns[d_ + c]) * problem_.parameters[c].ValuePerTheta(theta[c]) * weight;
      if (jacobians[1])
        for (int c = 0; c < d_; ++c) jacobians[1][row * d_ + c] = component(flow.columns[c]) * scale_.unit[c] * weight;
      if (jacobians[2])
        for (int j = 0; j < kNuisance; ++j) jacobians[2][row * kNuisance + j] = 0.0;
      if (jacobians[3])
        for (int c = 0; c < d_; ++c) jacobians[3][row * d_ + c] = c == k ? -scale_.unit[k] * weight : 0.0;
    }
    return true;
  }

 private:
  const ExtendedProblem& problem_;
  ResponseKind kind_;
  const RecordData& data_;
  Segment segment_;
  StateScale scale_;
  int d_;
  const double* continuity_gap_;  // the fit's current one (kContinuityGaps)
  std::vector<double ActuatorModel::*> fields_;
};

// A start state within kStartBound of each component's scale: the actuator's motion stays within a few
// strokes and their speeds, and a window too short to pin the start down cannot send it further.
constexpr double kStartBound = 10.0;
void BoundStart(ceres::Problem* problem, double* start, int d) {
  for (int c = 0; c < d; ++c) {
    start[c] = std::clamp(start[c], -kStartBound, kStartBound);
    problem->SetParameterLowerBound(start, c, -kStartBound);
    problem->SetParameterUpperBound(start, c, kStartBound);
  }
}

// k_p as the one parameter of a problem whose parameters are all held (theta = 1 is its value).
FreeParameter HeldStiffness(const ActuatorModel& model) {
  FreeParameter held;
  held.name = "k_p";
  held.unit = "N/m";
  held.field = &ActuatorModel::stiffness_n_per_m;
  held.start = model.stiffness_n_per_m;
  return held;
}

// The start state (scaled) that fits samples [first, end) of `data` best at the model of `problem`
// at theta, from *start: Levenberg-Marquardt over the d start components alone (theta and the
// record's offset and hum held).
void FitStartOver(const ExtendedProblem& problem, ResponseKind kind, const RecordData& data, Segment part,
                  const StateScale& scale, int d, std::vector<double>& theta, std::vector<double>& nuisance,
                  std::vector<double>* start) {
  part.last = true;  // no continuity residual: the samples only
  ceres::Problem local;
  local.AddResidualBlock(new SegmentCost(problem, kind, data, part, scale, d, nullptr), nullptr,
                         {theta.data(), start->data(), nuisance.data()});
  local.SetParameterBlockConstant(theta.data());
  local.SetParameterBlockConstant(nuisance.data());
  BoundStart(&local, start->data(), d);
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 20;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &local, &summary);
}

// `model` without its stops, all its parameters held (theta = {1}).
ExtendedProblem StopFree(const ActuatorModel& model) {
  ExtendedProblem stop_free;
  stop_free.base = model;
  stop_free.base.lower_stop_m = ActuatorModel::kNoLowerStop;
  stop_free.base.upper_stop_m = ActuatorModel::kNoUpperStop;
  stop_free.parameters = {HeldStiffness(model)};
  return stop_free;
}

// The start state (scaled, from *start) of `stop_free` (StopFree) that fits samples [part.first,
// part.end), over windows that double from 16 samples: the motion is smooth in the start, and for a
// model that is linear without its stops, linear in it (one Gauss-Newton step per window). Fewer than
// 16 samples leave *start as it is.
void FitStopFreeStart(const ExtendedProblem& stop_free, ResponseKind kind, const RecordData& data, const Segment& part,
                      const StateScale& scale, int d, std::vector<double>& nuisance, std::vector<double>* start) {
  std::vector<double> held_theta = {1.0};
  const size_t length = part.end - part.first;
  for (size_t window = 16; window <= length; window = window == length ? length + 1 : std::min(2 * window, length)) {
    Segment prefix = part;
    prefix.end = prefix.first + window;
    FitStartOver(stop_free, kind, data, prefix, scale, d, held_theta, nuisance, start);
  }
}

// How long a contact of `model`'s stop lasts at an impact speed of speed_m_per_s: a linear contact's
// half period pi sqrt(m_p / k_s) (paper Eq. 4), a Hertzian one's 2.94 p_max / v, with p_max = (5 m_p v^2 /
// (4 k_s))^(2/5) its deepest penetration (K. L. Johnson, "Contact Mechanics", 1985, Sec. 11.4).
double ContactDurationS(const ActuatorModel& model, double speed_m_per_s) {
  if (model.contact_law == ContactLaw::kLinear) return std::numbers::pi * std::sqrt(model.mass_kg / model.contact_stiffness);
  const double deepest_m = std::pow(1.25 * model.mass_kg * speed_m_per_s * speed_m_per_s / model.contact_stiffness, 0.4);
  return 2.94 * deepest_m / speed_m_per_s;
}

// The sum of squared residuals of `cost` (a segment's, no continuity row) at the start `start`.
double StartMisfit(const SegmentCost& cost, std::vector<double>& theta, const std::vector<double>& start,
                   std::vector<double>& nuisance) {
  std::vector<double> residuals(cost.num_residuals());
  const double* blocks[] = {theta.data(), start.data(), nuisance.data()};
  if (!cost.Evaluate(blocks, residuals.data(), nullptr)) return kInf;
  double sum = 0.0;
  for (double r : residuals) sum += r * r;
  return sum;
}

// Moves *start (scaled), fitted with the stops taken away to the samples of `stretch` (stretch.last
// set) that end before a segment's first impact, to where the full model's motion matches the samples
// up to `matched_end`, the impact's included. The stretch can pin the start down poorly (a few
// milliseconds; in a force record x shows only as k_p x beside m_p x'', and unfitted hum biases it), and
// no local fit finds the impact from a motion that falls short of the stop: its residuals do not change
// with the start until the motion reaches the stop. So the start is moved along the line that changes x
// at the stretch's end, x(n), at least cost to the stretch's fit, delta = C g / (g^T C g), with C =
// (J^T J)^-1 of the stretch's residuals (noise units) and g = d x(n) / d start (the step of least norm
// in C^-1 under that one constraint), to where the stop-free motion reaches the stop at the impact's
// entry: at the first mark's centre, or up to one contact duration before it (the mark can be the
// release; kEntryCandidates instants). The fitted start and the one of those whose motion matches the
// samples best as it is each start a local fit of the full model to the matched samples; the better
// fit wins.
void MatchFirstImpact(const ExtendedProblem& problem, const ExtendedProblem& stop_free, ResponseKind kind,
                      const RecordData& data, const Segment& stretch, size_t first_mark, size_t contact_samples,
                      size_t matched_end, const StateScale& scale, int d, std::vector<double>& theta,
                      std::vector<double>& nuisance, std::vector<double>* start) {
  const double fs = data.record->sample_rate_hz;
  // The stop-free motion and its slopes per start component at the samples from n on.
  Segment after = stretch;
  after.first = stretch.end;
  after.end = matched_end;
  FlowRequest request;
  request.monodromy = true;
  request.sample_count = static_cast<int>(after.end - after.first);
  request.sample_start_s = after.T0(fs);
  request.sample_interval_s = 1.0 / fs;
  request.sample_sensitivities = true;
  FlowResult motion;
  try {
    motion = Flow(stop_free.base, data.drive, scale.Unscaled(start->data(), d), stretch.T0(fs),
                  static_cast<double>(after.end - 1) / fs, request);
  } catch (const std::exception&) {
    return;
  }
  // d (x, v) at sample i of `motion` per scaled start component c.
  auto slope_x = [&](size_t i, int c) { return motion.sample_slopes[(i * d + c) * 3] * scale.unit[c]; };
  auto slope_v = [&](size_t i, int c) { return motion.sample_slopes[(i * d + c) * 3 + 1] * scale.unit[c]; };
  const ActuatorModel model = problem.Decode(theta.data());
  const size_t centre = first_mark + 2;  // ImpactSamples marks 2 samples either side
  const double stop_m = motion.samples[std::min(centre, after.end - 1) - after.first].x_m < 0 ? model.lower_stop_m
                                                                                               : model.upper_stop_m;
  Segment matched = stretch;
  matched.end = matched_end;
  const SegmentCost matched_cost(problem, kind, data, matched, scale, d, nullptr);
  // The candidates of each kind: the one whose start matches best as it is.
  struct Best {
    std::vector<double> start;
    double misfit = kInf;
    void Offer(const std::vector<double>& candidate, double candidate_misfit) {
      if (!(candidate_misfit < misfit)) return;
      misfit = candidate_misfit;
      start = candidate;
    }
  } along_line, from_entry;
  std::vector<size_t> entries;  // kEntryCandidates instants of entry, as indices into `motion`
  for (size_t k = 0; k < kEntryCandidates; ++k) {
    const size_t back = contact_samples * k / (kEntryCandidates - 1);
    const size_t entry = centre - std::min(back, centre - after.first);
    if (entry < after.end) entries.push_back(entry - after.first);
  }
  // Along the stretch's line of least cost (at least 16 samples to fit the start to).
  const size_t rows = stretch.end - stretch.first;
  if (rows >= 16 && std::isfinite(stop_m)) {
    std::vector<double> held_theta = {1.0}, residuals(rows);
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> jacobian(rows, d);
    const double* blocks[] = {held_theta.data(), start->data(), nuisance.data()};
    double* jacobians[] = {nullptr, jacobian.data(), nullptr};
    Eigen::VectorXd g(d);
    for (int c = 0; c < d; ++c) g[c] = slope_x(0, c);
    const bool evaluated =
        SegmentCost(stop_free, kind, data, stretch, scale, d, nullptr).Evaluate(blocks, residuals.data(), jacobians);
    Eigen::VectorXd c_g = Eigen::VectorXd::Zero(d);
    if (evaluated) {
      const Eigen::LDLT<Eigen::MatrixXd> normal((jacobian.transpose() * jacobian).eval());
      if (normal.info() == Eigen::Success && normal.isPositive()) c_g = normal.solve(g);
    }
    const double variance = g.dot(c_g);
    if (variance > 0 && std::isfinite(variance)) {
      const Eigen::VectorXd delta = c_g / variance;  // scaled start per metre of x(n)
      for (size_t i : entries) {
        double h = 0.0;  // d x(entry) / d(shift of x(n))
        for (int c = 0; c < d; ++c) h += slope_x(i, c) * delta[c];
        const double shift_m = (stop_m - motion.samples[i].x_m) / h;
        if (!std::isfinite(shift_m)) continue;
        std::vector<double> moved = *start;
        for (int c = 0; c < d; ++c) moved[c] += shift_m * delta[c];
        along_line.Offer(moved, StartMisfit(matched_cost, theta, moved, nuisance));
      }
    }
  }
  // From the entry itself, for a stretch too short to say much (a record that begins a few samples
  // before an impact, where even the side its motion is on is unknown): the start whose stop-free
  // motion is at a stop at the instant of entry with an entry speed from a geometric grid (kEntrySpeeds
  // over kEntrySpeedRange of the speed scale), solved from the motion's slopes (exact: the stop-free
  // model is linear in its start). The coil's third state is left out (x and v alone fix an entry).
  for (const double entered_stop_m : {model.lower_stop_m, model.upper_stop_m}) {
    if (d != 2 || !std::isfinite(entered_stop_m)) continue;
    for (size_t i : entries) {
      Eigen::Matrix2d slopes;
      for (int c = 0; c < 2; ++c) {
        slopes(0, c) = slope_x(i, c);
        slopes(1, c) = slope_v(i, c);
      }
      const Eigen::FullPivLU<Eigen::Matrix2d> lu(slopes);
      if (!lu.isInvertible()) continue;
      const double inward = entered_stop_m == model.lower_stop_m ? -1.0 : 1.0;  // the entry's sign of v
      for (int k = 0; k < kEntrySpeeds; ++k) {
        const double speed = scale.unit[1] * kEntrySpeedRange[0] *
                             std::pow(kEntrySpeedRange[1] / kEntrySpeedRange[0], k / (kEntrySpeeds - 1.0));
        const Eigen::Vector2d change(entered_stop_m - motion.samples[i].x_m,
                                     inward * speed - motion.samples[i].v_m_per_s);
        const Eigen::Vector2d shift = lu.solve(change);
        const std::vector<double> moved = {(*start)[0] + shift[0], (*start)[1] + shift[1]};
        if (std::isfinite(moved[0]) && std::isfinite(moved[1]))
          from_entry.Offer(moved, StartMisfit(matched_cost, theta, moved, nuisance));
      }
    }
  }
  // Each kind's best and the stretch's own start each start a local fit; the best fit wins.
  std::vector<std::vector<double>> trials = {*start};
  for (const Best* best : {&along_line, &from_entry})
    if (!best->start.empty()) trials.push_back(best->start);
  double best_misfit = kInf;
  for (std::vector<double>& trial : trials) {
    FitStartOver(problem, kind, data, matched, scale, d, theta, nuisance, &trial);
    const double misfit = StartMisfit(matched_cost, theta, trial, nuisance);
    if (misfit < best_misfit) {
      best_misfit = misfit;
      *start = trial;
    }
  }
}

// Each segment's start state at the start model, segment after segment from the previous segment's
// end (rest for the first). Over a record's impacts the misfit is no bowl around the recorded state: a
// start whose motion grazes the stop where the record does not (or misses an impact it shows) sits in
// a valley of its own, since an impact's residuals do not change with the start until the motion
// reaches the stop. So the start is first fitted to the samples before the segment's first impact with
// the stops taken away (FitStopFreeStart), matched to that impact (MatchFirstImpact), then fitted to
// the whole segment with the full model. The stretch before the impact ends one contact duration
// before its first mark: a contact that sets in between two samples can leave its entry's kink below
// ImpactSamples' threshold, so that the first mark is its release (at 51.2 kHz a linear contact at the
// data sheet's k_s lasts 25 samples). The match takes the samples up to kOnsetAfter past one contact
// duration after the first mark: the whole contact, and the motion it leaves.
void FitSegmentStarts(const ExtendedProblem& problem, ResponseKind kind, const RecordData& data,
                      const std::vector<Segment>& segments, size_t record, const StateScale& scale, int d,
                      std::vector<double>& theta, std::vector<double>& nuisance,
                      std::vector<std::vector<double>>* starts) {
  const ActuatorModel model = problem.Decode(theta.data());
  const ExtendedProblem stop_free = StopFree(model);
  const double fs = data.record->sample_rate_hz;
  const double contact_s = ContactDurationS(model, scale.unit[1]);  // at the state's speed scale, L w_n
  const size_t contact_samples =
      static_cast<size_t>(std::ceil(std::min(contact_s * fs, static_cast<double>(data.record->size()))));
  std::vector<double> guess(d, 0.0);
  for (size_t s = 0; s < segments.size(); ++s) {
    if (segments[s].record != record) continue;
    std::vector<double>& start = (*starts)[s];
    start = guess;
    size_t first_mark = segments[s].end;
    for (size_t n = segments[s].first; n < segments[s].end; ++n)
      if (data.impact[n]) {
        first_mark = n;
        break;
      }
    Segment stretch = segments[s];
    stretch.last = true;
    stretch.end = first_mark;
    if (first_mark < segments[s].end) stretch.end = first_mark - std::min(first_mark - stretch.first, contact_samples);
    FitStopFreeStart(stop_free, kind, data, stretch, scale, d, nuisance, &start);
    if (first_mark < segments[s].end)
      MatchFirstImpact(problem, stop_free, kind, data, stretch, first_mark, contact_samples,
                       std::min(segments[s].end, first_mark + contact_samples + kOnsetAfter), scale, d, theta,
                       nuisance, &start);
    FitStartOver(problem, kind, data, segments[s], scale, d, theta, nuisance, &start);
    // The next guess: this segment's end from its fitted start.
    try {
      const double end_s = static_cast<double>(segments[s].end) / fs;
      scale.Scale(Flow(model, data.drive, scale.Unscaled(start.data(), d), segments[s].T0(fs), end_s, {}).end, d,
                  guess.data());
    } catch (const std::exception&) {
      std::fill(guess.begin(), guess.end(), 0.0);
    }
  }
}

// The model's motion over a segment from `start`, sampled at the segment's samples (no sensitivities).
// Throws as Flow.
FlowResult SegmentMotion(const ActuatorModel& model, const RecordData& data, const Segment& seg, const State& start) {
  const double fs = data.record->sample_rate_hz;
  FlowRequest request;
  request.sample_count = static_cast<int>(seg.end - seg.first);
  request.sample_start_s = seg.T0(fs);
  request.sample_interval_s = 1.0 / fs;
  return Flow(model, data.drive, start, seg.T0(fs), static_cast<double>(seg.end - 1) / fs, request);
}

// The offset and hum (kNuisance) that best fit the residual of the model's motion from each segment's
// start, by linear least squares over the record.
std::vector<double> NuisanceOfResiduals(const ActuatorModel& model, ResponseKind kind, const RecordData& data,
                                        const std::vector<Segment>& segments, size_t record, const StateScale& scale,
                                        int d, const std::vector<std::vector<double>>& starts) {
  const double fs = data.record->sample_rate_hz;
  Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(kNuisance, kNuisance);
  Eigen::VectorXd right = Eigen::VectorXd::Zero(kNuisance);
  for (size_t s = 0; s < segments.size(); ++s) {
    const Segment& seg = segments[s];
    if (seg.record != record) continue;
    FlowResult flow;
    try {
      flow = SegmentMotion(model, data, seg, scale.Unscaled(starts[s].data(), d));
    } catch (const std::exception&) {
      continue;
    }
    Eigen::VectorXd basis(kNuisance);
    for (size_t i = 0; i < seg.end - seg.first; ++i) {
      const size_t n = seg.first + i;
      for (int j = 0; j < kNuisance; ++j) basis(j) = NuisanceBasis(j, n, fs);
      normal += basis * basis.transpose();
      const double predicted = ResponseOf(kind, model.mass_kg, flow.samples[i], flow.sample_force_n[i]);
      right += basis * (data.record->response[n] - predicted);
    }
  }
  const Eigen::VectorXd solution = normal.ldlt().solve(right);
  return std::vector<double>(solution.data(), solution.data() + kNuisance);
}

// BroadbandRecordFit's series over one segment (samples [first, end) of `out`'s vectors, which hold the
// whole record): the model's motion from the segment's start, and the residual after offset and hum.
void SegmentSeries(const ActuatorModel& model, ResponseKind kind, const RecordData& data, const Segment& seg,
                   const State& start, const std::vector<double>& nuisance, BroadbandRecordFit* out) {
  const double fs = data.record->sample_rate_hz;
  FlowResult flow;
  try {
    flow = SegmentMotion(model, data, seg, start);
  } catch (const std::exception&) {
    return;  // the series stay NaN there
  }
  for (size_t i = 0; i < seg.end - seg.first; ++i) {
    const size_t n = seg.first + i;
    double predicted = ResponseOf(kind, model.mass_kg, flow.samples[i], flow.sample_force_n[i]);
    for (int j = 0; j < kNuisance; ++j) predicted += nuisance[j] * NuisanceBasis(j, n, fs);
    out->residual[n] = data.record->response[n] - predicted;
    out->x_m[n] = flow.samples[i].x_m;
    out->v_m_per_s[n] = flow.samples[i].v_m_per_s;
  }
}

// The model's parameters' errors, the first p unknowns, the others eliminated (LeadingErrors).
std::optional<ParameterErrors> ModelErrors(const ceres::CRSMatrix& crs, int p, double residual_variance) {
  const Eigen::Map<const Eigen::SparseMatrix<double, Eigen::RowMajor>> j(
      crs.num_rows, crs.num_cols, static_cast<Eigen::Index>(crs.values.size()), crs.rows.data(), crs.cols.data(),
      crs.values.data());
  return LeadingErrors(j, p, residual_variance);
}

// The response's misfit over `part`'s samples of `model` flowed from `at`, the state at its first
// sample (offset only).
double SampleMisfit(const ActuatorModel& model, ResponseKind kind, const RecordData& data, double offset,
                    const Segment& part, const State& at) {
  const FlowResult flow = SegmentMotion(model, data, part, at);
  double sum = 0.0;
  for (size_t i = 0; i < part.end - part.first; ++i) {
    const double e = data.record->response[part.first + i] - offset -
                     ResponseOf(kind, model.mass_kg, flow.samples[i], flow.sample_force_n[i]);
    sum += e * e;
  }
  return sum;
}

// The stop position the impact at sample n (ImpactSamples' first mark) tells, as ImpactOnsetsM says:
// `start` is the stop-free start state fitted over `window` (ending at n).
double OnsetOf(const ActuatorModel& model, ResponseKind kind, const RecordData& data, double offset,
               const Segment& window, size_t n, const State& start) {
  const double fs = data.record->sample_rate_hz;
  ActuatorModel stop_free = model;
  stop_free.lower_stop_m = ActuatorModel::kNoLowerStop;
  stop_free.upper_stop_m = ActuatorModel::kNoUpperStop;
  Segment around = window;  // the samples the stop is matched to
  around.first = n - kOnsetBefore;
  around.end = n + kOnsetAfter;
  FlowRequest request;
  request.sample_count = static_cast<int>(around.end - around.first);
  request.sample_start_s = around.T0(fs);
  request.sample_interval_s = 1.0 / fs;
  const FlowResult flow =
      Flow(stop_free, data.drive, start, window.T0(fs), static_cast<double>(around.end - 1) / fs, request);
  // ImpactSamples marks 2 samples either side of each fourth difference that stands out: the first
  // one's centre is 2 on.
  const double centre = flow.samples[kOnsetBefore + 2].x_m;
  const bool lower = centre < 0;
  double low = flow.samples[0].x_m, high = low;
  for (const State& y : flow.samples) {
    low = std::min(low, y.x_m);
    high = std::max(high, y.x_m);
  }
  if (lower) high = flow.samples[0].x_m;
  else low = flow.samples[0].x_m;
  auto misfit = [&](double stop_m) {
    ActuatorModel m = stop_free;
    (lower ? m.lower_stop_m : m.upper_stop_m) = stop_m;
    try {
      return SampleMisfit(m, kind, data, offset, around, flow.samples[0]);
    } catch (const std::exception&) {
      return kInf;
    }
  };
  // The best of a grid over the bracket (the misfit need not have one minimum there: a bounce, or a
  // contact lined up with a later spike), then golden-section search between the grid point's neighbours
  // (Kiefer 1953; Press et al., "Numerical Recipes", 3rd ed., Sec. 10.2).
  const double step = (high - low) / kOnsetGrid;
  int best_point = 0;
  double best_misfit = kInf;
  for (int i = 0; i <= kOnsetGrid; ++i) {
    const double f = misfit(low + i * step);
    if (f < best_misfit) {
      best_misfit = f;
      best_point = i;
    }
  }
  const double ratio = (std::sqrt(5.0) - 1.0) / 2.0;
  double a = low + std::max(best_point - 1, 0) * step, b = low + std::min(best_point + 1, kOnsetGrid) * step;
  double c = b - ratio * (b - a), e = a + ratio * (b - a);
  double fc = misfit(c), fe = misfit(e);
  for (int i = 0; i < kOnsetSections; ++i) {
    if (fc < fe) {  // the minimum lies in [a, e]
      b = e;
      e = c;
      fe = fc;
      c = b - ratio * (b - a);
      fc = misfit(c);
    } else {  // in [c, b]
      a = c;
      c = e;
      fc = fe;
      e = a + ratio * (b - a);
      fe = misfit(e);
    }
  }
  const double best = 0.5 * (a + b);
  // At the bracket's end the contact set in outside it: the centre stands.
  if (std::abs(best - low) < 1e-3 * (high - low) || std::abs(best - high) < 1e-3 * (high - low)) return centre;
  return best;
}

}  // namespace

std::vector<size_t> SegmentFirsts(size_t samples, double sample_rate_hz, double segment_s) {
  const size_t length = std::max<size_t>(8, static_cast<size_t>(std::llround(segment_s * sample_rate_hz)));
  std::vector<size_t> firsts;
  for (size_t first = 0; first < samples; first += length) {
    firsts.push_back(first);
    if (samples - std::min(samples, first + length) < length / 2) break;  // no short tail segment
  }
  return firsts;
}

double FourthDifferenceNoiseRms(std::span<const double> y) {
  // Fourth differences (1, -4, 6, -4, 1; noise variance 70 sigma^2): a signal at w is scaled by
  // (2 sin(w / 2fs))^4, 2.5e-4 at a band edge of fs / 50 (second differences keep 1.6e-2 there).
  if (y.size() < 16) return kNaN;
  std::vector<double> d;
  d.reserve(y.size() - 4);
  for (size_t n = 2; n + 2 < y.size(); ++n) d.push_back(y[n - 2] - 4 * y[n - 1] + 6 * y[n] - 4 * y[n + 1] + y[n + 2]);
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  const double center = median(d);
  for (double& v : d) v = std::abs(v - center);
  return 1.4826 * median(d) / std::sqrt(70.0);
}

double ResponseNoiseRms(std::span<const double> response) {
  double power = 0.0;
  for (double v : response) power += v * v;
  const double rms = std::sqrt(power / static_cast<double>(std::max<size_t>(response.size(), 1)));
  return std::max(FourthDifferenceNoiseRms(response), 1e-9 * rms);
}

std::vector<bool> ImpactSamples(std::span<const double> y, double sigma) {
  std::vector<bool> impact(y.size(), false);
  const double limit = 8.0 * std::sqrt(70.0) * sigma;
  for (size_t n = 2; n + 2 < y.size(); ++n)
    if (std::abs(y[n - 2] - 4 * y[n - 1] + 6 * y[n] - 4 * y[n + 1] + y[n + 2]) > limit)
      for (size_t k = n - 2; k <= n + 2; ++k) impact[k] = true;
  return impact;
}

std::vector<double> ImpactOnsetsM(std::span<const Recording* const> records, ResponseKind kind,
                                  const ActuatorModel& model, const BroadbandFitOptions& options) {
  Validate(model);
  std::vector<Segment> segments;
  const std::vector<RecordData> data = RecordsData(records, options, &segments);
  const ExtendedProblem stop_free = StopFree(model);
  const StateScale scale(model);
  const int d = model.StateSize();
  std::vector<std::vector<double>> onsets(records.size());
  ParallelFor(records.size(), [&](size_t r) {
    const Recording& rec = *records[r];
    const double fs = rec.sample_rate_hz;
    const size_t longest = static_cast<size_t>(std::llround(kOnsetWindowS * fs));
    const size_t shortest = static_cast<size_t>(std::llround(kOnsetQuietS * fs));
    std::vector<double> nuisance(kNuisance, 0.0);
    for (double v : rec.response) nuisance[0] += v;
    nuisance[0] /= static_cast<double>(rec.size());
    size_t quiet_from = 0;  // the first sample after the last impact
    for (size_t n = 0; n < rec.size(); ++n) {
      if (!data[r].impact[n]) continue;
      const size_t quiet = n - quiet_from;
      quiet_from = n + 1;
      if (quiet < std::max(shortest, kOnsetBefore + 16)) continue;
      Segment window;
      window.record = r;
      window.first = n - std::min(quiet, longest);
      window.end = n;
      if (n + kOnsetAfter >= rec.size()) break;
      std::vector<double> start(d, 0.0);
      FitStopFreeStart(stop_free, kind, data[r], window, scale, d, nuisance, &start);
      try {
        onsets[r].push_back(OnsetOf(model, kind, data[r], nuisance[0], window, n, scale.Unscaled(start.data(), d)));
      } catch (const std::exception&) {  // a flow that fails: no onset from this window
      }
    }
  });
  std::vector<double> out;
  for (const std::vector<double>& o : onsets) out.insert(out.end(), o.begin(), o.end());
  return out;
}

BroadbandFitResult FitBroadband(std::span<const Recording* const> records, ResponseKind kind,
                                const ExtendedProblem& requested, const BroadbandFitOptions& options) {
  const auto clock_start = std::chrono::steady_clock::now();
  if (!(options.segment_s > 0) || !std::isfinite(options.segment_s))
    throw InputError("segment_s", "must be a finite number > 0");
  if (options.max_iterations < 1) throw InputError("max_iterations", "must be >= 1");
  if (records.empty()) throw InputError("records", "no broadband record to fit");
  if (!options.noise.empty() && options.noise.size() != records.size())
    throw InputError("noise", "holds " + std::to_string(options.noise.size()) + " levels for " +
                                  std::to_string(records.size()) + " records");
  for (const auto& level : options.noise)
    if (!(level.rms > 0) || !std::isfinite(level.rms) || level.samples < 1)
      throw InputError("noise", "each level must be finite and > 0, from at least one sample");
  if (options.stepped_orders < 1) throw InputError("stepped_orders", "must be >= 1");
  for (const RecordAnalysis* r : options.stepped)
    if (r == nullptr) throw InputError("stepped", "holds no record");
  Validate(requested.base);
  // An evaluation (no free parameter): Ceres takes no empty parameter block, so the costs get one that
  // is held constant.
  const bool evaluation = requested.parameters.empty();
  ExtendedProblem problem = requested;
  if (evaluation) problem.parameters = {HeldStiffness(requested.base)};
  const int p = static_cast<int>(problem.parameters.size());
  std::vector<double> theta(p, 1.0);
  const ActuatorModel start_model = problem.Decode(theta.data());
  // The start model's, not the base's: a coil's pole may be a free parameter that the base lacks (the
  // coil's force is then a state of every segment's start, and continuous across segments).
  const int d = start_model.StateSize();
  const StateScale scale(start_model);

  // Records, their drives, noise levels and segments.
  std::vector<Segment> segments;
  const std::vector<RecordData> data = RecordsData(records, options, &segments);

  // Unknowns: theta, each segment's scaled start state, each record's nuisance.
  std::vector<std::vector<double>> starts(segments.size(), std::vector<double>(d, 0.0));
  std::vector<std::vector<double>> nuisance(records.size(), std::vector<double>(kNuisance, 0.0));
  // The starts are fitted twice: with the offset at the response's mean and no hum, then with the
  // offset and hum that the first starts' residuals show (over a short window, hum of a few noise
  // levels is a misfit the start would otherwise take up).
  const BroadbandFitResult* warm = options.warm_start;
  if (warm && (warm->segment_starts.size() != segments.size() || warm->nuisance.size() != records.size()))
    throw InputError("warm_start", "is a fit of other records or segments (" + std::to_string(warm->segment_starts.size()) +
                                       " segments, this fit has " + std::to_string(segments.size()) + ")");
  bool add_coil_force = false;
  if (warm) {
    // A warm start without the coil's pole has no coil force: each segment's F_e then starts where it
    // would have settled (a start at 0 begins every segment with a jump of the drive force).
    add_coil_force = d == 3 && !warm->fit.model.HasCoilPole();
    for (size_t s = 0; s < segments.size(); ++s) {
      State y = warm->segment_starts[s];
      const RecordData& r = data[segments[s].record];
      if (add_coil_force)
        y.coil_force_n = QuasiStaticCoilForceN(start_model, r.drive.Voltage(segments[s].T0(r.drive.sample_rate_hz)), y);
      scale.Scale(y, d, starts[s].data());
    }
    nuisance = warm->nuisance;
  }
  if (!warm) ParallelFor(records.size(), [&](size_t r) {
    double mean = 0.0;
    for (double v : records[r]->response) mean += v;
    nuisance[r][0] = mean / static_cast<double>(records[r]->size());
    std::vector<double> theta_copy = theta;  // each record's own (the local problems hold them constant)
    FitSegmentStarts(problem, kind, data[r], segments, r, scale, d, theta_copy, nuisance[r], &starts);
    nuisance[r] = NuisanceOfResiduals(start_model, kind, data[r], segments, r, scale, d, starts);
    FitSegmentStarts(problem, kind, data[r], segments, r, scale, d, theta_copy, nuisance[r], &starts);
  });
  ceres::Problem::Options problem_options;
  ceres::Problem solver_problem(problem_options);
  solver_problem.AddParameterBlock(theta.data(), p);
  for (int i = 0; i < p; ++i) {
    solver_problem.SetParameterLowerBound(theta.data(), i, problem.parameters[i].theta_min);
    solver_problem.SetParameterUpperBound(theta.data(), i, problem.parameters[i].theta_max);
  }
  if (evaluation) solver_problem.SetParameterBlockConstant(theta.data());
  std::vector<ceres::ResidualBlockId> blocks;
  double continuity_gap = kContinuityGaps[0];
  for (size_t s = 0; s < segments.size(); ++s) {
    const Segment& seg = segments[s];
    auto* cost = new SegmentCost(problem, kind, data[seg.record], seg, scale, d, &continuity_gap);
    std::vector<double*> blocks_of = {theta.data(), starts[s].data(), nuisance[seg.record].data()};
    if (!seg.last) blocks_of.push_back(starts[s + 1].data());
    blocks.push_back(solver_problem.AddResidualBlock(cost, nullptr, blocks_of));
    BoundStart(&solver_problem, starts[s].data(), d);
  }

  // The stepped-sine records of a joint fit: their harmonics' residuals share theta. Anchors: the orbit
  // that matches each record best among the start model's attractors.
  const int orders = options.stepped_orders;
  std::vector<OrbitTarget> targets(options.stepped.size());
  std::vector<ceres::ResidualBlockId> stepped_blocks;
  ParallelFor(targets.size(), [&](size_t i) {
    OrbitTarget& t = targets[i];
    t.record = options.stepped[i];
    t.weight = 1.0 / t.record->harmonic_se;
    t.correction.assign(orders, 0.0);
    std::optional<ModelOrbit> orbit;
    try {
      orbit = BestMatchingOrbit(start_model, *t.record, kind, orders);
    } catch (const std::exception&) {
    }
    if (!orbit) throw NumericalError("no steady state of the starting model at record " + t.record->name);
    t.anchor = orbit->anchor;
  });
  for (const OrbitTarget& t : targets)
    stepped_blocks.push_back(solver_problem.AddResidualBlock(new OrbitCost(&problem, &t, kind, orders), nullptr, theta.data()));
  size_t stepped_residuals = 0;
  for (const RecordAnalysis* r : options.stepped) stepped_residuals += FittedResiduals(*r, orders);

  // Per-record residuals at the current unknowns: sum of squares of the sample rows, and of the raw
  // misfit in response units.
  auto record_misfit = [&](std::vector<double>* chi2, std::vector<double>* raw) {
    chi2->assign(records.size(), 0.0);
    raw->assign(records.size(), 0.0);
    for (size_t s = 0; s < segments.size(); ++s) {
      const Segment& seg = segments[s];
      const SegmentCost* cost = static_cast<const SegmentCost*>(solver_problem.GetCostFunctionForResidualBlock(blocks[s]));
      std::vector<double> residuals(cost->num_residuals());
      std::vector<const double*> parameter_blocks = {theta.data(), starts[s].data(), nuisance[seg.record].data()};
      if (!seg.last) parameter_blocks.push_back(starts[s + 1].data());
      if (!cost->Evaluate(parameter_blocks.data(), residuals.data(), nullptr)) {
        (*chi2)[seg.record] = (*raw)[seg.record] = kNaN;
        continue;
      }
      for (size_t i = 0; i < seg.end - seg.first; ++i) {
        (*chi2)[seg.record] += residuals[i] * residuals[i];
        const double e = residuals[i] * data[seg.record].sigma;
        (*raw)[seg.record] += e * e;
      }
    }
  };
  std::vector<double> chi2_initial, raw_initial;
  record_misfit(&chi2_initial, &raw_initial);

  // After each successful step the stepped records' anchors move to the new iterate's orbits (and stay on
  // each record's branch).
  AfterSuccessfulStep callback([&] {
    if (targets.empty()) return;
    const ActuatorModel model = problem.Decode(theta.data());
    ParallelFor(targets.size(), [&](size_t i) { MoveAnchor(model, *targets[i].record, kind, orders, &targets[i].anchor); });
  });
  ceres::Solver::Options solver = RefinementSolverOptions(options.max_iterations, &callback);
  solver.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  if (options.threads > 0) solver.num_threads = options.threads;
  ceres::Solver::Summary summary;
  int iterations = 0;
  auto solve = [&] {
    RefreshCorrections(problem.Decode(theta.data()), targets, kind, orders);
    solver.max_solver_time_in_seconds = std::max(
        1.0, options.max_seconds - std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count());
    ceres::Solve(solver, &solver_problem, &summary);
    iterations += static_cast<int>(summary.iterations.size()) - 1;
  };
  // A warm start's gaps are closed already: its fit starts at the final weight. Not where it lacked the
  // coil: the coil's pole moves every segment's end, and from gaps of 1e-6 of the scales Ceres then ran
  // out of iterations with tau_e at a third of its truth (tuning campaign 8301: 0.2 against 0.67 ms).
  for (size_t g = warm && !add_coil_force ? std::size(kContinuityGaps) - 1 : 0; g < std::size(kContinuityGaps); ++g) {
    continuity_gap = kContinuityGaps[g];
    solve();
  }
  // The model's parameters' errors at the current unknowns (ModelErrors), or nothing.
  ceres::Problem::EvaluateOptions evaluate;
  evaluate.parameter_blocks.push_back(theta.data());
  for (auto& s : starts) evaluate.parameter_blocks.push_back(s.data());
  for (auto& q : nuisance) evaluate.parameter_blocks.push_back(q.data());
  auto parameter_errors = [&](double residual_variance) -> std::optional<ParameterErrors> {
    ceres::CRSMatrix crs;
    if (evaluation || !solver_problem.Evaluate(evaluate, nullptr, nullptr, nullptr, &crs)) return std::nullopt;
    return ModelErrors(crs, p, residual_variance);
  };
  // With stepped records, solves with refreshed sampling corrections until they move no parameter by
  // more than kSolveTolerancePerError of its standard error (the residual variance taken as 1: the
  // residuals are in noise standard errors).
  bool corrections_settled = targets.empty() || evaluation;
  for (int pass = 0; !corrections_settled && pass < kJointPasses; ++pass) {
    if (summary.termination_type != ceres::CONVERGENCE) break;
    const std::vector<double> before = theta;
    solve();
    const std::optional<ParameterErrors> errors = parameter_errors(1.0);
    if (!errors) break;
    double move = 0.0;  // the largest move of an identifiable theta, in its standard errors
    for (int i = 0; i < p; ++i)
      if (errors->identifiable[i]) move = std::max(move, std::abs(theta[i] - before[i]) / std::sqrt(errors->covariance(i, i)));
    corrections_settled = move <= kSolveTolerancePerError;
  }

  BroadbandFitResult out;
  ExtendedFitResult& fit = out.fit;
  fit.theta = theta;
  fit.model = problem.Decode(theta.data());
  fit.iterations = iterations;
  fit.passes = static_cast<int>(std::size(kContinuityGaps));
  std::vector<double> chi2, raw;
  record_misfit(&chi2, &raw);
  size_t samples = 0;
  for (const Recording* r : records) samples += r->size();
  fit.residuals = samples + stepped_residuals;
  fit.chi2 = 0.0;
  for (double c : chi2) fit.chi2 += c;
  for (size_t i = 0; i < targets.size(); ++i) {
    SteppedRecordFit f;
    f.name = targets[i].record->name;
    f.residuals = FittedResiduals(*targets[i].record, orders);
    std::vector<double> residuals(2 * static_cast<size_t>(orders));
    const double* theta_block = theta.data();
    const ceres::CostFunction* cost = solver_problem.GetCostFunctionForResidualBlock(stepped_blocks[i]);
    f.chi2 = cost->Evaluate(&theta_block, residuals.data(), nullptr) ? 0.0 : kNaN;
    for (double r : residuals) f.chi2 += r * r;
    fit.chi2 += f.chi2;
    out.stepped.push_back(f);
  }
  // Degrees of freedom: the samples and stepped residuals less the model's parameters, one start state
  // per record (the continuity rows tie the other segments' starts) and the nuisance.
  const int free_parameters = evaluation ? 0 : p;
  const double dof = static_cast<double>(fit.residuals) - free_parameters -
                     static_cast<double>(records.size()) * (d + kNuisance);
  fit.residual_variance = fit.chi2 / dof;
  fit.report = summary.BriefReport();
  bool converged = summary.termination_type == ceres::CONVERGENCE && std::isfinite(fit.chi2);
  if (converged && !corrections_settled) {
    converged = false;
    fit.report += "\nNOT CONVERGED: the stepped records' sampling corrections still moved the parameters after " +
                  std::to_string(kJointPasses) + " solves";
  }

  fit.covariance.assign(static_cast<size_t>(free_parameters) * free_parameters, kNaN);
  const std::optional<ParameterErrors> errors = parameter_errors(fit.residual_variance);
  if (!errors && !evaluation) {
    converged = false;
    fit.report += "\nNOT CONVERGED: the segments' start states, offsets and hum are not all identifiable from these "
                  "records, so neither are the parameters' errors";
  }
  std::string unidentified;
  for (int i = 0; i < free_parameters; ++i) {
    const FreeParameter& fp = problem.parameters[i];
    const bool identified = errors && errors->identifiable[i];
    FitParameter parameter = fp.Reported(theta[i], identified ? errors->covariance(i, i) : kNaN);
    parameter.identifiable = identified;
    const bool on_bound = theta[i] <= fp.theta_min + 1e-9 || theta[i] >= fp.theta_max - 1e-9;
    if (on_bound) parameter.note = "ended on its bound";
    else if (errors && !identified) parameter.note = "not identifiable from these records";
    if (errors && !identified) unidentified += (unidentified.empty() ? "" : ", ") + fp.name;
    fit.parameters.push_back(parameter);
    if (identified)
      for (int j = 0; j < p; ++j)
        if (errors->identifiable[j])
          fit.covariance[static_cast<size_t>(i) * p + j] =
              errors->covariance(i, j) * fp.ValuePerTheta(theta[i]) * problem.parameters[j].ValuePerTheta(theta[j]);
  }
  if (!unidentified.empty()) {
    converged = false;
    fit.report += "\nNOT IDENTIFIABLE from these records: " + unidentified;
  }
  fit.converged = converged;
  if (summary.termination_type != ceres::CONVERGENCE) fit.report += "\nNOT CONVERGED: " + summary.message;
  // The records reject the fitted model (as extended_fit.h: a wrong model, or a valley of the misfit
  // away from the optimum, where records with hard impacts can end from a start far from the truth)
  // when chi-square stands beyond its 1e-3 upper tail. The noise levels it is scaled by are estimates
  // from the same records, whose own spread (kNoiseEstimateVariance) widens chi-square / dof's beyond
  // chi-square's 2 / dof: var = 2 / dof + 4 sum_r (n_r / M)^2 kNoiseEstimateVariance / N_r, with N_r
  // the samples record r's level was estimated from (n_r, its own, unless options.noise says) and M
  // every residual (a stepped record's harmonic standard error is taken as known).
  double variance = 2.0 / dof;
  for (size_t r = 0; r < records.size(); ++r) {
    const double share = static_cast<double>(records[r]->size()) / static_cast<double>(fit.residuals);
    const size_t estimated_from = options.noise.empty() ? records[r]->size() : options.noise[r].samples;
    variance += 4.0 * share * share * kNoiseEstimateVariance / static_cast<double>(estimated_from);
  }
  constexpr double kUpperTail1e3 = 3.0902;  // the standard normal's 1e-3 upper quantile
  const double limit = dof * (1.0 + kUpperTail1e3 * std::sqrt(variance));
  out.dof = dof;
  out.chi2_limit = limit;
  out.rejected = !(fit.chi2 <= limit);
  if (out.rejected) {
    char line[200];
    std::snprintf(line, sizeof line,
                  "\nREJECTED: chi-square %.4g over %.0f degrees of freedom, beyond its 1e-3 upper tail %.4g (the "
                  "noise levels' own spread included): the fitted model does not explain the records",
                  fit.chi2, dof, limit);
    fit.report += line;
  }

  for (size_t r = 0; r < records.size(); ++r) {
    const Recording& rec = *records[r];
    BroadbandRecordFit f;
    f.name = rec.name;
    f.noise_rms = data[r].sigma;
    f.offset = nuisance[r][0];
    for (int j = 1; j < kNuisance; ++j) f.hum_amplitude = std::max(f.hum_amplitude, std::abs(nuisance[r][j]));
    double power = 0.0;
    for (double v : rec.response) power += (v - f.offset) * (v - f.offset);
    f.nrmse_initial = std::sqrt(raw_initial[r] / power);
    f.nrmse = std::sqrt(raw[r] / power);
    f.chi2_per_sample = chi2[r] / static_cast<double>(rec.size());
    f.segments = static_cast<size_t>(std::count_if(segments.begin(), segments.end(),
                                                   [r](const Segment& s) { return s.record == r; }));
    out.records.push_back(f);
  }
  for (size_t s = 0; s < segments.size(); ++s) out.segment_starts.push_back(scale.Unscaled(starts[s].data(), d));
  out.nuisance = nuisance;
  if (options.keep_series) {
    for (size_t r = 0; r < records.size(); ++r) {
      BroadbandRecordFit& f = out.records[r];
      f.residual.assign(records[r]->size(), kNaN);
      f.x_m = f.v_m_per_s = f.residual;
    }
    ParallelFor(segments.size(), [&](size_t s) {
      const Segment& seg = segments[s];
      SegmentSeries(fit.model, kind, data[seg.record], seg, scale.Unscaled(starts[s].data(), d), nuisance[seg.record],
                    &out.records[seg.record]);
    });
  }
  fit.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return out;
}

}  // namespace strokelab::internal
