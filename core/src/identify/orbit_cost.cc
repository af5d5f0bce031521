// The stepped-sine records' residuals (orbit_cost.h).
#include "orbit_cost.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <optional>

#include "strokelab/base/parallel_for.h"
#include "strokelab/steady/steady_state.h"

namespace strokelab::internal {
namespace {

using Complex = std::complex<double>;
constexpr int kAperiodicSettlePeriods = 64;  // plain periods before harmonics of an aperiodic anchor
const std::vector<double ActuatorModel::*> kNoFields;

}  // namespace

OrbitCost::OrbitCost(const ExtendedProblem* problem, const OrbitTarget* target, ResponseKind kind, int orders)
    : problem_(problem), target_(target), kind_(kind), orders_(orders) {
  set_num_residuals(2 * orders);
  mutable_parameter_block_sizes()->push_back(static_cast<int>(problem->parameters.size()));
  for (const FreeParameter& p : problem->parameters) fields_.push_back(p.field);
}

bool OrbitCost::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  const double* theta = parameters[0];
  try {
    const ActuatorModel model = problem_->Decode(theta);
    const RecordAnalysis& record = *target_->record;
    // The orbit near the anchor: Newton on its period; an aperiodic anchor is settled further.
    // Ceres evaluates an accepted step twice, residuals alone and then with the Jacobian: the
    // second reuses the first's orbit (a third of the cost's periods).
    const int period = target_->anchor.period;
    State start = target_->anchor.start;
    const bool same = !last_theta_.empty() && std::equal(last_theta_.begin(), last_theta_.end(), theta) &&
                      last_anchor_.start.x_m == start.x_m && last_anchor_.start.v_m_per_s == start.v_m_per_s &&
                      last_anchor_.start.coil_force_n == start.coil_force_n && last_anchor_.period == period;
    if (!same) {
      const PeriodMap map(model, record.drive.frequency_hz, record.drive.amplitude_v);
      if (period > 0) {
        const std::optional<SteadyState> orbit = Shoot(map, start, period);
        if (!orbit) return false;  // Ceres rejects the step
        start = orbit->start;
      } else {
        for (int i = 0; i < kAperiodicSettlePeriods; ++i) start = map.Apply(start);
      }
      last_theta_.assign(theta, theta + fields_.size());
      last_anchor_ = target_->anchor;
      last_start_ = start;
    } else {
      start = last_start_;
    }
    // Ceres asks for residuals alone at trial steps: then the harmonics without their slopes.
    const bool jacobian = jacobians != nullptr && jacobians[0] != nullptr;
    const OrbitSlopes slopes =
        OrbitHarmonicSlopes(model, record, start, period, kind_, orders_, jacobian ? fields_ : kNoFields);
    const size_t p = fields_.size();
    for (int h = 0; h < orders_; ++h) {
      const double weight = record.usable[h] ? target_->weight : 0.0;
      const Complex r = weight * (record.harmonics[h] - slopes.harmonics[h] - target_->correction[h]);
      residuals[2 * h] = r.real();
      residuals[2 * h + 1] = r.imag();
      if (!jacobian) continue;
      for (size_t j = 0; j < p; ++j) {
        const Complex d = -weight * slopes.d_harmonics[j][h] * problem_->parameters[j].ValuePerTheta(theta[j]);
        jacobians[0][(2 * h) * p + j] = d.real();
        jacobians[0][(2 * h + 1) * p + j] = d.imag();
      }
    }
    for (int i = 0; i < 2 * orders_; ++i)
      if (!std::isfinite(residuals[i])) return false;
    return true;
  } catch (const std::exception&) {
    return false;  // a model the engines refuse: Ceres rejects the step
  }
}

void RefreshCorrections(const ActuatorModel& model, std::span<OrbitTarget> targets, ResponseKind kind, int orders) {
  ParallelFor(targets.size(), [&](size_t i) {
    OrbitTarget& t = targets[i];
    SampledCorrection sampled;
    try {
      if (const std::optional<ModelOrbit> orbit =
              SolveOrbit(model, *t.record, t.anchor, kind, orders, OrbitSearch::kNearby))
        sampled = SamplingCorrection(model, *t.record, *orbit, kind, orders);
    } catch (const std::exception&) {
      sampled = SampledCorrection{};
    }
    if (sampled.harmonics.empty()) sampled.harmonics.assign(orders, 0.0);
    t.correction = std::move(sampled.harmonics);
  });
}

}  // namespace strokelab::internal
