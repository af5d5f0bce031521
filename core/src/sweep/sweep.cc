// The sweep engine: rows (one amplitude, continuation in frequency) give the steady states at the
// grid points and the jump intervals; columns (one frequency, root-finding and continuation in
// amplitude) give the saturation threshold. Rows and columns are independent units of work, run on
// a pool of threads and written into slots by index, so results do not depend on the thread count.
#include "strokelab/base/cancel.h"
#include "strokelab/sweep/sweep.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <limits>
#include <mutex>
#include <numbers>
#include <sstream>
#include <thread>

#include "strokelab/base/errors.h"
#include "strokelab/base/parallel_for.h"
#include "strokelab/steady/continuation.h"
#include "strokelab/steady/steady_state.h"

namespace strokelab {
namespace {

constexpr double kRangeMargin = 0.02;  // continuation runs 2 % past the grid on each side
// A row's continuation that stops short of the grid (its corrector fails, e.g. where a smooth model's
// orbit grazes the stop or friction sticks) starts again on the attractor this fraction above the
// highest frequency it reached, at most kMaxRowRestarts times.
constexpr double kRestartGap = 0.01;
constexpr int kMaxRowRestarts = 8;

SweepPoint MakeSweepPoint(const ActuatorModel& model, double f_hz, double amplitude_v, Branch branch, bool stable,
                          int period, const OrbitFigures& figures, double max_multiplier) {
  SweepPoint p;
  p.frequency_hz = f_hz;
  p.amplitude_v = amplitude_v;
  p.branch = branch;
  p.stable = stable;
  p.period = period;
  const double omega = 2.0 * std::numbers::pi * f_hz;
  // C_1(f) = -m w^2 C_1(x) (steady_state.h); H = C_1(f) / C_1(v_in), C_1(v_in) = -j V.
  const std::complex<double> force_c1 = -model.mass_kg * omega * omega * figures.x1;
  p.h = amplitude_v > 0 ? force_c1 / std::complex<double>(0.0, -amplitude_v) : 0.0;
  p.first_harmonic_force_n = std::abs(force_c1);
  p.first_harmonic_phase_rad = std::arg(p.h);
  p.min_displacement_m = figures.min_displacement_m;
  p.max_displacement_m = figures.max_displacement_m;
  p.peak_force_n = figures.peak_force_n;
  p.contacts_per_period = static_cast<double>(figures.contacts) / (period > 0 ? period : 16);
  p.max_multiplier = max_multiplier;
  return p;
}

SweepPoint FromBranchPoint(const ActuatorModel& model, double amplitude_v, const BranchPoint& b, Branch branch) {
  return MakeSweepPoint(model, b.parameter, amplitude_v, branch, b.stable, 1, b.figures, b.MaxMultiplier());
}

SweepPoint FromAttractor(const ActuatorModel& model, double f_hz, double amplitude_v, const SteadyState& s,
                         Branch branch) {
  return MakeSweepPoint(model, f_hz, amplitude_v, branch, s.stable, s.period, s.figures, s.MaxMultiplier());
}

// What bounds a stable stretch of a branch where it ends between points[k] and points[k + 1].
struct Boundary {
  double frequency_hz;
  std::string kind;
};

Boundary BoundaryInSegment(const ContinuedBranch& branch, size_t k) {
  const BranchEvent* fold = nullptr;
  const BranchEvent* graze = nullptr;
  const BranchEvent* stability = nullptr;
  // A grazing corner is sometimes seen as a fold in one segment and as grazing in the next, a
  // hair apart: look at the neighbouring segments too and let grazing win where they coincide.
  for (const BranchEvent& e : branch.events) {
    if (e.kind == BranchEvent::Kind::kGrazing && e.after + 1 >= k && e.after <= k + 1) {
      const double p = branch.points[k].parameter;
      if (e.after == k || std::abs(e.point.parameter - p) < 1e-3 * p) graze = &e;
    }
  }
  for (const BranchEvent& e : branch.events) {
    if (e.after != k) continue;
    if (e.kind == BranchEvent::Kind::kFold) fold = &e;
    if (e.kind == BranchEvent::Kind::kStabilityChange) stability = &e;
  }
  if (graze) return {graze->point.parameter, "grazing"};
  if (stability && stability->period_doubling) return {stability->point.parameter, "period-doubling"};
  if (fold) return {fold->point.parameter, "fold"};
  if (stability) return {stability->point.parameter, "fold"};
  return {0.5 * (branch.points[k].parameter + branch.points[k + 1].parameter), "unlocated"};
}

// Frequency intervals where two stable stretches of the row's branches overlap. A branch's ends are the
// grid's where it starts at the grid's lowest frequency or leaves the range; where it was restarted or
// stopped short, the stretch is bounded there by something not located.
std::vector<JumpInterval> JumpIntervals(const std::vector<ContinuedBranch>& branches, double amplitude_v, double f_lo,
                                        double f_hi) {
  struct Run {
    Boundary lo, hi;
  };
  std::vector<Run> runs;
  for (const ContinuedBranch& branch : branches) {
    const auto& pts = branch.points;
    const char* first_end = pts.front().parameter <= f_lo ? "grid" : "unlocated";
    const char* last_end = branch.stopped_because == "range" ? "grid" : "unlocated";
    for (size_t i = 0; i < pts.size();) {
      if (!pts[i].stable) {
        ++i;
        continue;
      }
      size_t j = i;
      while (j + 1 < pts.size() && pts[j + 1].stable) ++j;
      Boundary a = i == 0 ? Boundary{pts[0].parameter, first_end} : BoundaryInSegment(branch, i - 1);
      Boundary b = j + 1 == pts.size() ? Boundary{pts[j].parameter, last_end} : BoundaryInSegment(branch, j);
      if (a.frequency_hz > b.frequency_hz) std::swap(a, b);
      if (a.frequency_hz < f_lo) a = {f_lo, "grid"};
      if (b.frequency_hz > f_hi) b = {f_hi, "grid"};
      if (b.frequency_hz > a.frequency_hz) runs.push_back({a, b});
      i = j + 1;
    }
  }
  std::vector<JumpInterval> jumps;
  for (size_t a = 0; a < runs.size(); ++a) {
    for (size_t b = a + 1; b < runs.size(); ++b) {
      const Boundary& lo = runs[a].lo.frequency_hz > runs[b].lo.frequency_hz ? runs[a].lo : runs[b].lo;
      const Boundary& hi = runs[a].hi.frequency_hz < runs[b].hi.frequency_hz ? runs[a].hi : runs[b].hi;
      if (hi.frequency_hz - lo.frequency_hz > 1e-9 * lo.frequency_hz)
        jumps.push_back({amplitude_v, lo.frequency_hz, hi.frequency_hz, lo.kind, hi.kind});
    }
  }
  std::sort(jumps.begin(), jumps.end(),
            [](const JumpInterval& x, const JumpInterval& y) { return x.bistable_from_hz < y.bistable_from_hz; });
  // An interval cut by a restart (it ends where one branch stopped and the next begins within the
  // restart's gap, both ends unlocated) is one interval: bistable on both sides of the gap.
  std::vector<JumpInterval> merged;
  for (const JumpInterval& j : jumps) {
    if (!merged.empty()) {
      JumpInterval& last = merged.back();
      if (last.to_kind == "unlocated" && j.from_kind == "unlocated" &&
          j.bistable_from_hz <= last.bistable_to_hz * (1 + 2 * kRestartGap) && j.bistable_from_hz >= last.bistable_to_hz) {
        last.bistable_to_hz = j.bistable_to_hz;
        last.to_kind = j.to_kind;
        continue;
      }
    }
    merged.push_back(j);
  }
  return merged;
}

std::optional<FieldError> AxisError(const GridAxis& axis, const std::string& name, double lowest) {
  if (!std::isfinite(axis.from) || axis.from < lowest)
    return FieldError{name + ".from", "must be a finite number >= " + std::to_string(lowest)};
  if (!std::isfinite(axis.to) || axis.to < axis.from) return FieldError{name + ".to", "must be >= " + name + ".from"};
  if (axis.points < 1 || axis.points > 100000) return FieldError{name + ".points", "must be between 1 and 100000"};
  if (axis.points > 1 && axis.to == axis.from) return FieldError{name + ".to", "must be > from when points > 1"};
  if (axis.geometric && axis.from <= 0) return FieldError{name + ".from", "must be > 0 on a geometric grid"};
  return std::nullopt;
}

// The branches of one amplitude over the grid, by continuation in frequency from its lowest frequency.
// A branch that ends below the top of the range (its corrector failed, or it turned at a fold and left
// the range at the bottom) is followed by one from the attractor kRestartGap above the highest frequency
// it reached, seeded by its orbit there; where no period-1 orbit is found, the next grid frequency above
// is tried. At most 1 + kMaxRowRestarts branches.
std::vector<ContinuedBranch> RowBranches(const ActuatorModel& model, double amplitude_v, const std::vector<double>& grid_hz,
                                         const ContinuationOptions& continuation, const std::atomic<bool>* cancel) {
  const double p_min = grid_hz.front() * (1 - kRangeMargin), p_max = grid_hz.back() * (1 + kRangeMargin);
  std::vector<ContinuedBranch> branches;
  double from = grid_hz.front();
  std::optional<State> seed;  // the orbit of the branch before, near `from`
  for (int attempt = 0; attempt <= kMaxRowRestarts && from <= p_max; ++attempt) {
    const PeriodMap map(model, from, amplitude_v);
    std::optional<SteadyState> start = seed ? std::nullopt : Shoot(map, map.ClippedLinearStart(), 1);
    if (!start) start = Shoot(map, SolveAttractor(map, seed.value_or(map.ClippedLinearStart())).start, 1);
    if (!start) {
      const auto next = std::upper_bound(grid_hz.begin(), grid_hz.end(), from);
      if (next == grid_hz.end()) break;  // the points above come from SolveAttractor
      from = *next;
      continue;
    }
    branches.push_back(ContinueBranch(model, ContinuationParameter::kFrequencyHz, amplitude_v, from, start->start,
                                      p_min, p_max, true, continuation, cancel));
    const ContinuedBranch& last = branches.back();
    if (last.stopped_because == "cancelled") break;
    const BranchPoint& highest = *std::max_element(
        last.points.begin(), last.points.end(),
        [](const BranchPoint& a, const BranchPoint& b) { return a.parameter < b.parameter; });
    if (highest.parameter > p_max) break;  // the branch covered the range
    from = std::max(highest.parameter, from) * (1 + kRestartGap);
    seed = highest.start;
  }
  return branches;
}

// The orbits of the row's branches at frequency f, in the branches' order, each orbit once (a restarted
// branch that turns back at a fold can trace an orbit an earlier branch holds).
std::vector<BranchPoint> RowSolutionsAt(const ActuatorModel& model, const std::vector<ContinuedBranch>& branches,
                                        double f) {
  if (branches.size() == 1) return SolutionsAt(model, branches.front(), f);
  const double length = LengthScaleM(model), speed = length * 2.0 * std::numbers::pi * f;
  std::vector<BranchPoint> out;
  for (const ContinuedBranch& branch : branches)
    for (BranchPoint& s : SolutionsAt(model, branch, f)) {
      const bool known = std::any_of(out.begin(), out.end(), [&](const BranchPoint& o) {
        return std::abs(o.start.x_m - s.start.x_m) < 1e-6 * length &&
               std::abs(o.start.v_m_per_s - s.start.v_m_per_s) < 1e-6 * speed;
      });
      if (!known) out.push_back(std::move(s));
    }
  return out;
}

}  // namespace

// The steady states of one amplitude at every grid frequency, by continuation in frequency.
SweepRowResult SweepRow(const ActuatorModel& model, double amplitude_v, const std::vector<double>& grid_hz,
                        const std::atomic<bool>* cancel, const std::function<void(size_t points)>& passed) {
  const CancelScope scope(cancel ? cancel : CurrentCancelFlag());  // the engines poll it too
  cancel = CurrentCancelFlag();
  SweepRowResult row;
  ContinuationOptions continuation;
  size_t reached = 0;
  if (passed)
    continuation.on_point = [&](double f_hz) {
      const size_t n = static_cast<size_t>(std::count_if(grid_hz.begin(), grid_hz.end(), [&](double g) { return g <= f_hz; }));
      if (n > reached) passed(reached = n);
    };
  const double f_lo = grid_hz.front(), f_hi = grid_hz.back();
  const std::vector<ContinuedBranch> branches = RowBranches(model, amplitude_v, grid_hz, continuation, cancel);
  row.jumps = JumpIntervals(branches, amplitude_v, f_lo, f_hi);
  for (double f : grid_hz) {
    if (cancel && cancel->load()) throw Cancelled();
    const PeriodMap map(model, f, amplitude_v);
    const std::vector<BranchPoint> solutions = RowSolutionsAt(model, branches, f);
    std::vector<const BranchPoint*> stable;
    for (const BranchPoint& s : solutions)
      if (s.stable) stable.push_back(&s);
    if (stable.empty()) {
      // No stable period-1 orbit (period doubling, chaos, or a branch that could not be followed):
      // the attractor reached from the least unstable orbit (or the linear start) is the response.
      State guess = map.ClippedLinearStart();
      double least = INFINITY;
      for (const BranchPoint& s : solutions)
        if (s.MaxMultiplier() < least) least = s.MaxMultiplier(), guess = s.start;
      const SteadyState attractor = SolveAttractor(map, guess);
      row.points.push_back(FromAttractor(model, f, amplitude_v, attractor, Branch::kUp));
      row.points.push_back(FromAttractor(model, f, amplitude_v, attractor, Branch::kDown));
    } else {
      // Along the branch from low frequency: the up-sweep stays on the first stable orbit it
      // meets, the down-sweep (coming from high frequency) on the last.
      row.points.push_back(FromBranchPoint(model, amplitude_v, *stable.front(), Branch::kUp));
      row.points.push_back(FromBranchPoint(model, amplitude_v, *stable.back(), Branch::kDown));
    }
    for (const BranchPoint& s : solutions)
      if (!s.stable) row.points.push_back(FromBranchPoint(model, amplitude_v, s, Branch::kUnstable));
  }
  return row;
}

// The saturation threshold at one frequency: the grazing amplitude of the non-contacting response,
// and the lowest amplitude down to which the contacting response stays a stable attractor
// (continuation in amplitude from well above grazing, to a fold or to grazing).
SaturationThreshold SweepColumn(const ActuatorModel& model, double f_hz, const std::atomic<bool>* cancel) {
  const CancelScope scope(cancel ? cancel : CurrentCancelFlag());  // the engines poll it too
  cancel = CurrentCancelFlag();
  SaturationThreshold t{f_hz, NAN, NAN};
  if (!model.HasLowerStop() && !model.HasUpperStop()) return t;
  const double v_probe = 1e-3;
  BranchPoint quiet;
  quiet.parameter = v_probe;
  {
    ActuatorModel free_model = model;
    free_model.lower_stop_m = ActuatorModel::kNoLowerStop;
    free_model.upper_stop_m = ActuatorModel::kNoUpperStop;
    const PeriodMap map(free_model, f_hz, v_probe);
    const std::optional<BranchPoint> q =
        SolveAt(free_model, ContinuationParameter::kAmplitudeV, f_hz, v_probe, map.ClippedLinearStart());
    if (!q) return t;
    quiet = *q;
  }
  const std::optional<BranchPoint> graze = LocateGrazing(model, ContinuationParameter::kAmplitudeV, f_hz, quiet);
  if (!graze) return t;
  t.grazing_amplitude_v = graze->parameter;
  if (cancel && cancel->load()) throw Cancelled();

  // Start on the contacting response well above grazing, where no other response exists.
  const double v_start = 1.3 * t.grazing_amplitude_v;
  const PeriodMap map(model, f_hz, v_start);
  // Any period-1 orbit there will do to start the continuation (stable or not); the attractor
  // search (hundreds of periods where the response is period-doubled) only if shooting fails.
  std::optional<SteadyState> orbit = Shoot(map, map.ClippedLinearStart(), 1);
  if (!orbit) orbit = Shoot(map, SolveAttractor(map, map.ClippedLinearStart()).start, 1);
  if (!orbit) return t;
  ContinuationOptions options;
  options.stop_at_first_event = true;
  const ContinuedBranch branch =
      ContinueBranch(model, ContinuationParameter::kAmplitudeV, f_hz, v_start, orbit->start,
                     0.05 * t.grazing_amplitude_v, 2.0 * v_start, false, options, cancel);
  // The contacting response lasts down to the first fold, grazing, or loss of stability other than
  // period doubling (past period doubling a stable period-2 contacting response takes over).
  t.lowest_contact_amplitude_v = branch.points.back().parameter;
  for (const BranchEvent& e : branch.events) {
    if (e.kind == BranchEvent::Kind::kStabilityChange && e.period_doubling) continue;
    if (e.kind == BranchEvent::Kind::kStabilityChange && e.point.stable) continue;  // regained
    t.lowest_contact_amplitude_v = e.point.parameter;
    break;
  }
  return t;
}

namespace {

// `value` as the decimal it rounds from: from + (to - from) s lands a few ulps off the decimal the
// axis defines (0.1 + 0.2 = 0.30000000000000004 on 0.1 .. 0.6 V), which then prints and is queried as
// such. The decimal of 12 significant digits is taken when it lies within 4 ulps (a value that is no
// short decimal, 0.5 + 1/3, is 1e-13 or more from it and is left as computed).
double NearestShortDecimal(double value) {
  if (value == 0 || !std::isfinite(value)) return value;
  char text[32];
  std::snprintf(text, sizeof text, "%.12g", value);
  const double decimal = std::strtod(text, nullptr);
  return std::abs(decimal - value) <= 4 * std::numeric_limits<double>::epsilon() * std::abs(value) ? decimal : value;
}

}  // namespace

std::vector<double> GridAxis::Values() const {
  std::vector<double> values(points);
  for (int i = 0; i < points; ++i) {
    const double s = points == 1 ? 0.0 : static_cast<double>(i) / (points - 1);
    values[i] = NearestShortDecimal(geometric ? from * std::pow(to / from, s) : from + (to - from) * s);
  }
  if (points > 1) values.back() = to;
  return values;
}

std::optional<FieldError> SweepSpec::IsValid() const {
  if (auto error = model.IsValid()) return error;
  if (auto error = AxisError(frequency_hz, "frequency_hz", 1e-3)) return error;
  if (auto error = AxisError(amplitude_v, "amplitude_v", 1e-6)) return error;
  if (static_cast<double>(frequency_hz.points) * amplitude_v.points > 4e6)
    return FieldError{"grid", "frequency points x amplitude points must not exceed 4,000,000"};
  if (threads < 1 || threads > 256) return FieldError{"threads", "must be between 1 and 256"};
  return std::nullopt;
}

const char* ToString(Branch branch) {
  switch (branch) {
    case Branch::kUp: return "up";
    case Branch::kDown: return "down";
    case Branch::kUnstable: return "unstable";
  }
  return "?";
}

SweepResult RunSweep(const SweepSpec& spec, const std::function<void(const SweepProgress&)>& progress,
                     const std::atomic<bool>* cancel) {
  Validate(spec);
  const CancelScope scope(cancel ? cancel : CurrentCancelFlag());
  cancel = CurrentCancelFlag();
  const auto start = std::chrono::steady_clock::now();
  SweepResult result;
  result.frequency_hz = spec.frequency_hz.Values();
  result.amplitude_v = spec.amplitude_v.Values();
  const size_t rows = result.amplitude_v.size();
  const size_t columns = spec.thresholds ? result.frequency_hz.size() : 0;
  std::vector<SweepRowResult> row_results(rows);
  result.saturation_threshold.resize(columns);
  std::vector<std::string> failures(rows + columns);  // by unit, in slots: independent of the threads

  // Progress in grid points and columns (SweepProgress); `done` is changed and reported under the
  // mutex, so that the counts reported only grow.
  std::mutex progress_mutex;
  size_t done = 0;
  const size_t row_points = result.frequency_hz.size();
  const size_t total = rows * row_points + columns;
  auto advance = [&](size_t units) {
    if (!progress || units == 0) return;
    std::lock_guard<std::mutex> lock(progress_mutex);
    done += units;
    progress({done, total});
  };
  ParallelFor(rows + columns, [&](size_t i) {
    size_t row_reported = 0;  // of this row's points
    try {
      if (i < rows) {
        row_results[i] = SweepRow(spec.model, result.amplitude_v[i], result.frequency_hz, cancel, [&](size_t points) {
          advance(points - row_reported);
          row_reported = points;
        });
      } else {
        result.saturation_threshold[i - rows] = SweepColumn(spec.model, result.frequency_hz[i - rows], cancel);
      }
    } catch (const NumericalError& e) {
      if (!spec.skip_failed_units) throw;
      std::ostringstream unit;
      unit.precision(6);
      if (i < rows) {
        unit << "row at " << result.amplitude_v[i] << " V: " << e.what();
      } else {
        const double f_hz = result.frequency_hz[i - rows];
        result.saturation_threshold[i - rows] = {f_hz, NAN, NAN};
        unit << "column at " << f_hz << " Hz: " << e.what();
      }
      failures[i] = unit.str();
    }
    advance(i < rows ? row_points - row_reported : 1);
  }, static_cast<size_t>(spec.threads), cancel);
  if (cancel && cancel->load()) throw Cancelled();
  for (SweepRowResult& r : row_results) {
    result.points.insert(result.points.end(), r.points.begin(), r.points.end());
    result.jump.insert(result.jump.end(), r.jumps.begin(), r.jumps.end());
  }
  for (std::string& failure : failures)
    if (!failure.empty()) result.failures.push_back(std::move(failure));
  result.wall_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.points_per_second = static_cast<double>(rows * result.frequency_hz.size()) / result.wall_time_s;
  return result;
}

}  // namespace strokelab
