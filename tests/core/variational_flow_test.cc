// The variational flow (engines/variational_flow.h) against two independent references: the closed
// form on piecewise-linear models (steady/steady_state.h's PeriodMap::Trace: exact propagation and
// saltation matrices), and central finite differences of the flow itself for every force term's
// monodromy, parameter sensitivities and harmonic sensitivities.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <string>
#include <vector>

#include "strokelab/engines/engine.h"
#include "strokelab/engines/variational_flow.h"
#include "strokelab/model/model.h"
#include "strokelab/steady/steady_state.h"

namespace strokelab {
namespace {

using Field = double ActuatorModel::*;

// x / L, v / (w L) and, with the coil's pole, F_e / (k_p L): the sweep's scaling (steady_state.h), so
// that the components count alike.
struct Scale {
  double length_m, speed_m_per_s, force_n;
  double Norm(State s) const {
    const double e = force_n > 0 ? s.coil_force_n / force_n : 0.0;
    return std::sqrt(std::pow(s.x_m / length_m, 2) + std::pow(s.v_m_per_s / speed_m_per_s, 2) + e * e);
  }
};

Scale ScaleOf(const ActuatorModel& model, double frequency_hz) {
  const double length = LengthScaleM(model);
  return {length, length * 2.0 * std::numbers::pi * frequency_hz,
          model.HasCoilPole() ? model.stiffness_n_per_m * length : 0.0};
}

State Difference(State a, State b) {
  return {a.x_m - b.x_m, a.v_m_per_s - b.v_m_per_s, a.coil_force_n - b.coil_force_n};
}

// (plus - minus) / (2 step), component by component.
State CentralQuotient(State plus, State minus, double step) {
  return {(plus.x_m - minus.x_m) / (2 * step), (plus.v_m_per_s - minus.v_m_per_s) / (2 * step),
          (plus.coil_force_n - minus.coil_force_n) / (2 * step)};
}

// A start on or near the orbit (a few periods from the linear start), so that the pass has contacts.
State SettledStart(const ActuatorModel& model, const SineDrive& drive) {
  const PeriodMap map(model, drive.frequency_hz, drive.amplitude_v);
  State y = map.ClippedLinearStart();
  for (int i = 0; i < 5; ++i) y = Flow(model, drive, y, 0.0, 1.0 / drive.frequency_hz, {}).end;
  return y;
}

struct PwlCase {
  std::string name;
  ActuatorModel model;
  double frequency_hz, amplitude_v;
};

std::vector<PwlCase> PiecewiseLinearCases() {
  ActuatorModel two_stops = PaperModel();
  two_stops.upper_stop_m = 1.2e-3;
  ActuatorModel damped = PaperModel();
  damped.contact_damping_n_s_per_m = 15.0;  // the stop force jumps at entry: a non-trivial saltation
  ActuatorModel clipped = PaperModel();
  clipped.amplifier_limit_v = 0.35;
  return {{"paper_8Hz_0.5V", PaperModel(), 8.0, 0.5},   {"paper_13Hz_0.3V", PaperModel(), 13.0, 0.3},
          {"paper_free_30Hz", PaperModel(), 30.0, 0.1}, {"two_stops_10Hz_0.8V", two_stops, 10.0, 0.8},
          {"damped_stop_8Hz_0.5V", damped, 8.0, 0.5},   {"clipped_8Hz_0.6V", clipped, 8.0, 0.6}};
}

TEST(VariationalFlowTest, MatchesTheClosedFormOnPiecewiseLinearModels) {
  for (const PwlCase& c : PiecewiseLinearCases()) {
    SCOPED_TRACE(c.name);
    const SineDrive drive{c.amplitude_v, c.frequency_hz, 0.0};
    const Scale scale = ScaleOf(c.model, c.frequency_hz);
    const PeriodMap map(c.model, c.frequency_hz, c.amplitude_v);
    const State start = SettledStart(c.model, drive);
    const OrbitFigures closed = map.Trace(start, 1);
    FlowRequest request;
    request.monodromy = true;
    request.harmonics = 1;
    request.figures = true;
    const FlowResult flow = Flow(c.model, drive, start, 0.0, map.period_s(), request);
    EXPECT_LT(scale.Norm(Difference(flow.end, closed.end)), 1e-9);
    // Monodromy in the scaled coordinates, elementwise against its largest element.
    const StateMatrix& m = closed.monodromy;
    const double r = scale.speed_m_per_s / scale.length_m;  // d(v/V)/d(x/L) = dv/dx / r
    const double closed_scaled[4] = {m(0, 0), m(0, 1) * r, m(1, 0) / r, m(1, 1)};
    const double flow_scaled[4] = {flow.columns[0].x_m, flow.columns[1].x_m * r, flow.columns[0].v_m_per_s / r,
                                   flow.columns[1].v_m_per_s};
    double largest = 0.0;
    for (double e : closed_scaled) largest = std::max(largest, std::abs(e));
    for (int i = 0; i < 4; ++i) EXPECT_NEAR(flow_scaled[i], closed_scaled[i], 1e-9 * largest) << "element " << i;
    const std::complex<double> x1 = 2.0 * flow.harmonic_integrals[0] / map.period_s();
    EXPECT_LT(std::abs(x1 - closed.x1), 1e-9 * std::abs(closed.x1));
    EXPECT_EQ(flow.contacts, closed.contacts);
    EXPECT_NEAR(flow.min_displacement_m, closed.min_displacement_m, 1e-9 * scale.length_m);
    EXPECT_NEAR(flow.max_displacement_m, closed.max_displacement_m, 1e-9 * scale.length_m);
  }
}

struct SmoothCase {
  std::string name;
  ActuatorModel model;
  double frequency_hz, amplitude_v;
  std::vector<Field> parameters;
};

std::vector<SmoothCase> ForceTermCases() {
  using M = ActuatorModel;
  const std::vector<Field> linear_part = {&M::mass_kg, &M::damping_n_s_per_m, &M::stiffness_n_per_m,
                                          &M::gain_n_per_v, &M::lower_stop_m, &M::contact_stiffness};
  std::vector<SmoothCase> cases;
  auto add = [&](std::string name, ActuatorModel model, double f, double v, std::vector<Field> extra) {
    std::vector<Field> parameters = linear_part;
    parameters.insert(parameters.end(), extra.begin(), extra.end());
    cases.push_back({std::move(name), model, f, v, parameters});
  };
  ActuatorModel k2 = PaperModel();
  k2.quadratic_stiffness_n_per_m2 = 3e4;
  add("quadratic_stiffness", k2, 8.0, 0.5, {&M::quadratic_stiffness_n_per_m2});
  ActuatorModel k3 = PaperModel();
  k3.cubic_stiffness_n_per_m3 = 4e7;
  add("cubic_stiffness", k3, 8.0, 0.5, {&M::cubic_stiffness_n_per_m3});
  ActuatorModel hertz = PaperModel();
  hertz.contact_law = ContactLaw::kHertzian;
  hertz.contact_stiffness = 2.65e8;
  add("hertzian_contact", hertz, 8.0, 0.5, {});
  ActuatorModel friction = PaperModel();
  friction.friction_force_n = 0.01;
  friction.friction_velocity_m_per_s = 2e-3;
  add("dry_friction", friction, 8.0, 0.5, {&M::friction_force_n, &M::friction_velocity_m_per_s});
  // c2 v|v|: its second derivative jumps where v = 0 (each apex), as friction's does not.
  ActuatorModel quadratic_damping = PaperModel();
  quadratic_damping.quadratic_damping_n_s2_per_m2 = 2.0;
  add("quadratic_damping", quadratic_damping, 8.0, 0.5, {&M::quadratic_damping_n_s2_per_m2});
  ActuatorModel force_factor = PaperModel();  // -20 % at 1 mm, an offset, and its back-EMF
  force_factor.force_factor_b1_per_m = 40.0;
  force_factor.force_factor_b2_per_m2 = -2e5;
  force_factor.back_emf_damping_n_s_per_m = 0.8;
  add("force_factor", force_factor, 8.0, 0.5,
      {&M::force_factor_b1_per_m, &M::force_factor_b2_per_m2, &M::back_emf_damping_n_s_per_m});
  ActuatorModel damped = PaperModel();
  damped.contact_damping_n_s_per_m = 15.0;
  damped.cubic_stiffness_n_per_m3 = 2e7;
  add("contact_damping", damped, 8.0, 0.5, {&M::contact_damping_n_s_per_m, &M::cubic_stiffness_n_per_m3});
  ActuatorModel clipped = PaperModel();
  clipped.amplifier_limit_v = 0.35;
  clipped.cubic_stiffness_n_per_m3 = 2e7;
  add("clipping", clipped, 8.0, 0.6, {&M::amplifier_limit_v});
  ActuatorModel upper = PaperModel();
  upper.upper_stop_m = 1.2e-3;
  upper.contact_law = ContactLaw::kHertzian;
  upper.contact_stiffness = 2.65e8;
  add("upper_stop", upper, 10.0, 0.8, {&M::upper_stop_m});
  // The coil's pole (a third state) with a force factor over the stroke: F_e' couples to x and v
  // through c_emf phi v, and g and the drive act through F_e. tau_e = 2 mH / 3 Ohm.
  ActuatorModel coil = force_factor;
  coil.coil_time_constant_s = 2e-3 / 3.0;
  add("coil_pole", coil, 8.0, 0.5,
      {&M::coil_time_constant_s, &M::back_emf_damping_n_s_per_m, &M::force_factor_b1_per_m,
       &M::force_factor_b2_per_m2});
  ActuatorModel clipped_coil = clipped;
  clipped_coil.coil_time_constant_s = 2e-3 / 3.0;
  clipped_coil.back_emf_damping_n_s_per_m = 0.8;
  add("coil_pole_clipping", clipped_coil, 8.0, 0.6, {&M::coil_time_constant_s, &M::amplifier_limit_v});
  return cases;
}

// Central difference of the flow's end (and first harmonics) in one perturbation.
constexpr double kDifferenceTolerance = 1e-13;
struct Perturbed {
  State end;
  std::vector<std::complex<double>> harmonics;
};

template <typename Perturb>
Perturbed CentralDifference(const SmoothCase& c, State start, double step, int harmonics, Perturb perturb) {
  const SineDrive drive{c.amplitude_v, c.frequency_hz, 0.0};
  FlowRequest request;
  request.harmonics = harmonics;
  // Tighter than the default tolerance, so that the quotient's noise (the flows' error over the step)
  // stays far below what is checked.
  FlowOptions tight;
  tight.relative_tolerance = kDifferenceTolerance;
  tight.absolute_tolerance_m = 1e-17;
  tight.absolute_tolerance_m_per_s = 1e-14;
  tight.absolute_tolerance_n = 1e-15;
  auto run = [&](double sign) {
    ActuatorModel model = c.model;
    State y = start;
    perturb(&model, &y, sign * step);
    return Flow(model, drive, y, 0.0, 1.0 / c.frequency_hz, request, tight);
  };
  const FlowResult plus = run(1.0), minus = run(-1.0);
  Perturbed d;
  d.end = CentralQuotient(plus.end, minus.end, step);
  for (int k = 0; k < harmonics; ++k)
    d.harmonics.push_back((plus.harmonic_integrals[k] - minus.harmonic_integrals[k]) / (2 * step));
  return d;
}

// |analytic - difference| against the column's own size, in the sweep's scaling. A harmonic's
// sensitivity can be much smaller than the harmonic (friction's smoothing velocity barely moves C_1):
// the difference quotient then carries the integrator's error over the step, `harmonic_noise`.
void ExpectColumn(const Scale& scale, State analytic, State difference, const std::vector<std::complex<double>>& h_analytic,
                  const std::vector<std::complex<double>>& h_difference, double tolerance, double harmonic_noise) {
  EXPECT_LE(scale.Norm(Difference(analytic, difference)), tolerance * scale.Norm(difference))
      << "analytic (" << analytic.x_m << ", " << analytic.v_m_per_s << ", " << analytic.coil_force_n << ") difference ("
      << difference.x_m << ", " << difference.v_m_per_s << ", " << difference.coil_force_n << ")";
  double size = 0.0, error = 0.0;
  for (size_t k = 0; k < h_difference.size(); ++k) {
    size = std::max(size, std::abs(h_difference[k]));
    error = std::max(error, std::abs(h_analytic[k] - h_difference[k]));
  }
  EXPECT_LE(error, tolerance * size + harmonic_noise) << "harmonic sensitivities";
}

TEST(VariationalFlowTest, EveryForceTermsSensitivitiesAreTheFlowsFiniteDifferences) {
  constexpr int kHarmonics = 3;
  // Central differences at a relative step of 1e-4: truncation ~1e-8, the flows' tolerance (1e-13)
  // over the step ~1e-9; the analytic sensitivities (at the default tolerances) must agree to 1e-6.
  constexpr double kRelativeStep = 1e-4, kTolerance = 1e-6;
  for (const SmoothCase& c : ForceTermCases()) {
    SCOPED_TRACE(c.name);
    const SineDrive drive{c.amplitude_v, c.frequency_hz, 0.0};
    const Scale scale = ScaleOf(c.model, c.frequency_hz);
    const State start = SettledStart(c.model, drive);
    FlowRequest request;
    request.monodromy = true;
    request.parameters = c.parameters;
    request.harmonics = kHarmonics;
    request.harmonic_sensitivities = true;
    const FlowResult flow = Flow(c.model, drive, start, 0.0, 1.0 / c.frequency_hz, request);
    ASSERT_GT(flow.contacts, 0) << "the case must exercise its stop";
    const double h_x = kRelativeStep * scale.length_m, h_v = kRelativeStep * scale.speed_m_per_s;
    double harmonic_size = 0.0;
    for (std::complex<double> q : flow.harmonic_integrals) harmonic_size = std::max(harmonic_size, std::abs(q));
    // Ten times the differenced flows' relative tolerance on the harmonics, over the difference's step.
    auto noise = [&](double step) { return 10 * kDifferenceTolerance * harmonic_size / step; };
    const Perturbed dx = CentralDifference(c, start, h_x, kHarmonics, [](ActuatorModel*, State* y, double e) { y->x_m += e; });
    ExpectColumn(scale, flow.columns[0], dx.end, flow.harmonic_sensitivities[0], dx.harmonics, kTolerance, noise(h_x));
    const Perturbed dv =
        CentralDifference(c, start, h_v, kHarmonics, [](ActuatorModel*, State* y, double e) { y->v_m_per_s += e; });
    ExpectColumn(scale, flow.columns[1], dv.end, flow.harmonic_sensitivities[1], dv.harmonics, kTolerance, noise(h_v));
    const int d = c.model.StateSize();
    if (d > 2) {
      const double h_e = kRelativeStep * scale.force_n;
      const Perturbed de =
          CentralDifference(c, start, h_e, kHarmonics, [](ActuatorModel*, State* y, double e) { y->coil_force_n += e; });
      ExpectColumn(scale, flow.columns[2], de.end, flow.harmonic_sensitivities[2], de.harmonics, kTolerance, noise(h_e));
    }
    for (size_t p = 0; p < c.parameters.size(); ++p) {
      const Field field = c.parameters[p];
      SCOPED_TRACE("parameter " + std::to_string(p));
      const double step = kRelativeStep * std::abs(c.model.*field);
      const Perturbed dp = CentralDifference(c, start, step, kHarmonics,
                                             [field](ActuatorModel* m, State*, double e) { m->*field += e; });
      ExpectColumn(scale, flow.columns[d + p], dp.end, flow.harmonic_sensitivities[d + p], dp.harmonics, kTolerance, noise(step));
    }
  }
}

// The map's derivative in the drive's frequency and amplitude (the continuation's parameter column),
// exact from the flow (the pass's end moving with the frequency), against central differences of
// the map at shifted drives.
TEST(VariationalFlowTest, DriveDerivativesAreTheMapsFiniteDifferences) {
  for (const SmoothCase& c : ForceTermCases()) {
    SCOPED_TRACE(c.name);
    const SineDrive drive{c.amplitude_v, c.frequency_hz, 0.0};
    const Scale scale = ScaleOf(c.model, c.frequency_hz);
    const State start = SettledStart(c.model, drive);
    const PeriodMap map(c.model, c.frequency_hz, c.amplitude_v);
    for (DriveParameter which : {DriveParameter::kFrequencyHz, DriveParameter::kAmplitudeV}) {
      const bool frequency = which == DriveParameter::kFrequencyHz;
      const State exact = map.Linearize(start, 1, which).d_end_d_drive;
      const double step = 1e-5 * (frequency ? c.frequency_hz : c.amplitude_v);
      auto apply = [&](double sign) {
        const PeriodMap shifted(c.model, c.frequency_hz + (frequency ? sign * step : 0.0),
                                c.amplitude_v + (frequency ? 0.0 : sign * step));
        return shifted.Apply(start);
      };
      const State plus = apply(1.0), minus = apply(-1.0);
      const State difference = CentralQuotient(plus, minus, step);
      EXPECT_LE(scale.Norm(Difference(exact, difference)), 1e-6 * scale.Norm(difference))
          << (frequency ? "frequency" : "amplitude") << ": exact (" << exact.x_m << ", " << exact.v_m_per_s
          << ") difference (" << difference.x_m << ", " << difference.v_m_per_s << ")";
    }
  }
}

// A record of two drive periods at 51.2 kHz from `start`, velocity included.
SimulationOptions TwoPeriodsAt51kHz(double frequency_hz, State start) {
  SimulationOptions sim;
  sim.sample_rate_hz = 51200.0;
  sim.duration_s = 2.0 / frequency_hz;
  sim.initial = start;
  sim.record_velocity = true;
  return sim;
}

// The largest |x|, |v| and |force| of a record: the scale of the samples' tolerances.
struct Peaks {
  double x_m = 0, v_m_per_s = 0, force_n = 0;
};
Peaks PeaksOf(const Record& record) {
  Peaks peaks;
  for (size_t n = 0; n < record.displacement_m.size(); ++n) {
    peaks.x_m = std::max(peaks.x_m, std::abs(record.displacement_m[n]));
    peaks.v_m_per_s = std::max(peaks.v_m_per_s, std::abs(record.velocity_m_per_s[n]));
    peaks.force_n = std::max(peaks.force_n, std::abs(record.force_n[n]));
  }
  return peaks;
}

// The samples on a record's grid from the dense output (what the fit's sampling correction analyses)
// against the exact engine's record of the same motion: 51.2 kHz over two periods, through contacts,
// a damped stop and clipping; displacement, velocity and force to 1e-8 of their largest values (the
// 7th-order interpolant between steps at the flow's tolerance 1e-11).
TEST(VariationalFlowTest, SamplesOnARecordsGridAreTheExactEnginesRecord) {
  for (const PwlCase& c : PiecewiseLinearCases()) {
    SCOPED_TRACE(c.name);
    const SineDrive drive{c.amplitude_v, c.frequency_hz, 0.0};
    const State start = SettledStart(c.model, drive);
    const SimulationOptions sim = TwoPeriodsAt51kHz(c.frequency_hz, start);
    const Record exact = MakeExactEngine()->Simulate(c.model, drive, sim);
    FlowRequest request;
    request.sample_count = static_cast<int>(exact.displacement_m.size());
    request.sample_interval_s = 1.0 / sim.sample_rate_hz;
    const double end_s = (request.sample_count - 1) * request.sample_interval_s;
    const FlowResult flow = Flow(c.model, drive, start, 0.0, end_s, request);
    ASSERT_EQ(flow.samples.size(), exact.displacement_m.size());
    ASSERT_EQ(flow.sample_force_n.size(), exact.force_n.size());
    const Peaks peaks = PeaksOf(exact);
    const double x_max = peaks.x_m, v_max = peaks.v_m_per_s, f_max = peaks.force_n;
    for (size_t n = 0; n < exact.displacement_m.size(); ++n) {
      ASSERT_NEAR(flow.samples[n].x_m, exact.displacement_m[n], 1e-8 * x_max) << "sample " << n;
      ASSERT_NEAR(flow.samples[n].v_m_per_s, exact.velocity_m_per_s[n], 1e-8 * v_max) << "sample " << n;
      ASSERT_NEAR(flow.sample_force_n[n], exact.force_n[n], 1e-8 * f_max) << "sample " << n;
    }
  }
}

// Hertzian contacts, whose two ends the flow integrates over u = sqrt(p) (variational_flow.cc's top),
// against CVODE's record of the same motion at rtol 1e-12 (an independent integrator that steps over
// t throughout): the samples at 51.2 kHz over two periods, and the end of a flow that stops at each
// sample instant within a contact (its end cut out of a step over u where it falls in an entry or a
// release). Lower and upper stops; to 1e-8 of the largest values, what the flow's tolerance of 1e-11
// and CVODE's leave after ~10 steps of error growth through each stiff contact.
TEST(VariationalFlowTest, HertzianContactsAreCvodesRecord) {
  ActuatorModel lower = PaperModel();
  lower.contact_law = ContactLaw::kHertzian;
  lower.contact_stiffness = 2.65e8;
  lower.cubic_stiffness_n_per_m3 = 2.5e7;
  ActuatorModel both = lower;
  both.upper_stop_m = 1.2e-3;
  ActuatorModel damped = lower;  // the force jumps at entry, and the release is at p > 0, over t
  damped.contact_damping_n_s_per_m = 15.0;
  const PwlCase cases[] = {{"lower_8Hz_0.5V", lower, 8.0, 0.5},
                           {"lower_13Hz_0.6V", lower, 13.0, 0.6},
                           {"both_10Hz_0.8V", both, 10.0, 0.8},
                           {"damped_8Hz_0.5V", damped, 8.0, 0.5}};
  for (const PwlCase& c : cases) {
    SCOPED_TRACE(c.name);
    const SineDrive drive{c.amplitude_v, c.frequency_hz, 0.0};
    const State start = SettledStart(c.model, drive);
    SimulationOptions sim = TwoPeriodsAt51kHz(c.frequency_hz, start);
    sim.cvode_relative_tolerance = 1e-12;
    sim.cvode_absolute_tolerance_m = 1e-17;
    sim.cvode_absolute_tolerance_m_per_s = 1e-14;
    const Record reference = MakeCvodeEngine()->Simulate(c.model, drive, sim);
    const size_t count = reference.displacement_m.size();
    const Peaks peaks = PeaksOf(reference);
    const double x_max = peaks.x_m, v_max = peaks.v_m_per_s, f_max = peaks.force_n;
    FlowRequest request;
    request.sample_count = static_cast<int>(count);
    request.sample_interval_s = 1.0 / sim.sample_rate_hz;
    const FlowResult flow = Flow(c.model, drive, start, 0.0, (count - 1) * request.sample_interval_s, request);
    ASSERT_GE(flow.contacts, 2);
    for (size_t n = 0; n < count; ++n) {
      ASSERT_NEAR(flow.samples[n].x_m, reference.displacement_m[n], 1e-8 * x_max) << "sample " << n;
      ASSERT_NEAR(flow.samples[n].v_m_per_s, reference.velocity_m_per_s[n], 1e-8 * v_max) << "sample " << n;
      ASSERT_NEAR(flow.sample_force_n[n], reference.force_n[n], 1e-8 * f_max) << "sample " << n;
    }
    int ends_in_contact = 0;
    for (size_t n = 1; n < count; ++n) {
      const double x = reference.displacement_m[n];
      if (!(x < c.model.lower_stop_m || x > c.model.upper_stop_m)) continue;
      ++ends_in_contact;
      const State end = Flow(c.model, drive, start, 0.0, n * request.sample_interval_s, {}).end;
      ASSERT_NEAR(end.x_m, x, 1e-8 * x_max) << "a flow ending at sample " << n;
      ASSERT_NEAR(end.v_m_per_s, reference.velocity_m_per_s[n], 1e-8 * v_max) << "a flow ending at sample " << n;
    }
    EXPECT_GE(ends_in_contact, 10);
  }
}

TEST(VariationalFlowTest, BadOptionsAndIntervalsNameTheField) {
  FlowOptions options;
  options.relative_tolerance = 0.0;
  try {
    Flow(PaperModel(), {0.5, 8.0, 0.0}, {}, 0.0, 0.1, {}, options);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "relative_tolerance");
  }
  EXPECT_THROW(Flow(PaperModel(), {0.5, 8.0, 0.0}, {}, 0.1, 0.0, {}), InputError);
  FlowRequest past_the_end;
  past_the_end.sample_count = 11;
  past_the_end.sample_interval_s = 0.01;  // the last at 0.1 s > t1
  EXPECT_THROW(Flow(PaperModel(), {0.5, 8.0, 0.0}, {}, 0.0, 0.05, past_the_end), InputError);
}

TEST(VariationalFlowTest, ASpentStepBudgetIsANumericalError) {
  FlowOptions options;
  options.max_steps = 10;
  EXPECT_THROW(Flow(PaperModel(), {0.5, 8.0, 0.0}, {}, 0.0, 1.0, {}, options), NumericalError);
}

}  // namespace
}  // namespace strokelab
