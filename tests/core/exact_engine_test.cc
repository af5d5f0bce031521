// The exact engine against closed forms: paper Eq. 3 below saturation, free decay, the contact
// half-period, and switching instants on the located surfaces; which models it takes (ChooseMethod).
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "strokelab/engines/engine.h"
#include "strokelab/model/linear_response.h"
#include "strokelab/model/model.h"
#include "strokelab/engines/pwl_system.h"
#include "test_util.h"

namespace strokelab {
namespace {

// C1 of a signal over the last `periods` drive periods, by a direct DFT: exact when the window
// holds a whole number of samples per period (8 Hz at 51.2 kHz: 6400).
std::complex<double> DftAtDrive(const std::vector<double>& signal, double fs, double f_hz, int periods) {
  const size_t per_period = static_cast<size_t>(std::llround(fs / f_hz));
  const size_t n_window = per_period * periods;
  const size_t begin = signal.size() - n_window;
  std::complex<double> sum = 0;
  for (size_t n = begin; n < signal.size(); ++n) {
    const double theta = 2 * std::numbers::pi * f_hz * static_cast<double>(n) / fs;
    sum += signal[n] * std::polar(1.0, -theta);
  }
  return 2.0 * sum / static_cast<double>(n_window);
}

TEST(ExactEngineTest, BelowSaturationMatchesEq3) {
  // 8 Hz, 0.2 V: below V_sat(8 Hz) = 0.261 V, so the steady state never touches the stop.
  const ActuatorModel model = PaperModel();
  const SineDrive drive{0.2, 8.0, 0.0};
  SimulationOptions options;
  const Record record = MakeExactEngine()->Simulate(model, drive, options);
  EXPECT_TRUE(record.contacts.empty());
  const std::complex<double> force_c1 = DftAtDrive(record.force_n, options.sample_rate_hz, 8.0, 8);
  const std::complex<double> drive_c1 = std::polar(drive.amplitude_v, -std::numbers::pi / 2);  // V sin
  const std::complex<double> h = force_c1 / drive_c1;
  EXPECT_REL_NEAR(h, ForceFrf(model, drive.AngularFrequency()), 1e-9);
}

TEST(ExactEngineTest, FreeDecayMatchesTheDampedOscillator) {
  ActuatorModel model = PaperModel();
  model.lower_stop_m = ActuatorModel::kNoLowerStop;
  SimulationOptions options;
  options.duration_s = 0.5;
  options.initial = {0.5e-3, 0.02};
  const Record record = MakeExactEngine()->Simulate(model, SineDrive{0.0, 8.0, 0.0}, options);
  const double m = model.mass_kg, c = model.damping_n_s_per_m, k = model.stiffness_n_per_m;
  const double a = c / (2 * m), b = std::sqrt(k / m - a * a);
  const double x0 = options.initial.x_m, v0 = options.initial.v_m_per_s;
  double worst = 0;
  for (size_t n = 0; n < record.size(); ++n) {
    const double t = record.TimeS(n);
    const double x = std::exp(-a * t) * (x0 * std::cos(b * t) + (v0 + a * x0) / b * std::sin(b * t));
    worst = std::max(worst, std::abs(record.displacement_m[n] - x));
  }
  EXPECT_LT(worst, 1e-15);  // metres; the amplitude is 0.6 mm: relative 2e-12
}

TEST(ExactEngineTest, ContactLastsTheDampedHalfPeriod) {
  // Stop at the rest position, no drive, the mass starting into the stop: the contact region's
  // equilibrium is the stop itself, so the contact lasts exactly pi / w_d.
  ActuatorModel model = PaperModel();
  model.lower_stop_m = 0.0;
  model.contact_damping_n_s_per_m = 20.0;
  SimulationOptions options;
  options.duration_s = 0.01;
  options.initial = {0.0, -0.1};
  const Record record = MakeExactEngine()->Simulate(model, SineDrive{0.0, 8.0, 0.0}, options);
  ASSERT_GE(record.contacts.size(), 1u);
  const double m = model.mass_kg, c = model.damping_n_s_per_m + model.contact_damping_n_s_per_m;
  const double k = model.stiffness_n_per_m + model.contact_stiffness;
  const double half_period_s = std::numbers::pi / std::sqrt(k / m - std::pow(c / (2 * m), 2));
  // With c_s > 0 the stop lets go when its push k_s p + c_s p' reaches zero, before x returns to d.
  // Push zero: k_s x + c_s v = 0 on the damped solution; compare with its closed form instead.
  const double a = c / (2 * m), b = std::sqrt(k / m - a * a);
  // x = (v0/b) e^{-at} sin(bt); push = -(k_s x + c_s x') = 0 -> tan(bt) = -c_s b / (k_s - c_s a).
  const double ks = model.contact_stiffness, cs = model.contact_damping_n_s_per_m;
  const double release_s = (std::numbers::pi - std::atan(cs * b / (ks - cs * a))) / b;
  EXPECT_NEAR(record.contacts[0].start_s, 0.0, 1e-15);
  EXPECT_NEAR(record.contacts[0].end_s, release_s, 1e-12);
  EXPECT_LT(release_s, half_period_s);

  model.contact_damping_n_s_per_m = 0.0;
  const Record undamped_stop = MakeExactEngine()->Simulate(model, SineDrive{0.0, 8.0, 0.0}, options);
  const double c0 = model.damping_n_s_per_m;
  const double half_period0_s = std::numbers::pi / std::sqrt(k / m - std::pow(c0 / (2 * m), 2));
  ASSERT_GE(undamped_stop.contacts.size(), 1u);
  EXPECT_NEAR(undamped_stop.contacts[0].DurationS(), half_period0_s, 1e-12);
}

TEST(ExactEngineTest, SwitchingInstantsLieOnTheSurface) {
  // Every located entry and release of the paper model at 8 Hz / 0.5 V puts the mass on x = d.
  const ActuatorModel model = PaperModel();
  const SineDrive drive{0.5, 8.0, 0.0};
  const PiecewiseLinearSystem system(model, drive);
  double t = 0;
  State y;
  PwlMode mode = system.InitialMode(0, y);
  int switches = 0;
  double worst_m = 0;
  system.Advance(&t, &y, &mode, 2.0, [&](const SwitchEvent& e) {
    ++switches;
    worst_m = std::max(worst_m, std::abs(e.state.x_m - model.lower_stop_m));
  });
  EXPECT_GT(switches, 20);
  // 1e-14 s at an impact speed below 0.2 m/s is 2e-15 m.
  EXPECT_LT(worst_m, 1e-14);
}

TEST(ExactEngineTest, RefusesModelsThatAreNotPiecewiseLinear) {
  ActuatorModel model = PaperModel();
  model.cubic_stiffness_n_per_m3 = 4e7;
  try {
    MakeExactEngine()->Simulate(model, SineDrive{0.3, 8.0, 0.0}, SimulationOptions{});
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "method");
    EXPECT_NE(std::string(e.what()).find("k3"), std::string::npos);
  }
}

// Issue 15: models outside ModelBounds (which Engine::Simulate refuses) ran Advance for ever. It
// now ends with a NumericalError naming what was spent and the drive: at once where the substeps
// fall below the resolution of t, after its budget where they merely crawl.
std::string AdvanceError(const ActuatorModel& model, double span_s, State y = {0.0, 0.0}, double phase_rad = 0.0,
                         double budget_steps = PiecewiseLinearSystem::kBudgetBaseSteps) {
  PiecewiseLinearSystem system(model, SineDrive{0.5, 8.0, phase_rad});
  if (budget_steps != PiecewiseLinearSystem::kBudgetBaseSteps) system.SetStepBudget(budget_steps, 0.0, 0.0);
  double t = 0.0;
  PwlMode mode = system.InitialMode(t, y);
  try {
    system.Advance(&t, &y, &mode, span_s, [](const SwitchEvent&) {});
  } catch (const NumericalError& e) {
    return e.what();
  }
  return "";
}

TEST(ExactEngineTest, AdvanceEndsWithAnErrorWhenItsBudgetIsSpent) {
  ActuatorModel stiff = PaperModel();
  stiff.contact_stiffness = 1e40;
  std::string error = AdvanceError(stiff, 1.0);
  EXPECT_NE(error.find("substeps below the resolution of t"), std::string::npos) << error;
  EXPECT_NE(error.find("under the drive 8 Hz, 0.5 V"), std::string::npos) << error;
  ActuatorModel light = PaperModel();
  light.mass_kg = 1e-300;
  error = AdvanceError(light, 1.0);
  EXPECT_NE(error.find("the state is not finite"), std::string::npos) << error;
  // Where the substeps move t on but crawl, the budget ends the call; the paper's model at 8 Hz
  // (four switches a period, from rest) with a budget of 20 steps shows it.
  error = AdvanceError(PaperModel(), 1.0, State{0.0, 0.0}, 0.0, 20.0);
  EXPECT_NE(error.find("work budget spent: 20 substeps and switches"), std::string::npos) << error;
  EXPECT_NE(error.find("under the drive 8 Hz"), std::string::npos) << error;
  EXPECT_EQ(AdvanceError(PaperModel(), 1.0), "");  // the paper's model: well within its budget
}

// "auto" gives the exact engine every piecewise-linear model (stops on both sides, contact damping,
// clipping) and cvode every model with a smooth term, naming the term; a named engine is taken as
// named, except exact on a model it cannot take.
TEST(ChooseMethodTest, AutoTakesTheExactEngineWhereItCanAndCvodeElsewhere) {
  ActuatorModel piecewise = PaperModel();
  piecewise.upper_stop_m = 2e-3;
  piecewise.contact_damping_n_s_per_m = 5.0;
  piecewise.amplifier_limit_v = 0.4;
  for (const ActuatorModel& model : {PaperModel(), PresetModel("linear"), piecewise}) {
    const MethodChoice choice = ChooseMethod("auto", model);
    EXPECT_EQ(choice.method, Method::kExact);
    EXPECT_EQ(choice.Describe(), "exact (auto: the model is piecewise linear)");
  }
  ActuatorModel k2 = PaperModel(), k3 = PaperModel(), hertz = PaperModel(), friction = PaperModel();
  k2.quadratic_stiffness_n_per_m2 = 1e4;
  k3.cubic_stiffness_n_per_m3 = 4e7;
  hertz.contact_law = ContactLaw::kHertzian;
  friction.friction_force_n = 0.01;
  const std::vector<std::pair<ActuatorModel, std::string>> smooth = {
      {k2, "k2"}, {k3, "k3"}, {hertz, "Hertzian"}, {friction, "friction"}};
  for (const auto& [model, term] : smooth) {
    SCOPED_TRACE(term);
    const MethodChoice choice = ChooseMethod("auto", model);
    EXPECT_EQ(choice.method, Method::kCvode);
    EXPECT_EQ(choice.reason.find("the model has "), 0u) << choice.reason;
    EXPECT_NE(choice.reason.find(term), std::string::npos) << choice.reason;
    EXPECT_NE(choice.reason.find("which the exact engine cannot take"), std::string::npos) << choice.reason;
    EXPECT_EQ(choice.Describe(), "cvode (auto: " + choice.reason + ")");
    EXPECT_EQ(ChooseMethod("ode3", model).Describe(), "ode3");
  }
  EXPECT_EQ(ChooseMethod("cvode", PaperModel()).Describe(), "cvode");
  EXPECT_EQ(ChooseMethod("exact", PaperModel()).Describe(), "exact");
  try {
    (void)ChooseMethod("exact", k3);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "method");
    EXPECT_EQ(e.bare_message(), "the exact engine needs a piecewise-linear model; this one has k3 (cubic stiffness) "
                                "(use auto, the default, or cvode)");
  }
  try {
    (void)ChooseMethod("rk4", PaperModel());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "method");
    EXPECT_EQ(e.bare_message(), "unknown method 'rk4' (known: auto, exact, cvode, ode3)");
  }
}

}  // namespace
// Amplifier clipping on both half-waves, with impacts: the closed form agrees with CVODE sample by
// sample. (A sign slip in the release surface of negative clipping once kept the drive clipped at
// -limit for the rest of the record: 0.6 rad of first-harmonic phase error.)
TEST(ExactEngineTest, ClippedDriveMatchesCvodeOnBothHalfWaves) {
  ActuatorModel model = PaperModel();
  model.amplifier_limit_v = 0.45;
  const SineDrive drive{0.5, 9.0, 0.0};
  SimulationOptions options;
  options.duration_s = 1.0;
  options.sample_rate_hz = 51200.0;
  const Record exact = MakeExactEngine()->Simulate(model, drive, options);
  const Record cvode = MakeCvodeEngine()->Simulate(model, drive, options);
  ASSERT_EQ(exact.size(), cvode.size());
  double max_dx = 0.0, max_x = 0.0;
  for (size_t n = 0; n < exact.size(); ++n) {
    max_dx = std::max(max_dx, std::abs(exact.displacement_m[n] - cvode.displacement_m[n]));
    max_x = std::max(max_x, std::abs(cvode.displacement_m[n]));
  }
  // CVODE at rtol 1e-10 against the closed form: a few 1e-9 of the stroke (the contacts' switching
  // instants dominate); the slip gave ~30 % of it.
  EXPECT_LT(max_dx, 1e-7 * max_x);
  EXPECT_GT(exact.contacts.size(), 5u);
}

}  // namespace strokelab
