// Steady states of a model the closed form cannot take (paper + k3, paper + k3 with Hertzian contact,
// and the coil's pole, a third state) by shooting on the variational period map, against a second method: CVODE at rtol 1e-12
// run from rest until the transient has died out, its first harmonic taken from 4096 samples of the
// last period (a DFT bin: x is smooth enough that the aliased harmonics are far below 1e-8).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <complex>
#include <string>
#include <vector>

#include "strokelab/engines/engine.h"
#include "strokelab/model/linear_response.h"
#include "strokelab/model/model.h"
#include "strokelab/signal/signal.h"
#include "strokelab/steady/steady_state.h"

namespace strokelab {
namespace {

constexpr int kSettleDrivePeriods = 300;  // multipliers <= 0.5 here: 0.5^300 leaves nothing
constexpr double kSamplesPerPeriod = 4096;

// |F1| = m_p w^2 |C_1(x)| [N] of CVODE's steady state from rest.
double ReferenceF1(const ActuatorModel& model, double f_hz, double v) {
  SimulationOptions o;
  o.duration_s = kSettleDrivePeriods / f_hz;
  o.sample_rate_hz = kSamplesPerPeriod * f_hz;
  o.cvode_relative_tolerance = 1e-12;
  o.cvode_absolute_tolerance_m = 1e-16;
  o.cvode_absolute_tolerance_m_per_s = 1e-13;
  o.cvode_absolute_tolerance_n = 1e-15;
  o.record_velocity = false;
  const Record r = MakeCvodeEngine()->Simulate(model, SineDrive{v, f_hz, 0.0}, o);
  const SampleWindow last{r.size() - static_cast<size_t>(kSamplesPerPeriod), r.size(), 1.0};
  const std::complex<double> x1 = HarmonicAmplitudes(r.displacement_m, o.sample_rate_hz, f_hz, last, 1)[0];
  const double omega = 2.0 * std::numbers::pi * f_hz;
  return model.mass_kg * omega * omega * std::abs(x1);
}

TEST(SmoothSteadyStateTest, FirstHarmonicIsLongTimeIntegrations) {
  ActuatorModel k3 = PaperModel();
  k3.cubic_stiffness_n_per_m3 = 4e7;
  ActuatorModel hertz = k3;
  hertz.cubic_stiffness_n_per_m3 = 2.5e7;
  hertz.contact_law = ContactLaw::kHertzian;
  hertz.contact_stiffness = 2.65e8;
  ActuatorModel coil = PaperModel();  // tau_e = 2 mH / 3 Ohm, with a force factor over the stroke
  coil.coil_time_constant_s = 2e-3 / 3.0;
  coil.back_emf_damping_n_s_per_m = 0.8;
  coil.force_factor_b2_per_m2 = -2e5;
  struct Case {
    std::string name;
    ActuatorModel model;
    double f_hz, v;
  };
  // Free, one contact a period, and well above resonance; none in a jump region.
  for (const Case& c : {Case{"k3 5 Hz 0.2 V", k3, 5.0, 0.2}, Case{"k3 8 Hz 0.5 V", k3, 8.0, 0.5},
                        Case{"k3 30 Hz 0.6 V", k3, 30.0, 0.6}, Case{"hertz 8 Hz 0.5 V", hertz, 8.0, 0.5},
                        Case{"hertz 12 Hz 0.6 V", hertz, 12.0, 0.6}, Case{"coil 8 Hz 0.5 V", coil, 8.0, 0.5},
                        Case{"coil 30 Hz 0.6 V", coil, 30.0, 0.6}}) {
    SCOPED_TRACE(c.name);
    const PeriodMap map(c.model, c.f_hz, c.v);
    const SteadyState s = SolveAttractor(map, map.ClippedLinearStart());
    ASSERT_EQ(s.period, 1);
    ASSERT_TRUE(s.stable);
    const double f1 = std::abs(s.Frf(map)) * c.v;
    const double reference = ReferenceF1(c.model, c.f_hz, c.v);
    std::printf("%s: |F1| %.12g N, CVODE %.12g N, relative difference %.2g\n", c.name.c_str(), f1, reference,
                std::abs(f1 / reference - 1));
    EXPECT_NEAR(f1, reference, 1e-8 * reference);
  }
}

// The coil's pole on the linear actuator (no stop): the steady state by shooting (a third state in the
// flow, Newton on 3 x 3) against the phasor closed form of linear_response.h, g / [(k_p - m_p w^2 +
// j (c_p - c_emf) w)(1 + j w tau_e) + j w c_emf], at frequencies where the pole turns the phase by
// 1 to 25 degrees; and its start (ClippedLinearStart) already on the orbit.
TEST(SmoothSteadyStateTest, TheCoilsPoleOnTheLinearActuatorIsThePhasorClosedForm) {
  ActuatorModel coil = PresetModel("linear");
  coil.coil_time_constant_s = 2e-3 / 3.0;
  coil.back_emf_damping_n_s_per_m = 0.8;
  for (double f_hz : {5.0, 10.3, 40.0, 180.0}) {
    SCOPED_TRACE(f_hz);
    const PeriodMap map(coil, f_hz, 0.4);
    const State start = map.ClippedLinearStart();
    const State end = map.Apply(start);
    EXPECT_NEAR(end.x_m, start.x_m, 1e-9 * std::abs(start.x_m) + 1e-15);
    EXPECT_NEAR(end.coil_force_n, start.coil_force_n, 1e-9 * 0.3 * 0.4);
    const std::optional<SteadyState> s = Shoot(map, start);
    ASSERT_TRUE(s.has_value());
    EXPECT_EQ(s->multipliers.size(), 3u);
    EXPECT_TRUE(s->stable);
    const std::complex<double> closed = ForceFrf(coil, 2.0 * std::numbers::pi * f_hz);
    EXPECT_LT(std::abs(s->Frf(map) - closed), 1e-9 * std::abs(closed)) << s->Frf(map) << " vs " << closed;
    // Without the pole the same actuator's response differs by more than the tolerance: the test sees it.
    ActuatorModel no_pole = coil;
    no_pole.coil_time_constant_s = 0.0;
    EXPECT_GT(std::abs(ForceFrf(no_pole, 2.0 * std::numbers::pi * f_hz) - closed), 1e-3 * std::abs(closed));
  }
}

}  // namespace
}  // namespace strokelab
