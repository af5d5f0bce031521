// The linear actuator's closed forms: paper Eq. 3 against the model's m, c, k form, its limits,
// H_p = -H / (m w^2), and the saturation threshold against reference values to 4 decimals.
#include "strokelab/model/linear_response.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>

#include "strokelab/base/errors.h"
#include "test_util.h"

namespace strokelab {
namespace {

using Complex = std::complex<double>;
using ::strokelab::testing::kPi;
constexpr double kClosedFormRoundingRel = 1e-14;
// The reference values of V_sat have 4 decimals.
constexpr double kQuotedVolts = 1e-4;

double RadS(double hz) { return 2.0 * kPi * hz; }

TEST(LinearResponseTest, NaturalFrequencyAndDampingOfTable2) {
  const ActuatorModel m = PaperModel();
  EXPECT_REL_NEAR(NaturalFrequencyRadS(m), std::sqrt(124.0 / 0.032), kClosedFormRoundingRel);
  EXPECT_NEAR(NaturalFrequencyRadS(m), 62.2, 0.05);          // from Table 2: 62.2 rad/s
  EXPECT_NEAR(NaturalFrequencyRadS(m) / (2 * kPi), 9.91, 0.005);  // 9.91 Hz
  EXPECT_NEAR(DampingRatio(m), 0.326, 0.0005);
}

TEST(LinearResponseTest, Eq3EqualsTheMassSpringDamperForm) {
  // -g w^2 / (w_p^2 + j 2 zeta w_p w - w^2) = -g m w^2 / (k - m w^2 + j c w).
  const ActuatorModel m = PaperModel();
  for (const double hz : {1.0, 5.0, 9.91, 13.0, 50.0, 500.0}) {
    const double w = RadS(hz);
    const Complex expected = -m.gain_n_per_v * m.mass_kg * w * w /
                             Complex(m.stiffness_n_per_m - m.mass_kg * w * w, m.damping_n_s_per_m * w);
    EXPECT_REL_NEAR(ForceFrf(m, w), expected, kClosedFormRoundingRel) << hz;
  }
}

TEST(LinearResponseTest, Eq3Limits) {
  const double wp = 62.25, zeta = 0.326, g = 0.3;
  // At resonance: -g / (j 2 zeta) = j g / (2 zeta), phase +90 degrees.
  EXPECT_REL_NEAR(ForceFrfEq3(wp, zeta, g, wp), Complex(0.0, g / (2 * zeta)), kClosedFormRoundingRel);
  // Far above resonance the blocked force tends to +g (the sign of Eq. 3).
  EXPECT_REL_NEAR(ForceFrfEq3(wp, zeta, g, 1e6 * wp), Complex(g, 0.0), 1e-6);
  // Far below: -g (w / w_p)^2 (1 - j 2 zeta w / w_p + O(w^2)), negative.
  const double r = 1e-3;
  EXPECT_REL_NEAR(ForceFrfEq3(wp, zeta, g, r * wp), -g * r * r * Complex(1.0, -2.0 * zeta * r), 1e-5);
}

TEST(LinearResponseTest, DisplacementFrfIsMinusHOverMassOmegaSquared) {
  const ActuatorModel m = PaperModel();
  for (const double hz : {2.0, 9.91, 30.0}) {
    const double w = RadS(hz);
    EXPECT_REL_NEAR(DisplacementFrf(m, w), -ForceFrf(m, w) / (m.mass_kg * w * w), 1e-13) << hz;
  }
  // Static limit: g / k_p.
  EXPECT_REL_NEAR(DisplacementFrf(m, 0.0), Complex(0.3 / 124.0, 0.0), kClosedFormRoundingRel);
}

TEST(LinearResponseTest, SaturationThresholdMatchesPaperNotes) {
  const ActuatorModel m = PaperModel();
  EXPECT_NEAR(LinearSaturationThresholdV(m, 16 * kPi), 0.2610, kQuotedVolts);  // 8 Hz
  EXPECT_NEAR(LinearSaturationThresholdV(m, 26 * kPi), 0.4629, kQuotedVolts);  // 13 Hz
  // Minimum: d/dw |k - m w^2 + j c w|^2 = 0  ->  w^2 = k/m - c^2 / (2 m^2).
  const double w_min = std::sqrt(124.0 / 0.032 - 1.3 * 1.3 / (2 * 0.032 * 0.032));
  EXPECT_NEAR(w_min / (2 * kPi), 8.8, 0.05);  // "near 8.8 Hz": 8.789 Hz
  EXPECT_NEAR(LinearSaturationThresholdV(m, w_min), 0.2550, kQuotedVolts);
  EXPECT_GT(LinearSaturationThresholdV(m, 0.99 * w_min), LinearSaturationThresholdV(m, w_min));
  EXPECT_GT(LinearSaturationThresholdV(m, 1.01 * w_min), LinearSaturationThresholdV(m, w_min));
}

TEST(LinearResponseTest, SaturationThresholdIsWhereTheLinearStrokeReachesTheStop) {
  // |H_p(w)| V_sat = |d|.
  const ActuatorModel m = PaperModel();
  for (const double hz : {3.0, 8.0, 13.0, 40.0}) {
    const double w = RadS(hz);
    EXPECT_REL_NEAR(std::abs(DisplacementFrf(m, w)) * LinearSaturationThresholdV(m, w), 1e-3, kClosedFormRoundingRel) << hz;
  }
}

TEST(LinearResponseTest, NoLowerStopNeverSaturates) {
  ActuatorModel m = PaperModel();
  m.lower_stop_m = ActuatorModel::kNoLowerStop;
  EXPECT_TRUE(std::isinf(LinearSaturationThresholdV(m, RadS(8.0))));
}

TEST(LinearResponseTest, RejectsNonPhysicalModelsNamingTheParameter) {
  ActuatorModel m = PaperModel();
  m.mass_kg = 0.0;
  try {
    NaturalFrequencyRadS(m);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "m_p");
  }
  m = PaperModel();
  m.gain_n_per_v = 0.0;
  try {
    LinearSaturationThresholdV(m, 50.0);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "g");
  }
}

}  // namespace
}  // namespace strokelab
