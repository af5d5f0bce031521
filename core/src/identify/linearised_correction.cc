// The sampling correction linearised in the fit's parameters (linearised_correction.h).
#include "linearised_correction.h"

#include <exception>
#include <optional>

namespace strokelab::internal {
namespace {

using Complex = std::complex<double>;
// Central-difference step in theta: 1e-4 moves a contact by about 1e-3 of a sample at 44.1 kHz (k_s's
// relative change times a contact of ~20 samples), small against the sample interval over which the
// correction's slope changes and far above the orbit's accuracy (shooting to 1e-11 of |d|). Forward
// differences were tried: on 9706 they left k_s 8 standard errors off and g's standard error a fifth
// of the central differences' (the correction is not smooth enough at that step for them).
constexpr double kStep = 1e-4;

// The correction on the model's orbit through `anchor`, and the orbit's contacts per period.
std::optional<SampledCorrection> CorrectionAt(const ActuatorModel& model, const RecordAnalysis& record,
                                              const Anchor& anchor, ResponseKind kind, int orders,
                                              double* contacts_per_period = nullptr) {
  try {
    const std::optional<ModelOrbit> orbit = SolveOrbit(model, record, anchor, kind, orders, OrbitSearch::kNearby);
    if (!orbit) return std::nullopt;
    if (contacts_per_period) *contacts_per_period = orbit->contacts_per_period;
    SampledCorrection c = SamplingCorrection(model, record, *orbit, kind, orders);
    if (static_cast<int>(c.harmonics.size()) != orders) return std::nullopt;
    return c;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

}  // namespace

Complex LinearisedCorrection::At(int h, const double* theta) const {
  Complex c = at[h];
  for (size_t j = 0; j < slopes.size(); ++j) c += slopes[j][h] * (theta[j] - theta0[j]);
  return c;
}

LinearisedCorrection LineariseCorrection(const std::function<ActuatorModel(const double*)>& decode,
                                         std::span<const double> theta, const RecordAnalysis& record,
                                         const Anchor& anchor, ResponseKind kind, int orders, bool with_slopes) {
  LinearisedCorrection out;
  out.theta0.assign(theta.begin(), theta.end());
  double contacts = 0.0;
  const std::optional<SampledCorrection> at =
      CorrectionAt(decode(theta.data()), record, anchor, kind, orders, &contacts);
  out.at = at ? at->harmonics : std::vector<Complex>(orders, 0.0);
  if (!with_slopes || !at || !(contacts > 0.0)) return out;
  out.slopes.assign(theta.size(), std::vector<Complex>(orders, 0.0));
  std::vector<double> moved = out.theta0;
  for (size_t j = 0; j < theta.size(); ++j) {
    moved[j] = theta[j] + kStep;
    const std::optional<SampledCorrection> above = CorrectionAt(decode(moved.data()), record, anchor, kind, orders);
    moved[j] = theta[j] - kStep;
    const std::optional<SampledCorrection> below = CorrectionAt(decode(moved.data()), record, anchor, kind, orders);
    moved[j] = theta[j];
    if (!above || !below) continue;
    for (int h = 0; h < orders; ++h) out.slopes[j][h] = (above->harmonics[h] - below->harmonics[h]) / (2.0 * kStep);
  }
  return out;
}

}  // namespace strokelab::internal
