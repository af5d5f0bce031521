// The ode3 engine (fixed-step Bogacki-Shampine at h = 1/fs, no event location, as the paper's
// Simulink run) against closed forms and against the cvode engine. Each bound sits at about twice
// the error measured when the test was written (stated beside it, 51.2 kHz): a regression shows up,
// the method's honest error does not fail the test.
//   linear FRF             H(w) = -g w^2 / (w_p^2 + j 2 zeta_p w_p w - w^2)        paper Eq. 3
//   free decay             x(t) = e^{-a t} (x0 cos b t + (v0 + a x0) / b sin b t),  a = c_p / 2m, b^2 = k_p/m - a^2
//   linear contact         lasts pi / w_d, w_d^2 = (k_p + k_s)/m - ((c_p + c_s) / 2m)^2
//   clipped drive          first harmonic (2V/pi)(theta_c + r sqrt(1 - r^2)), r = limit / V
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <vector>

#include "strokelab/engines/engine.h"
#include "strokelab/base/errors.h"
#include "engine_test_util.h"
#include "test_util.h"

namespace strokelab {
namespace {

using ::testing::HasSubstr;
using ::strokelab::testing::ComplexAmplitude;
using ::strokelab::testing::LastSecond;
using ::strokelab::testing::PaperEq3;
using Complex = std::complex<double>;
using ::strokelab::testing::kPi;



using ::strokelab::testing::ContactDampedFrequency;

using ::strokelab::testing::kNoDrive;

TEST(Ode3EngineTest, ReportsItsMethod) { EXPECT_EQ(MakeOde3Engine()->method(), Method::kOde3); }

TEST(Ode3EngineTest, LinearForceFrfIsPaperEq3) {
  const ActuatorModel model = PresetModel("linear");
  SimulationOptions options;
  options.duration_s = 3.0;
  for (const double f_hz : {5.0, 8.0, 13.0, 47.0}) {
    SCOPED_TRACE(f_hz);
    const SineDrive drive{.amplitude_v = 0.2, .frequency_hz = f_hz};
    const Record record = MakeOde3Engine()->Simulate(model, drive, options);
    const Complex force_n = ComplexAmplitude(record.force_n, LastSecond(record), record.sample_rate_hz, f_hz);
    const Complex expected = PaperEq3(model, drive.AngularFrequency());
    // Measured 9.6e-11 (5 Hz), 1.9e-10 (8 Hz), 2.0e-10 (13 Hz), 1.8e-10 (47 Hz): the smooth linear
    // model is easy for a third-order method at 2000+ steps per period.
    EXPECT_REL_NEAR(force_n / Complex(0.0, -drive.amplitude_v), expected, 4e-10);
  }
}

TEST(Ode3EngineTest, FreeDecayIsTheDampedOscillatorWithThirdOrderError) {
  const ActuatorModel model = PresetModel("linear");
  const double a = model.damping_n_s_per_m / (2.0 * model.mass_kg);
  const double b = std::sqrt(model.stiffness_n_per_m / model.mass_kg - a * a);
  SimulationOptions options;
  options.duration_s = 0.5;
  options.initial = {.x_m = 0.5e-3, .v_m_per_s = 0.02};
  const double x0 = options.initial.x_m;
  const double v0 = options.initial.v_m_per_s;
  auto exact_x = [&](double t) {
    return std::exp(-a * t) * (x0 * std::cos(b * t) + (v0 + a * x0) / b * std::sin(b * t));
  };
  auto max_error_m = [&](double sample_rate_hz) {
    options.sample_rate_hz = sample_rate_hz;
    const Record record = MakeOde3Engine()->Simulate(model, kNoDrive, options);
    double error = 0.0;
    for (size_t n = 0; n < record.size(); ++n)
      error = std::max(error, std::abs(record.displacement_m[n] - exact_x(record.TimeS(n))));
    return error;
  };
  const double error_m = max_error_m(51200.0);
  const double half_step_error_m = max_error_m(102400.0);
  EXPECT_LT(error_m, 1.2e-13);                         // measured 6.0e-14 m, 1e-10 of the 0.6 mm amplitude
  EXPECT_NEAR(error_m / half_step_error_m, 8.0, 0.1);  // third order: halving h divides it by 2^3 (measured 8.002)
}

TEST(Ode3EngineTest, ContactTimesAreQuantisedToTheSamplePeriod) {
  ActuatorModel model = PaperModel();
  model.lower_stop_m = 0.0;
  SimulationOptions options;
  options.duration_s = 0.01;
  options.initial = {0.0, -0.1};
  const Record record = MakeOde3Engine()->Simulate(model, kNoDrive, options);
  ASSERT_EQ(record.contacts.size(), 1u);
  const double sample_period_s = 1.0 / options.sample_rate_hz;
  // Measured: from the second sample (19.5 us: at t = 0 the penetration is exactly 0) to 507.8 us,
  // 488.3 us against 492.9 us.
  EXPECT_NEAR(record.contacts[0].DurationS(), kPi / ContactDampedFrequency(model), sample_period_s);
  EXPECT_TRUE(record.contacts[0].closed);
  EXPECT_FALSE(record.contacts[0].upper);
}

TEST(Ode3EngineTest, AgreesWithCvodeOnThePaperModelToItsOwnError) {
  const ActuatorModel model = PaperModel();
  const SineDrive drive{.amplitude_v = 0.5, .frequency_hz = 8.0};
  const SimulationOptions options;  // 10 s at 51.2 kHz, as the paper
  const Record ode3 = MakeOde3Engine()->Simulate(model, drive, options);
  const Record cvode = MakeCvodeEngine()->Simulate(model, drive, options);
  const Complex f1_ode3 = ComplexAmplitude(ode3.force_n, LastSecond(ode3), ode3.sample_rate_hz, 8.0);
  const Complex f1_cvode = ComplexAmplitude(cvode.force_n, LastSecond(cvode), cvode.sample_rate_hz, 8.0);
  double max_force_difference_n = 0.0;
  for (size_t n = 0; n < ode3.size(); ++n)
    max_force_difference_n = std::max(max_force_difference_n, std::abs(ode3.force_n[n] - cvode.force_n[n]));
  // Measured: F1 differs by 3.4e-4 relative (an independent prototype: 2.4e-4 in |F1|), the force
  // by up to 0.087 N (the prototype: 0.087 N) at the spikes, where a contact starts or ends inside
  // a step.
  EXPECT_REL_NEAR(f1_ode3, f1_cvode, 7e-4);
  EXPECT_LT(max_force_difference_n, 0.2);
  EXPECT_EQ(ode3.contacts.size(), cvode.contacts.size());
  for (size_t i = 0; i < std::min(ode3.contacts.size(), cvode.contacts.size()); ++i) {
    EXPECT_NEAR(ode3.contacts[i].start_s, cvode.contacts[i].start_s, 1.0 / options.sample_rate_hz);
    EXPECT_NEAR(ode3.contacts[i].end_s, cvode.contacts[i].end_s, 1.0 / options.sample_rate_hz);
  }
  EXPECT_EQ(ode3.rhs_evaluations, 3 * ode3.size());  // three stages per step, the first reused
}

TEST(Ode3EngineTest, RecordedForceIsTheBlockedForceOfTheSampledState) {
  // The engine rotates a phasor for the drive instead of calling sin() three times per step; the
  // recorded force must still be BlockedForce at (t_n, x_n, v_n) in the state's own mode.
  const ActuatorModel model = PaperModel();
  const SineDrive drive{.amplitude_v = 0.5, .frequency_hz = 8.0, .phase_rad = 0.3};
  SimulationOptions options;
  options.duration_s = 2.0;
  const Record record = MakeOde3Engine()->Simulate(model, drive, options);
  double max_difference_n = 0.0;
  for (size_t n = 0; n < record.size(); ++n) {
    const double x = record.displacement_m[n], v = record.velocity_m_per_s[n];
    const ContactMode mode = ModeFromState(model, x, v);
    EXPECT_EQ(record.in_contact[n], mode.Any() ? 1 : 0);
    max_difference_n =
        std::max(max_difference_n,
                 std::abs(record.force_n[n] - BlockedForce(model, drive.Voltage(record.TimeS(n)), State{x, v}, mode)));
  }
  EXPECT_LT(max_difference_n, 1e-14);  // 0.15 N of drive force, rounded: a few 1e-17 N
}

TEST(Ode3EngineTest, AmplifierLimitClipsTheDrive) {
  ActuatorModel model = PresetModel("linear");
  model.amplifier_limit_v = 0.2;
  const SineDrive drive{.amplitude_v = 0.5, .frequency_hz = 8.0};
  SimulationOptions options;
  options.duration_s = 3.0;
  const Record ode3 = MakeOde3Engine()->Simulate(model, drive, options);
  const Record cvode = MakeCvodeEngine()->Simulate(model, drive, options);
  const double r = model.amplifier_limit_v / drive.amplitude_v, theta_c = std::asin(r);
  const double b1 = 2.0 * drive.amplitude_v / kPi * (theta_c + r * std::cos(theta_c));
  const Complex expected = PaperEq3(model, drive.AngularFrequency()) * Complex(0.0, -b1);
  const Complex f1 = ComplexAmplitude(ode3.force_n, LastSecond(ode3), ode3.sample_rate_hz, 8.0);
  double max_difference_n = 0.0;
  for (size_t n = 0; n < ode3.size(); ++n)
    max_difference_n = std::max(max_difference_n, std::abs(ode3.force_n[n] - cvode.force_n[n]));
  // Measured 7.5e-8 and 9.8e-9 N: a kink of the clipped drive inside a step costs the method its
  // order in that step (no event location), still far below anything the paper could measure.
  EXPECT_REL_NEAR(f1, expected, 1.5e-7);
  EXPECT_LT(max_difference_n, 2e-8);
}

TEST(Ode3EngineTest, RecordsContactsAsTheSampledFlagsSeeThem) {
  ActuatorModel model = PaperModel();
  model.upper_stop_m = 1e-3;
  const SineDrive drive{.amplitude_v = 1.0, .frequency_hz = 8.0};
  SimulationOptions options;
  options.duration_s = 1.0;
  const Record record = MakeOde3Engine()->Simulate(model, drive, options);
  size_t lower = 0, upper = 0;
  for (const ContactInterval& contact : record.contacts) (contact.upper ? upper : lower) += 1;
  EXPECT_GT(lower, 0u);
  EXPECT_GT(upper, 0u);
  // Every contact spans whole samples: [first in contact, first out).
  for (const ContactInterval& contact : record.contacts) {
    const size_t first = static_cast<size_t>(std::llround(contact.start_s * record.sample_rate_hz));
    const size_t last = static_cast<size_t>(std::llround(contact.end_s * record.sample_rate_hz));
    EXPECT_EQ(record.in_contact[first], 1);
    if (first > 0) {
      EXPECT_EQ(record.in_contact[first - 1], 0);
    }
    if (contact.closed) {
      EXPECT_EQ(record.in_contact[last], 0);
    }
    for (size_t n = first; n < last; ++n) ASSERT_EQ(record.in_contact[n], 1);
  }
}

TEST(Ode3EngineTest, RejectsBadInputNamingTheField) {
  SimulationOptions options;
  options.sample_rate_hz = 0.0;
  try {
    MakeOde3Engine()->Simulate(PaperModel(), kNoDrive, options);
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& error) {
    EXPECT_EQ(error.field(), "sample_rate_hz");
  }
  ActuatorModel model = PaperModel();
  model.stiffness_n_per_m = -1.0;
  options = SimulationOptions{};
  try {
    MakeOde3Engine()->Simulate(model, kNoDrive, options);
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& error) {
    EXPECT_EQ(error.field(), "k_p");
  }
}

TEST(Ode3EngineTest, DivergingModelIsANumericalError) {
  ActuatorModel model = PresetModel("linear");
  model.cubic_stiffness_n_per_m3 = -1e12;
  const SineDrive drive{.amplitude_v = 0.5, .frequency_hz = 8.0};
  SimulationOptions options;
  options.duration_s = 0.1;
  try {
    MakeOde3Engine()->Simulate(model, drive, options);
    ADD_FAILURE() << "expected a NumericalError";
  } catch (const NumericalError& error) {
    EXPECT_THAT(error.what(), HasSubstr("no longer finite"));
  }
}

}  // namespace
}  // namespace strokelab
