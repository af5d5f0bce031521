// The named effects' curves (effect_curves.h): each law against its closed form, and each band (the
// delta method over the fit's covariance) against a second method, the spread of the curve over
// parameter values drawn from that covariance (Monte Carlo).
#include "strokelab/diagnose/effect_curves.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace strokelab {
namespace {

// A fitted parameter by its reported name, and the model field it sets.
struct Field {
  const char* name;
  double ActuatorModel::*member;
  double relative_se;
};
const std::vector<Field>& Fields() {
  static const std::vector<Field> fields = {
      {"k_p", &ActuatorModel::stiffness_n_per_m, 0.01},
      {"c_p", &ActuatorModel::damping_n_s_per_m, 0.03},
      {"g", &ActuatorModel::gain_n_per_v, 0.01},
      {"k_s", &ActuatorModel::contact_stiffness, 0.05},
      {"c_s", &ActuatorModel::contact_damping_n_s_per_m, 0.1},
      {"k3", &ActuatorModel::cubic_stiffness_n_per_m3, 0.02},
      {"k2", &ActuatorModel::quadratic_stiffness_n_per_m2, 0.05},
      {"friction_n", &ActuatorModel::friction_force_n, 0.03},
      {"c2", &ActuatorModel::quadratic_damping_n_s2_per_m2, 0.04},
      {"b1", &ActuatorModel::force_factor_b1_per_m, 0.05},
      {"b2", &ActuatorModel::force_factor_b2_per_m2, 0.02},
      {"d_upper", &ActuatorModel::upper_stop_m, 0.02},
      {"amplifier_limit_v", &ActuatorModel::amplifier_limit_v, 0.02},
      {"tau_e", &ActuatorModel::coil_time_constant_s, 0.1},
  };
  return fields;
}

// The paper's model carrying every effect, with a fit whose covariance has the standard errors of
// Fields() and correlations -0.4 between neighbouring parameters (positive definite: a chain of
// correlations rho is so for |rho| < 1/2).
CandidateFit FittedWith(std::vector<Effect> effects, ContactLaw law) {
  CandidateFit fit;
  fit.effects = std::move(effects);
  ActuatorModel& m = fit.model;
  m = PaperModel();
  m.contact_law = law;
  m.contact_stiffness = law == ContactLaw::kHertzian ? 2.65e8 : 1.3e6;
  m.contact_damping_n_s_per_m = 2.0;
  m.cubic_stiffness_n_per_m3 = 3e7;
  m.quadratic_stiffness_n_per_m2 = -2e4;
  m.friction_force_n = 0.02;
  m.quadratic_damping_n_s2_per_m2 = 0.3;
  m.force_factor_b1_per_m = -10.0;
  m.force_factor_b2_per_m2 = -5e4;
  m.upper_stop_m = 0.6e-3;
  m.amplifier_limit_v = 0.4;
  m.coil_time_constant_s = 2e-3 / 3.0;
  const size_t p = Fields().size();
  std::vector<double> se(p);
  for (size_t i = 0; i < p; ++i) {
    const Field& f = Fields()[i];
    fit.parameters.push_back({f.name, "", m.*f.member, 0.0, false, true, ""});
    se[i] = f.relative_se * std::abs(m.*f.member);
  }
  fit.covariance.assign(p * p, 0.0);
  for (size_t i = 0; i < p; ++i) {
    fit.covariance[i * p + i] = se[i] * se[i];
    if (i + 1 < p) fit.covariance[i * p + i + 1] = fit.covariance[(i + 1) * p + i] = -0.4 * se[i] * se[i + 1];
  }
  return fit;
}

CurveRanges Ranges() { return {-1.1e-3, 1.0e-3, 0.12, 2e-5, 0.6, 5.0, 240.0, "test ranges"}; }

// The curves of `fit.model` with parameters drawn from N(values, covariance): per curve and point,
// the sample standard deviation of y.
std::vector<std::vector<double>> MonteCarloSpread(const CandidateFit& fit, int samples) {
  const size_t p = fit.parameters.size();
  Eigen::MatrixXd c(p, p);
  for (size_t i = 0; i < p; ++i)
    for (size_t j = 0; j < p; ++j) c(i, j) = fit.covariance[i * p + j];
  const Eigen::LLT<Eigen::MatrixXd> llt(c);
  EXPECT_EQ(llt.info(), Eigen::Success) << "the covariance must be positive definite";
  const Eigen::MatrixXd l = llt.matrixL();
  std::mt19937_64 rng(20261126);
  std::normal_distribution<double> normal;
  // Welford's running mean and sum of squared deviations, per curve and point.
  std::vector<std::vector<double>> mean, squares;
  for (int s = 1; s <= samples; ++s) {
    Eigen::VectorXd z(p);
    for (size_t i = 0; i < p; ++i) z(i) = normal(rng);
    const Eigen::VectorXd delta = l * z;
    CandidateFit drawn = fit;
    drawn.covariance.clear();
    for (size_t i = 0; i < p; ++i) drawn.model.*Fields()[i].member += delta(i);
    const std::vector<EffectCurve> curves = EffectCurves(drawn, fit.model, Ranges());
    if (mean.empty())
      for (const EffectCurve& curve : curves) mean.emplace_back(curve.y.size(), 0.0), squares.emplace_back(curve.y.size(), 0.0);
    for (size_t k = 0; k < curves.size(); ++k)
      for (size_t i = 0; i < curves[k].y.size(); ++i) {
        const double before = mean[k][i];
        mean[k][i] += (curves[k].y[i] - before) / s;
        squares[k][i] += (curves[k].y[i] - before) * (curves[k].y[i] - mean[k][i]);
      }
  }
  for (std::vector<double>& curve : squares)
    for (double& v : curve) v = std::sqrt(v / (samples - 1));
  return squares;
}

TEST(EffectCurves, LawsFollowTheirClosedForms) {
  const CandidateFit fit = FittedWith({Effect::kCubicStiffness, Effect::kQuadraticStiffness, Effect::kForceFactor,
                                       Effect::kQuadraticDamping, Effect::kDryFriction},
                                      ContactLaw::kLinear);
  const ActuatorModel& m = fit.model;
  ActuatorModel base = PaperModel();
  const std::vector<EffectCurve> curves = EffectCurves(fit, base, Ranges());
  ASSERT_EQ(curves.size(), 4u);  // one K(x) for the cubic and quadratic terms
  EXPECT_EQ(curves[0].id, "stiffness");
  EXPECT_EQ(curves[0].x.front(), -1.1e-3);
  EXPECT_DOUBLE_EQ(curves[0].x.back(), 1.0e-3);
  for (size_t i = 0; i < curves[0].x.size(); i += 10) {
    const double x = curves[0].x[i];
    EXPECT_NEAR(curves[0].y[i], m.stiffness_n_per_m + m.quadratic_stiffness_n_per_m2 * x + m.cubic_stiffness_n_per_m3 * x * x,
                1e-12 * m.stiffness_n_per_m);
    EXPECT_DOUBLE_EQ(curves[0].base_y[i], base.stiffness_n_per_m);
    // Linear in (k_p, k2, k3): var = C_pp + x^2 C_22 + x^4 C_33 + 2 x C_p2 + 2 x^2 C_p3 + 2 x^3 C_23.
    const size_t p = fit.parameters.size();
    const auto cov = [&](size_t a, size_t b) { return fit.covariance[a * p + b]; };
    const size_t kp = 0, k3 = 5, k2 = 6;
    const double var = cov(kp, kp) + x * x * cov(k2, k2) + std::pow(x, 4) * cov(k3, k3) + 2 * x * cov(kp, k2) +
                       2 * x * x * cov(kp, k3) + 2 * std::pow(x, 3) * cov(k2, k3);
    EXPECT_NEAR(curves[0].y_se[i], std::sqrt(var), 1e-9 * std::sqrt(var)) << x;
  }
  EXPECT_EQ(curves[1].id, "force_factor");
  const double x = curves[1].x.back();
  EXPECT_NEAR(curves[1].y.back(),
              m.gain_n_per_v * (1 + m.force_factor_b1_per_m * x + m.force_factor_b2_per_m2 * x * x), 1e-15);
  EXPECT_EQ(curves[2].id, "resistance");
  EXPECT_NEAR(curves[2].y.back(), m.damping_n_s_per_m + m.quadratic_damping_n_s2_per_m2 * 0.12, 1e-12);
  EXPECT_EQ(curves[3].id, "friction");
  EXPECT_NEAR(curves[3].y.front(), -m.friction_force_n * std::tanh(0.12 / m.friction_velocity_m_per_s), 1e-15);
  EXPECT_DOUBLE_EQ(curves[3].base_y.front(), 0.0);
  // The coil's lag atan(w tau_e), 45 degrees at its pole 1 / (2 pi tau_e) = 239 Hz, nothing without one.
  const CandidateFit coil = FittedWith({Effect::kCoilInductance}, ContactLaw::kLinear);
  const std::vector<EffectCurve> lag = EffectCurves(coil, base, Ranges());
  ASSERT_EQ(lag.size(), 1u);
  EXPECT_EQ(lag[0].id, "coil_lag");
  EXPECT_EQ(lag[0].x.front(), 5.0);
  EXPECT_NEAR(lag[0].y.back(), std::atan(2 * std::numbers::pi * 240.0 * 2e-3 / 3.0) * 180 / std::numbers::pi, 1e-12);
  EXPECT_NEAR(lag[0].y.back(), 45.0, 0.2);
  EXPECT_DOUBLE_EQ(lag[0].base_y.back(), 0.0);

  // A parameter without a standard error leaves the band of every curve that needs it unknown.
  CandidateFit unknown = fit;
  unknown.covariance[5 * fit.parameters.size() + 5] = NAN;  // k3
  EXPECT_TRUE(std::isnan(EffectCurves(unknown, base, Ranges())[0].y_se[3]));
  EXPECT_TRUE(std::isfinite(EffectCurves(unknown, base, Ranges())[2].y_se[3]));
}

// The delta method's band against the spread of the curve over parameters drawn from the covariance:
// exact for the laws linear in their parameters, to first order for the others (relative errors of
// 1-5 % here). 4000 draws estimate a standard deviation to ~1.1 %: 6 % allows 5 sigma.
TEST(EffectCurves, BandsMatchTheSpreadOverDrawnParameters) {
  for (const ContactLaw law : {ContactLaw::kLinear, ContactLaw::kHertzian}) {
    const CandidateFit fit =
        FittedWith({Effect::kCubicStiffness, Effect::kForceFactor, Effect::kQuadraticDamping, Effect::kDryFriction,
                    Effect::kHertzianContact, Effect::kContactDamping, Effect::kSecondStop, Effect::kAmplifierSaturation,
                    Effect::kCoilInductance},
                   law);
    const std::vector<EffectCurve> curves = EffectCurves(fit, PaperModel(), Ranges());
    ASSERT_EQ(curves.size(), 9u);
    const std::vector<std::vector<double>> spread = MonteCarloSpread(fit, 4000);
    for (size_t k = 0; k < curves.size(); ++k) {
      const EffectCurve& c = curves[k];
      // Laws with a kink (the upper stop's contact, the clipping) are smooth only away from it.
      const double kink = c.id == "upper_stop_force" ? fit.model.upper_stop_m
                          : c.id == "drive"          ? fit.model.amplifier_limit_v
                                                     : NAN;
      const double kink_se = 0.02 * kink;
      int compared = 0;
      for (size_t i = 0; i < c.x.size(); ++i) {
        if (std::abs(c.x[i] - kink) < 8 * kink_se) continue;
        if (!(c.y_se[i] > 0)) {
          EXPECT_LT(spread[k][i], 1e-12 * (1 + std::abs(c.y[i]))) << c.id << " at " << c.x[i];
          continue;
        }
        EXPECT_NEAR(spread[k][i], c.y_se[i], 0.06 * c.y_se[i]) << c.id << " at " << c.x[i];
        ++compared;
      }
      EXPECT_GE(compared, 10) << c.id;
    }
  }
}

}  // namespace
}  // namespace strokelab
