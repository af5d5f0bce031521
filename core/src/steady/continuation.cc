#include "strokelab/steady/continuation.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/LU>

#include "strokelab/base/illinois.h"

namespace strokelab {
namespace {

// A point u = (x / L, v / (w L), F_e / (k_p L), p / p_ref) of the branch's space, scaled to order one;
// e (the coil's force) stays 0 for models without the coil's pole.
struct Vec {
  double x = 0, v = 0, e = 0, p = 0;
  Vec operator+(const Vec& o) const { return {x + o.x, v + o.v, e + o.e, p + o.p}; }
  Vec operator-(const Vec& o) const { return {x - o.x, v - o.v, e - o.e, p - o.p}; }
  Vec operator*(double s) const { return {x * s, v * s, e * s, p * s}; }
  double Dot(const Vec& o) const { return x * o.x + v * o.v + e * o.e + p * o.p; }
  double Norm() const { return std::sqrt(Dot(*this)); }
  // Component i of the d + 1 that take part: x, v (, e), p.
  double& operator()(int i, int d) { return i == 0 ? x : i == 1 ? v : i == d ? p : e; }
};

// G(u) and its Jacobian at one point, with the orbit's figures; rows and state columns 0 .. d-1,
// the parameter's column d.
struct Evaluation {
  int d = 2;
  double g[3] = {0, 0, 0};
  double jacobian[3][4] = {};
  OrbitFigures figures;
  double Residual() const { return d == 2 ? std::hypot(g[0], g[1]) : std::sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]); }
  // The null vector of the d x (d+1) Jacobian, normalised: for d = 2 the cross product of its rows;
  // generally the signed minors, t_k = (-1)^k det(J without column k).
  Vec Tangent() const {
    Vec t;
    if (d == 2) {
      const double* a = jacobian[0];
      const double* b = jacobian[1];
      t = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], 0.0, a[0] * b[1] - a[1] * b[0]};
    } else {
      for (int k = 0; k <= 3; ++k) {
        Eigen::Matrix3d minor;
        for (int i = 0; i < 3; ++i)
          for (int j = 0, col = 0; j <= 3; ++j)
            if (j != k) minor(i, col++) = jacobian[i][j];
        t(k, 3) = (k % 2 == 0 ? 1.0 : -1.0) * minor.determinant();
      }
    }
    return t * (1.0 / t.Norm());
  }
};

// Solves the 3x3 system A d = r by Cramer's rule (well-conditioned here: the arclength row is the
// tangent, orthogonal to the Jacobian's rows' span complement).
bool Solve3(const double a[3][3], const double r[3], double d[3]) {
  const double det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                     a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                     a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
  if (!(std::abs(det) > 0.0) || !std::isfinite(det)) return false;
  for (int col = 0; col < 3; ++col) {
    double m[3][3];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) m[i][j] = j == col ? r[i] : a[i][j];
    d[col] = (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
              m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])) / det;
  }
  return true;
}

// Signed distance of an orbit from the stops: negative when it reaches into one [m].
double StopClearanceM(const ActuatorModel& model, const OrbitFigures& f) {
  double clearance = INFINITY;
  if (model.HasLowerStop()) clearance = std::min(clearance, f.min_displacement_m - model.lower_stop_m);
  if (model.HasUpperStop()) clearance = std::min(clearance, model.upper_stop_m - f.max_displacement_m);
  return clearance;
}

class BranchProblem {
 public:
  BranchProblem(const ActuatorModel& model, ContinuationParameter which, double fixed_value, double p_ref)
      : model_(model), which_(which), fixed_(fixed_value), p_ref_(p_ref) {
    length_m_ = LengthScaleM(model);
    const double f_ref = which == ContinuationParameter::kFrequencyHz ? p_ref : fixed_value;
    speed_m_per_s_ = length_m_ * 2.0 * std::numbers::pi * f_ref;
    force_n_ = model.stiffness_n_per_m * length_m_;
    d_ = model.StateSize();
  }

  PeriodMap MapAt(double p) const {
    return which_ == ContinuationParameter::kFrequencyHz ? PeriodMap(model_, p, fixed_) : PeriodMap(model_, fixed_, p);
  }
  Vec ToScaled(double p, State y) const {
    return {y.x_m / length_m_, y.v_m_per_s / speed_m_per_s_, d_ > 2 ? y.coil_force_n / force_n_ : 0.0, p / p_ref_};
  }
  State StateOf(const Vec& u) const { return {u.x * length_m_, u.v * speed_m_per_s_, u.e * force_n_}; }
  double ParameterOf(const Vec& u) const { return u.p * p_ref_; }

  // Solves [G'(u); t^T] step = -[G(u); constraint]: Cramer's rule for d = 2, LU otherwise.
  std::optional<Vec> NewtonStep(const Evaluation& e, Vec tangent, double constraint) const {
    if (d_ == 2) {
      const double a[3][3] = {{e.jacobian[0][0], e.jacobian[0][1], e.jacobian[0][2]},
                              {e.jacobian[1][0], e.jacobian[1][1], e.jacobian[1][2]},
                              {tangent.x, tangent.v, tangent.p}};
      const double r[3] = {-e.g[0], -e.g[1], -constraint};
      double d[3];
      if (!Solve3(a, r, d)) return std::nullopt;
      return Vec{d[0], d[1], 0.0, d[2]};
    }
    Eigen::Matrix4d a;
    Eigen::Vector4d r;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 4; ++j) a(i, j) = e.jacobian[i][j];
      r(i) = -e.g[i];
    }
    for (int j = 0; j < 4; ++j) a(3, j) = tangent(j, 3);
    r(3) = -constraint;
    const Eigen::FullPivLU<Eigen::Matrix4d> lu(a);
    if (!lu.isInvertible()) return std::nullopt;
    const Eigen::Vector4d step = lu.solve(r);
    if (!step.allFinite()) return std::nullopt;
    return Vec{step(0), step(1), step(2), step(3)};
  }

  // G and its Jacobian (PeriodMap::Linearize): the orbit's contact count and monodromy come with
  // them; its extrema and harmonics are not traced (SolutionsAt's points carry those).
  Evaluation Evaluate(const Vec& u) const {
    const double p = ParameterOf(u);
    const State y = StateOf(u);
    Evaluation e;
    const PeriodMap map = MapAt(p);
    const DriveParameter drive =
        which_ == ContinuationParameter::kFrequencyHz ? DriveParameter::kFrequencyHz : DriveParameter::kAmplitudeV;
    e.figures = map.Linearize(y, 1, drive);
    const StateMatrix& m = e.figures.monodromy;
    e.d = d_;
    const double scale[] = {length_m_, speed_m_per_s_, force_n_};
    const double end[] = {e.figures.end.x_m, e.figures.end.v_m_per_s, e.figures.end.coil_force_n};
    const double start[] = {y.x_m, y.v_m_per_s, y.coil_force_n};
    const double drive_rate[] = {e.figures.d_end_d_drive.x_m, e.figures.d_end_d_drive.v_m_per_s,
                                 e.figures.d_end_d_drive.coil_force_n};
    for (int i = 0; i < d_; ++i) {
      e.g[i] = (end[i] - start[i]) / scale[i];
      for (int j = 0; j < d_; ++j) e.jacobian[i][j] = i == j ? m(i, i) - 1.0 : m(i, j) * scale[j] / scale[i];
      // dG/d(p / p_ref) from the map's own drive derivative (PeriodMap::Trace).
      e.jacobian[i][d_] = drive_rate[i] * p_ref_ / scale[i];
    }
    return e;
  }

  struct Corrected {
    Vec u;
    Evaluation evaluation;
    int iterations;
  };
  // Newton on [G(u); t . (u - u_pred)] = 0. The point is the orbit of the linearization it converged
  // on: nothing reads a branch point's extrema or harmonics, so it is not traced again for them.
  std::optional<Corrected> Correct(const Vec& predicted, const Vec& tangent, const ContinuationOptions& o) const {
    Vec u = predicted;
    for (int iteration = 0; iteration <= o.max_corrector_iterations; ++iteration) {
      // Newton may wander out of the physical range (a frequency <= 0): treat that as a failure.
      const double p = ParameterOf(u);
      if (!std::isfinite(p) || !std::isfinite(u.x) || !std::isfinite(u.v) || !std::isfinite(u.e) || p <= 0.0)
        return std::nullopt;
      Evaluation e = Evaluate(u);
      const double residual = e.Residual();
      if (!std::isfinite(residual)) return std::nullopt;
      const double constraint = tangent.Dot(u - predicted);
      if (residual < o.tolerance && std::abs(constraint) < 1e-9) return Corrected{u, e, iteration};
      const std::optional<Vec> step = NewtonStep(e, tangent, constraint);
      if (!step) return std::nullopt;
      u = u + *step;
    }
    return std::nullopt;
  }

  BranchPoint MakePoint(const Vec& u, const Evaluation& e, const Vec& tangent, double arclength) const {
    BranchPoint point;
    point.parameter = ParameterOf(u);
    point.start = StateOf(u);
    point.figures = e.figures;
    point.multipliers = Eigenvalues(e.figures.monodromy);
    point.stable = point.MaxMultiplier() < 1.0;
    point.dparameter_ds = tangent.p;
    point.arclength = arclength;
    return point;
  }

  const ActuatorModel& model() const { return model_; }
  double p_ref() const { return p_ref_; }

 private:
  const ActuatorModel& model_;
  ContinuationParameter which_;
  double fixed_, p_ref_;
  double length_m_, speed_m_per_s_, force_n_;  // the scales of x, v and F_e
  int d_ = 2;                                  // the state's size
};

// A point on the branch between two accepted points, at arclength s from `from` along its tangent.
struct SegmentProbe {
  const BranchProblem& problem;
  Vec from, tangent;
  const ContinuationOptions& options;
  std::optional<BranchProblem::Corrected> At(double s) const {
    return problem.Correct(from + tangent * s, tangent, options);
  }
};

// Locates where `phi` (evaluated on corrected points) changes sign between s = 0 and s = s_end by
// the Illinois variant of regula falsi (illinois.h; bisection where a corrector fails), until the
// corrected points on either side of it lie within 1e-10 relative in the parameter (the points'
// own parameters: next to a grazing corner they move far more or less than the tangent's share of s).
// Returns the corrected point found last on the far side of the sign change.
template <class Phi>
std::optional<BranchProblem::Corrected> LocateOnSegment(const SegmentProbe& probe, double s_end, double phi_at_0,
                                                        double phi_at_end, Phi&& phi) {
  IllinoisBracket bracket{0.0, s_end, phi_at_0, phi_at_end};  // b: the far side
  std::optional<BranchProblem::Corrected> best;
  double near_p = probe.from.p;  // scaled, as the corrected points' u.p
  for (int iteration = 0; iteration < 60; ++iteration) {
    const double s = bracket.Next();
    const auto c = probe.At(s);
    if (!c) {
      // No point on the branch there: shrink toward the near end by bisection.
      bracket.b = 0.5 * (bracket.a + bracket.b);
      continue;
    }
    const double f = phi(*c);
    if (bracket.OnSideOfB(f)) {
      best = c;
    } else {
      near_p = c->u.p;
    }
    bracket.Update(s, f);
    if (f == 0.0 || (best && std::abs(best->u.p - near_p) <= 1e-10 * std::abs(near_p))) break;
  }
  if (!best) best = probe.At(bracket.b);
  return best;
}

bool PeriodDoublingLike(const BranchPoint& unstable) {
  for (const auto& mu : unstable.multipliers)
    if (mu.real() < -1.0 && std::abs(mu.imag()) < 1e-9) return true;
  return false;
}

// Where continuation stalls next to a grazing point: the grazing point itself and the first orbit
// past it on the other leg (the one with the other contact state), tried in the direction of
// travel first (a smooth passage) and then back (a corner). None where the grazing point found lies
// farther from the stall than `reach` (scaled): the stall has another cause (a fold the corrector
// could not round), and a restart there would jump onto another branch and report a grazing point
// this branch never reaches.
struct GrazingRestart {
  BranchPoint graze, point;
  Vec u, tangent;
};

std::optional<GrazingRestart> RestartPastGrazing(const ActuatorModel& model, ContinuationParameter which,
                                                 double fixed_value, const BranchProblem& problem,
                                                 const BranchPoint& last, const Vec& travel, double reach) {
  const std::optional<BranchPoint> graze = LocateGrazing(model, which, fixed_value, last);
  if (!graze) return std::nullopt;
  const double direction = travel.p >= 0 ? 1.0 : -1.0;
  const Vec at_graze = problem.ToScaled(graze->parameter, graze->start);
  if ((at_graze - problem.ToScaled(last.parameter, last.start)).Norm() > reach) return std::nullopt;
  for (double sign : {direction, -direction}) {
    for (double offset : {1e-6, 1e-5, 1e-4}) {
      const double p = graze->parameter * (1.0 + sign * offset);
      const std::optional<BranchPoint> orbit = SolveAt(model, which, fixed_value, p, graze->start);
      if (!orbit || orbit->contacting() == last.contacting()) continue;
      GrazingRestart restart;
      restart.graze = *graze;
      restart.u = problem.ToScaled(p, orbit->start);
      const Evaluation e = problem.Evaluate(restart.u);
      restart.tangent = e.Tangent();
      if (restart.tangent.Dot(restart.u - at_graze) < 0) restart.tangent = restart.tangent * -1.0;
      restart.point = problem.MakePoint(restart.u, e, restart.tangent, 0.0);
      return restart;
    }
  }
  return std::nullopt;
}

}  // namespace

double BranchPoint::MaxMultiplier() const {
  double largest = 0.0;
  for (const auto& mu : multipliers) largest = std::max(largest, std::abs(mu));
  return largest;
}

const char* ToString(BranchEvent::Kind kind) {
  switch (kind) {
    case BranchEvent::Kind::kFold: return "fold";
    case BranchEvent::Kind::kGrazing: return "grazing";
    case BranchEvent::Kind::kStabilityChange: return "stability-change";
  }
  return "?";
}

std::optional<BranchPoint> SolveAt(const ActuatorModel& model, ContinuationParameter which, double fixed_value,
                                   double p, State guess, const ShootingOptions& options) {
  const PeriodMap map = which == ContinuationParameter::kFrequencyHz ? PeriodMap(model, p, fixed_value)
                                                                     : PeriodMap(model, fixed_value, p);
  const std::optional<SteadyState> orbit = Shoot(map, guess, 1, options);
  if (!orbit) return std::nullopt;
  BranchPoint point;
  point.parameter = p;
  point.start = orbit->start;
  point.figures = orbit->figures;
  point.multipliers = orbit->multipliers;
  point.stable = orbit->stable;
  return point;
}

std::optional<FieldError> ContinuationOptions::IsValid() const {
  if (!(min_step > 0) || !std::isfinite(min_step)) return FieldError{"min_step", "must be a finite number > 0"};
  if (!(max_step >= min_step) || !std::isfinite(max_step)) return FieldError{"max_step", "must be finite and >= min_step"};
  if (!(initial_step >= min_step && initial_step <= max_step))
    return FieldError{"initial_step", "must lie between min_step and max_step"};
  if (max_points < 1) return FieldError{"max_points", "must be >= 1"};
  if (max_corrector_iterations < 1) return FieldError{"max_corrector_iterations", "must be >= 1"};
  if (!(tolerance > 0) || !std::isfinite(tolerance)) return FieldError{"tolerance", "must be a finite number > 0"};
  return std::nullopt;
}

ContinuedBranch ContinueBranch(const ActuatorModel& model, ContinuationParameter which, double fixed_value, double p0,
                               State start, double p_min, double p_max, bool increasing,
                               const ContinuationOptions& options, const std::atomic<bool>* cancel) {
  Validate(options);
  ContinuedBranch branch;
  branch.parameter = which;
  branch.fixed_value = fixed_value;
  const BranchProblem problem(model, which, fixed_value, p0);

  Vec u = problem.ToScaled(p0, start);
  Evaluation e = problem.Evaluate(u);
  Vec t = e.Tangent();
  if ((t.p > 0) != increasing) t = t * -1.0;
  double arclength = 0.0;
  branch.points.push_back(problem.MakePoint(u, e, t, arclength));

  double h = options.initial_step;
  bool restarted_here = false;
  while (static_cast<int>(branch.points.size()) < options.max_points) {
    if (cancel && cancel->load()) {
      branch.stopped_because = "cancelled";
      return branch;
    }
    const std::optional<BranchProblem::Corrected> c = problem.Correct(u + t * h, t, options);
    const BranchPoint& last = branch.points.back();
    // Reject a corrector that failed or wandered far from the predictor (a jump to another branch).
    bool accepted = c && (c->u - u).Norm() <= 3.0 * h;
    Vec t_new;
    std::optional<BranchPoint> graze;
    if (accepted) {
      // Orient the new tangent along the secant: at a grazing corner the branch can turn by more
      // than a right angle, where "same direction as the old tangent" would send it back.
      t_new = c->evaluation.Tangent();
      if (t_new.Dot(c->u - u) < 0) t_new = t_new * -1.0;
      const bool contact_change = last.contacting() != (c->evaluation.figures.contacts > 0);
      if (!contact_change) {
        // A sharp turn of the tangent: a fold taken in too long a stride; look closer (down to a
        // stride of 1e-3, below which a turn is a non-smooth kink, e.g. a second impact grazing).
        if (t_new.Dot(t) < 0.9 && h > 1e-3) accepted = false;
      } else {
        // Across a grazing point the step must pass near it; otherwise it skipped a stretch of
        // branch (a fold and its unstable side) and landed on another leg.
        const BranchPoint noncontacting_side =
            last.contacting() ? problem.MakePoint(c->u, c->evaluation, t_new, 0.0) : last;
        graze = LocateGrazing(model, which, fixed_value, noncontacting_side);
        if (graze) {
          const Vec g = problem.ToScaled(graze->parameter, graze->start);
          const double detour = (g - u).Norm() + (c->u - g).Norm();
          if (detour > 2.0 * (c->u - u).Norm() + 1e-9 && h > 1e-3) accepted = false;
          // Nor may the grazing point lie farther from either end than the ends from each other:
          // such a step leapt over a fold (and the unstable stretch after it) onto the other leg.
          const double chord = (c->u - u).Norm();
          if (((g - u).Norm() > chord || (c->u - g).Norm() > chord) && h > 1e-3) accepted = false;
        }
      }
    }
    if (!accepted) {
      h *= 0.5;
      if (h < options.min_step) {
        // Newton can lose its footing next to a grazing point, where the map is not smooth:
        // restart on the other side of it.
        if (!restarted_here) {
          const double reach = 2.0 * options.max_step;
          if (auto restart = RestartPastGrazing(model, which, fixed_value, problem, last, t, reach)) {
            restarted_here = true;
            branch.events.push_back({BranchEvent::Kind::kGrazing, branch.points.size() - 1, restart->graze, false});
            restart->point.arclength = arclength + (restart->u - u).Norm();
            arclength = restart->point.arclength;
            branch.points.push_back(restart->point);
            u = restart->u;
            t = restart->tangent;
            h = options.initial_step;
            continue;
          }
        }
        branch.stopped_because = "corrector failed at p = " + std::to_string(problem.ParameterOf(u));
        return branch;
      }
      continue;
    }
    restarted_here = false;
    const double step = (c->u - u).Norm();
    BranchPoint next = problem.MakePoint(c->u, c->evaluation, t_new, arclength + step);
    const BranchPoint previous = branch.points.back();

    if (options.locate_events) {
      const SegmentProbe probe{problem, u, t, options};
      const double s_end = t.Dot(c->u - u);
      auto add_event = [&](BranchEvent::Kind kind, double phi0, double phi1, auto phi) {
        const auto located = LocateOnSegment(probe, s_end, phi0, phi1, phi);
        if (!located) return;
        BranchEvent event{kind, branch.points.size() - 1, {}, false};
        Vec tangent = located->evaluation.Tangent();
        if (tangent.Dot(t) < 0) tangent = tangent * -1.0;
        event.point = problem.MakePoint(located->u, located->evaluation, tangent, arclength + (located->u - u).Norm());
        if (kind == BranchEvent::Kind::kStabilityChange)
          event.period_doubling = PeriodDoublingLike(previous.stable ? next : previous);
        branch.events.push_back(event);
      };
      if (graze) {
        // A grazing point explains any turn or change of stability in this segment (a corner).
        branch.events.push_back({BranchEvent::Kind::kGrazing, branch.points.size() - 1, *graze, false});
        if (previous.stable != next.stable)
          branch.events.push_back({BranchEvent::Kind::kStabilityChange, branch.points.size() - 1, *graze, false});
        // Travel away from the grazing point along the leg just reached.
        const Vec from_corner = c->u - problem.ToScaled(graze->parameter, graze->start);
        if (t_new.Dot(from_corner) < 0) t_new = t_new * -1.0;
        next.dparameter_ds = t_new.p;
      } else {
        const bool fold = (previous.dparameter_ds > 0) != (next.dparameter_ds > 0);
        if (fold) {
          add_event(BranchEvent::Kind::kFold, previous.dparameter_ds, next.dparameter_ds,
                    [&](const BranchProblem::Corrected& k) {
                      Vec tk = k.evaluation.Tangent();
                      if (tk.Dot(t) < 0) tk = tk * -1.0;
                      return tk.p;
                    });
        }
        if (previous.stable != next.stable) {
          const bool doubling = PeriodDoublingLike(previous.stable ? next : previous);
          if (fold && !doubling && !branch.events.empty() && branch.events.back().kind == BranchEvent::Kind::kFold &&
              branch.events.back().after + 1 == branch.points.size()) {
            // A multiplier through +1 at a fold: the same point.
            BranchEvent event = branch.events.back();
            event.kind = BranchEvent::Kind::kStabilityChange;
            branch.events.push_back(event);
          } else {
            add_event(BranchEvent::Kind::kStabilityChange, previous.MaxMultiplier() - 1.0, next.MaxMultiplier() - 1.0,
                      [&](const BranchProblem::Corrected& k) {
                        double largest = 0.0;
                        for (const auto& mu : Eigenvalues(k.evaluation.figures.monodromy))
                          largest = std::max(largest, std::abs(mu));
                        return largest - 1.0;
                      });
          }
        }
      }
    }
    if (options.stop_at_first_event) {
      // Terminal: a fold or grazing point, or a loss of stability not through period doubling.
      for (const BranchEvent& e : branch.events) {
        if (e.after + 1 != branch.points.size()) continue;
        const bool lost = e.kind == BranchEvent::Kind::kStabilityChange && !e.period_doubling && previous.stable;
        if (e.kind == BranchEvent::Kind::kStabilityChange && !lost) continue;
        branch.points.push_back(next);
        branch.stopped_because = std::string("event: ") + ToString(e.kind);
        return branch;
      }
    }
    branch.points.push_back(next);
    arclength += step;
    u = c->u;
    t = t_new;
    h = c->iterations <= 3 ? std::min(options.max_step, h * 1.5) : (c->iterations > 5 ? h * 0.6 : h);
    const double p = next.parameter;
    if (options.on_point) options.on_point(p);
    if (p > p_max || p < p_min) {
      branch.stopped_because = "range";
      return branch;
    }
  }
  branch.stopped_because = "max_points";
  return branch;
}

// The grazing point of the non-contacting family next to `noncontacting`: where the orbit of the
// model without stops first touches a stop. That family is smooth in the parameter, so the
// clearance is located by secant steps and Illinois regula falsi to 1e-12 relative.
std::optional<BranchPoint> LocateGrazing(const ActuatorModel& model, ContinuationParameter which, double fixed_value,
                                         const BranchPoint& noncontacting) {
  ActuatorModel free_model = model;
  free_model.lower_stop_m = ActuatorModel::kNoLowerStop;
  free_model.upper_stop_m = ActuatorModel::kNoUpperStop;
  State guess = noncontacting.start;
  auto clearance = [&](double p) -> std::optional<double> {
    if (!(p > 0.0)) return std::nullopt;
    const std::optional<BranchPoint> orbit = SolveAt(free_model, which, fixed_value, p, guess);
    if (!orbit) return std::nullopt;
    guess = orbit->start;
    return StopClearanceM(model, orbit->figures);
  };
  const double p0 = noncontacting.parameter;
  const std::optional<double> c0 = clearance(p0);
  const double dp = 1e-6 * p0;
  const std::optional<double> c1 = clearance(p0 + dp);
  if (!c0 || !c1 || *c1 == *c0) return std::nullopt;
  // Secant steps toward the root until the clearance changes sign (from either side: the free
  // orbit may already reach into the stop at p0).
  const bool positive = *c0 > 0.0;
  double pa = p0, ca = *c0, slope = (*c1 - *c0) / dp, pb = p0, cb = ca;
  for (int i = 0; i < 40 && (cb > 0.0) == positive; ++i) {
    pb = pa - 1.5 * ca / slope;
    const std::optional<double> c = clearance(pb);
    if (!c) return std::nullopt;
    cb = *c;
    if ((cb > 0.0) == positive) {
      slope = (cb - ca) / (pb - pa);
      pa = pb;
      ca = cb;
    }
  }
  if ((cb > 0.0) == positive) return std::nullopt;
  IllinoisBracket bracket{pa, pb, ca, cb};
  for (int i = 0; i < 200 && bracket.Width() > 1e-12 * std::abs(bracket.a); ++i) {
    const double p = bracket.Next();
    const std::optional<double> c = clearance(p);
    if (!c) return std::nullopt;
    bracket.Update(p, *c);
    if (*c == 0.0) break;
  }
  const double p_graze = bracket.gb == 0.0 ? bracket.b : 0.5 * (bracket.a + bracket.b);
  std::optional<BranchPoint> point = SolveAt(free_model, which, fixed_value, p_graze, guess);
  if (point && noncontacting.figures.contacts == 0) point->stable = noncontacting.stable;
  return point;
}

namespace {

// The branch's points in order along it, with its grazing points put in between: at a grazing
// corner one step cuts across from one leg to the other, and the stretches of both legs that the
// chord skips lie on either side of the grazing point.
// (Pointers into the branch: SolutionsAt runs once per grid value, and copying the branch each time
// was 7 % of a sweep.)
struct CornerPoint {
  const BranchPoint* point;
  bool graze;
  double arclength;  // a grazing point's is that of the step it interrupts
};
std::vector<CornerPoint> WithGrazingCorners(const ContinuedBranch& branch) {
  std::vector<CornerPoint> points;
  points.reserve(branch.points.size() + branch.events.size());
  size_t next_event = 0;
  for (size_t k = 0; k < branch.points.size(); ++k) {
    points.push_back({&branch.points[k], false, branch.points[k].arclength});
    for (; next_event < branch.events.size() && branch.events[next_event].after <= k; ++next_event) {
      const BranchEvent& e = branch.events[next_event];
      if (e.after == k && e.kind == BranchEvent::Kind::kGrazing && k + 1 < branch.points.size())
        points.push_back({&e.point, true, branch.points[k].arclength});
    }
  }
  return points;
}

}  // namespace

std::vector<BranchPoint> SolutionsAt(const ActuatorModel& model, const ContinuedBranch& branch, double p) {
  std::vector<BranchPoint> solutions;
  const std::vector<CornerPoint> corners = WithGrazingCorners(branch);
  for (size_t k = 0; k + 1 < corners.size(); ++k) {
    const BranchPoint* pts[2] = {corners[k].point, corners[k + 1].point};
    const double a = pts[0]->parameter - p, b = pts[1]->parameter - p;
    // Half-open crossings, so that a grid value equal to a branch point counts once.
    if (!((a <= 0 && b > 0) || (a >= 0 && b < 0))) continue;
    // Next to a corner, the orbit found must be on this stretch's side of it: that of its end other
    // than the grazing point (a grazing orbit just touches; its figures are the free model's).
    const bool corner = corners[k].graze || corners[k + 1].graze;
    const bool contacting = (corners[k].graze ? pts[1] : pts[0])->contacting();
    const double w = a == b ? 0.0 : a / (a - b);
    const State guess{pts[0]->start.x_m + w * (pts[1]->start.x_m - pts[0]->start.x_m),
                      pts[0]->start.v_m_per_s + w * (pts[1]->start.v_m_per_s - pts[0]->start.v_m_per_s)};
    std::optional<BranchPoint> s = SolveAt(model, branch.parameter, branch.fixed_value, p, guess);
    // Newton must land on this stretch of the branch, not on another branch at the same p.
    const double span = std::hypot(pts[1]->start.x_m - pts[0]->start.x_m,
                                   (pts[1]->start.v_m_per_s - pts[0]->start.v_m_per_s) /
                                       (2 * std::numbers::pi * std::max(1.0, p)));
    const double miss = s ? std::hypot(s->start.x_m - guess.x_m,
                                       (s->start.v_m_per_s - guess.v_m_per_s) / (2 * std::numbers::pi * std::max(1.0, p)))
                          : INFINITY;
    if (!s || miss > 2.0 * span + 1e-9 * LengthScaleM(model) || (corner && s->contacting() != contacting)) {
      // Fall back on the arclength: bisection for the parameter value along the segment.
      const BranchProblem problem(model, branch.parameter, branch.fixed_value, pts[0]->parameter);
      const ContinuationOptions options;
      const Vec u0 = problem.ToScaled(pts[0]->parameter, pts[0]->start);
      const Vec u1 = problem.ToScaled(pts[1]->parameter, pts[1]->start);
      const Vec direction = (u1 - u0) * (1.0 / (u1 - u0).Norm());
      const SegmentProbe probe{problem, u0, direction, options};
      const auto located = LocateOnSegment(probe, (u1 - u0).Norm(), a, b, [&](const BranchProblem::Corrected& c) {
        return problem.ParameterOf(c.u) - p;
      });
      if (!located) continue;
      s = SolveAt(model, branch.parameter, branch.fixed_value, p, problem.StateOf(located->u));
      if (!s || (corner && s->contacting() != contacting)) continue;
    }
    s->arclength = corners[k].arclength + w * (corners[k + 1].arclength - corners[k].arclength);
    s->dparameter_ds = pts[0]->dparameter_ds;
    solutions.push_back(*s);
  }
  return solutions;
}

}  // namespace strokelab
