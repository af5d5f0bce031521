// The missing-force surface (open_world.h, EstimateMissingForce) against closed forms: records of an
// actuator with a force term the model lacks give back that term, its coefficient and its values.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <vector>

#include "strokelab/diagnose/open_world.h"
#include "strokelab/steady/steady_state.h"

namespace strokelab {
namespace {

using internal::EstimateMissingForce;

constexpr int kSurfaceHarmonics = 10;

// The paper's suspension without its stop (the surface leaves out phases near a stop).
ActuatorModel StoplessActuator() {
  ActuatorModel m = PaperModel();
  m.lower_stop_m = ActuatorModel::kNoLowerStop;
  return m;
}

// Displacement harmonics (the response channel kDisplacement) of `model`'s steady state.
std::vector<std::complex<double>> SteadyHarmonics(const ActuatorModel& model, double frequency_hz, double amplitude_v) {
  const PeriodMap map(model, frequency_hz, amplitude_v);
  const SteadyState orbit = SolveAttractor(map, map.ClippedLinearStart());
  EXPECT_EQ(orbit.period, 1);
  return OrbitHarmonics(map, orbit.start, 1, kSurfaceHarmonics);
}

// Records of `truth` matched by `model` at 5-20 Hz and 0.2-0.6 V.
std::vector<RecordMatch> SurfaceMatches(const ActuatorModel& truth, const ActuatorModel& model) {
  std::vector<RecordMatch> matches;
  for (double f : {5.0, 8.0, 11.0, 14.0, 20.0})
    for (double v : {0.2, 0.4, 0.6}) {
      RecordMatch m;
      m.frequency_hz = f, m.amplitude_v = v;
      m.measured = SteadyHarmonics(truth, f, v);
      m.model = SteadyHarmonics(model, f, v);
      m.harmonic_chi2.assign(kSurfaceHarmonics, 1.0);
      matches.push_back(m);
    }
  return matches;
}

TEST(MissingForceTest, ACubicSpringTheModelLacksComesBackAsMinusK3XCubed) {
  const ActuatorModel model = StoplessActuator();
  ActuatorModel truth = model;
  truth.cubic_stiffness_n_per_m3 = 4e7;  // the force -k3 x^3
  const MissingForceSurface s = EstimateMissingForce(model, SurfaceMatches(truth, model), ResponseKind::kDisplacement);
  ASSERT_FALSE(s.force_n.empty()) << s.note;
  EXPECT_EQ(s.term, "x^3");
  EXPECT_EQ(s.term_unit, "N/m^3");
  // Ten harmonics of a response this weakly nonlinear hold its cubic force to well under 1 %.
  EXPECT_NEAR(s.term_coefficient, -4e7, 0.01 * 4e7);
  EXPECT_GT(s.term_r2, 0.999);
  // -k3 x^3 is monotonic: each bin's mean lies between its values at the bin's edges (up to 1 % of the
  // largest force, the harmonics' truncation).
  const double dx = s.x_m[1] - s.x_m[0], largest = 4e7 * std::pow(std::abs(s.x_m.front()) + dx, 3);
  int compared = 0;
  for (size_t ix = 0; ix < s.x_m.size(); ++ix)
    for (size_t iv = 0; iv < s.v_m_per_s.size(); ++iv) {
      const double force = s.force_n[ix * s.v_m_per_s.size() + iv];
      if (std::isnan(force)) continue;
      const double low = s.x_m[ix] - 0.5 * dx, high = s.x_m[ix] + 0.5 * dx;
      EXPECT_LE(force, -4e7 * low * low * low + 0.01 * largest) << "x " << s.x_m[ix];
      EXPECT_GE(force, -4e7 * high * high * high - 0.01 * largest) << "x " << s.x_m[ix];
      ++compared;
    }
  EXPECT_GT(compared, 20);
}

TEST(MissingForceTest, VelocityCubedDampingIsToldFromAStiffnessTerm) {
  const ActuatorModel model = StoplessActuator();
  ActuatorModel truth = model;
  truth.quadratic_damping_n_s2_per_m2 = 2.0;  // the force -c2 v|v|
  const MissingForceSurface s = EstimateMissingForce(model, SurfaceMatches(truth, model), ResponseKind::kDisplacement);
  ASSERT_FALSE(s.force_n.empty()) << s.note;
  EXPECT_EQ(s.term, "v|v|");
  EXPECT_NEAR(s.term_coefficient, -2.0, 0.02 * 2.0);
}

TEST(MissingForceTest, TheModelItselfLeavesNothing) {
  const ActuatorModel model = StoplessActuator();
  const MissingForceSurface s = EstimateMissingForce(model, SurfaceMatches(model, model), ResponseKind::kDisplacement);
  ASSERT_FALSE(s.force_n.empty()) << s.note;
  EXPECT_LT(s.rms_n, 1e-9);
}

TEST(MissingForceTest, ACoilPoleGivesNoSurfaceAndSaysWhy) {
  ActuatorModel model = StoplessActuator();
  model.coil_time_constant_s = 5e-4;
  const MissingForceSurface s = EstimateMissingForce(model, {}, ResponseKind::kForce);
  EXPECT_TRUE(s.force_n.empty());
  EXPECT_NE(s.note.find("coil"), std::string::npos);
}

}  // namespace
}  // namespace strokelab
