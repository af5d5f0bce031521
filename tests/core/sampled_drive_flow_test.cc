// The variational flow driven by a record's sampled voltage (dynamics.h's SampledDrive: a first-order
// hold), against the closed form of a linear oscillator driven by straight lines, the sine it samples
// (the hold's error falls as the square of the sample interval), and central differences of itself.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "strokelab/base/errors.h"
#include "strokelab/engines/variational_flow.h"
#include "strokelab/model/dynamics.h"
#include "strokelab/model/model.h"

namespace strokelab {
namespace {

SampledDrive Sampled(double sample_rate_hz, double duration_s, auto voltage_at) {
  SampledDrive drive{sample_rate_hz, {}};
  const int count = static_cast<int>(std::lround(duration_s * sample_rate_hz)) + 1;
  for (int k = 0; k < count; ++k) drive.voltage_v.push_back(voltage_at(k / sample_rate_hz));
  return drive;
}

// m x'' + c x' + k x = g b t from rest: x = (g b / k) t - g b c / k^2 plus the free motion that meets
// x(0) = x'(0) = 0 (underdamped: e^{-zeta wn t} (A cos wd t + B sin wd t)). [m]
State RampResponse(const ActuatorModel& m, double slope_v_per_s, double t) {
  if (t <= 0) return {};
  const double k = m.stiffness_n_per_m, c = m.damping_n_s_per_m, force_rate = m.gain_n_per_v * slope_v_per_s;
  const double sigma = c / (2 * m.mass_kg), wd = std::sqrt(k / m.mass_kg - sigma * sigma);
  const double a = force_rate * c / (k * k), b = (-force_rate / k + sigma * a) / wd;
  const double e = std::exp(-sigma * t), cs = std::cos(wd * t), sn = std::sin(wd * t);
  const double x = force_rate / k * t - force_rate * c / (k * k) + e * (a * cs + b * sn);
  const double v = force_rate / k + e * (-sigma * (a * cs + b * sn) + wd * (-a * sn + b * cs));
  return {x, v};
}

// A triangle (up at b for t1, then down at b) is exact in the hold when t1 is a sample instant, and
// the linear oscillator's response is the ramp's, R(t) - 2 R(t - t1) by superposition.
struct Triangle {
  ActuatorModel linear = StopFree(PaperModel());
  double slope = 2.0, corner_s = 0.1, fs = 1000.0, duration_s = 0.25;
  SampledDrive drive =
      Sampled(fs, duration_s, [this](double t) { return slope * (t <= corner_s ? t : 2 * corner_s - t); });
  State Exact(double t) const {
    const State up = RampResponse(linear, slope, t), down = RampResponse(linear, slope, t - corner_s);
    return State{up.x_m - 2 * down.x_m, up.v_m_per_s - 2 * down.v_m_per_s};
  }
  static ActuatorModel StopFree(ActuatorModel m) {
    m.lower_stop_m = ActuatorModel::kNoLowerStop;
    return m;
  }
};

// End state and every sample to 1e-9 of the largest |x| and |v|: the flow's tolerance 1e-11 after ~10^3
// steps.
TEST(SampledDriveFlowTest, ATriangleDriveIsTheLinearOscillatorsClosedForm) {
  const Triangle triangle;
  const ActuatorModel& linear = triangle.linear;
  const SampledDrive& drive = triangle.drive;
  const double duration_s = triangle.duration_s;
  auto exact = [&](double t) { return triangle.Exact(t); };
  FlowRequest request;
  request.sample_count = 240;
  request.sample_start_s = 0.0;
  request.sample_interval_s = 1.0 / 960.0;  // not the drive's grid: samples fall inside its intervals
  const FlowResult flow = Flow(linear, drive, State{}, 0.0, duration_s, request);
  double peak_x = 0, peak_v = 0;
  for (int n = 0; n < request.sample_count; ++n) {
    peak_x = std::max(peak_x, std::abs(exact(n / 960.0).x_m));
    peak_v = std::max(peak_v, std::abs(exact(n / 960.0).v_m_per_s));
  }
  ASSERT_GT(peak_x, 1e-4);
  EXPECT_NEAR(flow.end.x_m, exact(duration_s).x_m, 1e-9 * peak_x);
  EXPECT_NEAR(flow.end.v_m_per_s, exact(duration_s).v_m_per_s, 1e-9 * peak_v);
  ASSERT_EQ(flow.samples.size(), 240u);
  for (int n = 0; n < request.sample_count; ++n) {
    EXPECT_NEAR(flow.samples[n].x_m, exact(n / 960.0).x_m, 1e-9 * peak_x) << n;
    EXPECT_NEAR(flow.samples[n].v_m_per_s, exact(n / 960.0).v_m_per_s, 1e-9 * peak_v) << n;
  }
}

// The same triangle sampled on the drive's own grid, where the mass is clear of any stop: every step
// is the exact free-flight map (free_flight_map.h), a matrix exponential instead of a truncated series,
// so it meets the closed form to 1e-12 of the largest |x| and |v| (rounding over 250 products).
TEST(SampledDriveFlowTest, TheExactFreeFlightMapIsTheClosedForm) {
  const Triangle triangle;
  const double fs = triangle.fs;
  auto exact = [&](double t) { return triangle.Exact(t); };
  FlowRequest request;
  request.sample_count = 251;
  request.sample_start_s = 0.0;
  request.sample_interval_s = 1.0 / fs;
  const FlowResult flow = Flow(triangle.linear, triangle.drive, State{}, 0.0, triangle.duration_s, request);
  EXPECT_EQ(flow.exact_steps, 250);
  double peak_x = 0, peak_v = 0;
  for (int n = 0; n < request.sample_count; ++n) {
    peak_x = std::max(peak_x, std::abs(exact(n / fs).x_m));
    peak_v = std::max(peak_v, std::abs(exact(n / fs).v_m_per_s));
  }
  ASSERT_EQ(flow.samples.size(), 251u);
  for (int n = 0; n < request.sample_count; ++n) {
    EXPECT_NEAR(flow.samples[n].x_m, exact(n / fs).x_m, 1e-12 * peak_x) << n;
    EXPECT_NEAR(flow.samples[n].v_m_per_s, exact(n / fs).v_m_per_s, 1e-12 * peak_v) << n;
  }
}

// Two flows of the same request the same to 1e-8 of their largest sizes: each sample's x, v and force,
// each column's x, v and force at every sample, and the end state (DOP853's 1e-11 per step over
// thousands of steps, and the sensitivities' looser 1e-10).
void ExpectSameFlow(const FlowResult& exact, const FlowResult& reference, const std::string& name) {
  ASSERT_EQ(exact.samples.size(), reference.samples.size()) << name;
  ASSERT_EQ(exact.sample_slopes.size(), reference.sample_slopes.size()) << name;
  auto largest = [](const std::vector<double>& values, size_t first, size_t stride) {
    double size = 0;
    for (size_t i = first; i < values.size(); i += stride) size = std::max(size, std::abs(values[i]));
    return size;
  };
  std::vector<double> x, v;
  for (size_t n = 0; n < exact.samples.size(); ++n) {
    x.push_back(reference.samples[n].x_m);
    v.push_back(reference.samples[n].v_m_per_s);
  }
  const double x_size = largest(x, 0, 1), v_size = largest(v, 0, 1),
               force_size = largest(reference.sample_force_n, 0, 1);
  for (size_t n = 0; n < exact.samples.size(); ++n) {
    EXPECT_NEAR(exact.samples[n].x_m, x[n], 1e-8 * x_size) << name << " sample " << n;
    EXPECT_NEAR(exact.samples[n].v_m_per_s, v[n], 1e-8 * v_size) << name << " sample " << n;
    EXPECT_NEAR(exact.sample_force_n[n], reference.sample_force_n[n], 1e-8 * force_size) << name << " sample " << n;
  }
  // Each column's x, v and force at every sample, against that column's largest.
  const size_t columns = exact.columns.size(), per_sample = 3 * columns;
  for (size_t column = 0; column < columns; ++column)
    for (int k = 0; k < 3; ++k) {
      const size_t first = column * 3 + k;
      const double size = largest(reference.sample_slopes, first, per_sample);
      double error = 0;
      for (size_t i = first; i < exact.sample_slopes.size(); i += per_sample)
        error = std::max(error, std::abs(exact.sample_slopes[i] - reference.sample_slopes[i]));
      EXPECT_LE(error, 1e-8 * size) << name << " column " << column << " component " << k;
    }
  EXPECT_NEAR(exact.end.x_m, reference.end.x_m, 1e-8 * x_size) << name;
  EXPECT_NEAR(exact.end.v_m_per_s, reference.end.v_m_per_s, 1e-8 * v_size) << name;
}

// 40 harmonics of 5 Hz, each of 1.2 V / h at a random phase, sampled at fs: peaks of about 4 V.
SampledDrive Multisine(double fs, double duration_s) {
  std::mt19937 random(20261128);
  std::uniform_real_distribution<double> phase(0.0, 2 * std::numbers::pi);
  std::vector<double> phases;
  for (int h = 1; h <= 40; ++h) phases.push_back(phase(random));
  return Sampled(fs, duration_s, [&](double t) {
    double u = 0;
    for (int h = 1; h <= 40; ++h) u += 1.2 / h * std::sin(2 * std::numbers::pi * 5.0 * h * t + phases[h - 1]);
    return u;
  });
}

// The exact free-flight map against DOP853 throughout (FlowOptions::exact_free_flight false), with
// every sensitivity column, on models that hit their stops under a multisine sampled at 20 kHz: the
// map takes the intervals clear of the stops, DOP853 the ones near and in contact. End state, columns,
// and each sample's x, v, force and slopes the same to 1e-8 of their largest sizes (DOP853's 1e-11 per
// step over 6,000 steps, and the sensitivities' looser 1e-10). A model with a smooth nonlinear term
// (k3) or a parameter whose column is not affine (k3 at 0) takes no exact step. A clipped drive takes
// the map where its hold does not cross the limit.
TEST(SampledDriveFlowTest, TheExactFreeFlightMapIsDop853sFlow) {
  using M = ActuatorModel;
  const double fs = 20000.0, duration_s = 0.3;
  const SampledDrive drive = Multisine(fs, duration_s);
  ActuatorModel damped = PaperModel();
  damped.contact_damping_n_s_per_m = 15.0;
  damped.upper_stop_m = 1.2e-3;
  ActuatorModel hertz = PaperModel();
  hertz.contact_law = ContactLaw::kHertzian;
  hertz.contact_stiffness = 2.65e8;
  ActuatorModel coil = PaperModel();  // tau_e = 2 mH / 3 Ohm, with its back-EMF part of c_p
  coil.coil_time_constant_s = 2e-3 / 3.0;
  coil.back_emf_damping_n_s_per_m = 0.8;
  // Clipped at 2 V (over 1 in 20 of the samples lie beyond it, asserted below): within the limit, the
  // limit's column is unforced; beyond it, the drive is the limit itself and forces that column.
  ActuatorModel clipped = PaperModel();
  clipped.amplifier_limit_v = 2.0;
  ActuatorModel clipped_coil = coil;
  clipped_coil.amplifier_limit_v = 2.0;
  struct Case {
    std::string name;
    ActuatorModel model;
    std::vector<double M::*> parameters;
  };
  const std::vector<Case> cases = {
      {"paper", PaperModel(),
       {&M::mass_kg, &M::damping_n_s_per_m, &M::stiffness_n_per_m, &M::gain_n_per_v, &M::lower_stop_m,
        &M::contact_stiffness}},
      {"damped_two_stops", damped, {&M::stiffness_n_per_m, &M::upper_stop_m, &M::contact_damping_n_s_per_m}},
      {"hertzian", hertz, {&M::gain_n_per_v, &M::contact_stiffness}},
      {"coil_pole", coil, {&M::gain_n_per_v, &M::coil_time_constant_s, &M::back_emf_damping_n_s_per_m}},
      {"clipped", clipped, {&M::gain_n_per_v, &M::amplifier_limit_v, &M::lower_stop_m}},
      {"clipped_coil", clipped_coil, {&M::amplifier_limit_v, &M::coil_time_constant_s}},
  };
  const auto beyond = std::count_if(drive.voltage_v.begin(), drive.voltage_v.end(),
                                    [&](double u) { return std::abs(u) > clipped.amplifier_limit_v; });
  ASSERT_GT(beyond, std::ssize(drive.voltage_v) / 20);
  FlowOptions dop853_only;
  dop853_only.exact_free_flight = false;
  for (const Case& c : cases) {
    FlowRequest request;
    request.monodromy = true;
    request.parameters = c.parameters;
    request.sample_count = static_cast<int>(duration_s * fs) + 1;
    request.sample_start_s = 0.0;
    request.sample_interval_s = 1.0 / fs;
    request.sample_sensitivities = true;
    const State start{2e-4, -0.01, 0.0};
    const FlowResult exact = Flow(c.model, drive, start, 0.0, duration_s, request);
    const FlowResult reference = Flow(c.model, drive, start, 0.0, duration_s, request, dop853_only);
    ASSERT_GT(reference.contacts, 2) << c.name;
    EXPECT_EQ(exact.contacts, reference.contacts) << c.name;
    EXPECT_EQ(reference.exact_steps, 0) << c.name;
    EXPECT_GT(exact.exact_steps, request.sample_count / 2) << c.name;
    ExpectSameFlow(exact, reference, c.name);
  }
  ActuatorModel k3 = PaperModel();
  k3.cubic_stiffness_n_per_m3 = 4e7;
  FlowRequest plain;
  EXPECT_EQ(Flow(k3, drive, {}, 0.0, duration_s, plain).exact_steps, 0);
  FlowRequest k3_column;
  k3_column.parameters = {&M::cubic_stiffness_n_per_m3};
  EXPECT_EQ(Flow(PaperModel(), drive, {}, 0.0, duration_s, k3_column).exact_steps, 0);
  EXPECT_GT(Flow(PaperModel(), drive, {}, 0.0, duration_s, plain).exact_steps, 0);
}

// Clear of the stops, every interval of a clipped drive whose hold stays on one side of the limit takes
// the exact map, the many beyond it (the limit forcing its own column there) as well as those within;
// only those that cross it take DOP853. The flow is DOP853's throughout as in the test above.
TEST(SampledDriveFlowTest, AClippedDrivesIntervalsBeyondTheLimitTakeTheExactMap) {
  using M = ActuatorModel;
  const double fs = 20000.0, duration_s = 0.3, limit_v = 1.0;
  const SampledDrive drive = Multisine(fs, duration_s);
  ActuatorModel clipped = Triangle::StopFree(PaperModel());
  clipped.amplifier_limit_v = limit_v;
  ActuatorModel clipped_coil = clipped;  // tau_e = 2 mH / 3 Ohm, with its back-EMF part of c_p
  clipped_coil.coil_time_constant_s = 2e-3 / 3.0;
  clipped_coil.back_emf_damping_n_s_per_m = 0.8;
  auto side = [&](double u) { return u > limit_v ? 1 : u < -limit_v ? -1 : 0; };
  int one_side = 0, beyond = 0;
  for (size_t k = 0; k + 1 < drive.voltage_v.size(); ++k) {
    const int a = side(drive.voltage_v[k]), b = side(drive.voltage_v[k + 1]);
    one_side += a == b;
    beyond += a == b && a != 0;
  }
  ASSERT_GT(beyond, std::ssize(drive.voltage_v) / 5);
  FlowOptions dop853_only;
  dop853_only.exact_free_flight = false;
  for (const auto& [name, model] : {std::pair{"clipped", clipped}, std::pair{"clipped_coil", clipped_coil}}) {
    FlowRequest request;
    request.monodromy = true;
    request.parameters = {&M::gain_n_per_v, &M::amplifier_limit_v, &M::damping_n_s_per_m};
    if (model.coil_time_constant_s > 0) request.parameters.push_back(&M::coil_time_constant_s);
    request.sample_count = static_cast<int>(duration_s * fs) + 1;
    request.sample_start_s = 0.0;
    request.sample_interval_s = 1.0 / fs;
    request.sample_sensitivities = true;
    const State start{2e-4, -0.01, 0.0};
    const FlowResult exact = Flow(model, drive, start, 0.0, duration_s, request);
    const FlowResult reference = Flow(model, drive, start, 0.0, duration_s, request, dop853_only);
    EXPECT_EQ(exact.contacts, 0) << name;
    EXPECT_EQ(exact.exact_steps, one_side) << name;
    ExpectSameFlow(exact, reference, name);
  }
}

// The field jumps where the drive crosses the amplifier's limit (the limit's column, and a sine's
// amplitude and frequency columns, are forced beyond it only). The flow splits each crossing into
// instants on either side, so that no DOP853 step sees the other side at its end. Clear of the stops,
// a clipped multisine's flow then rejects no more steps than the same flow unclipped, and a clipped
// sine's at most one per crossing more (7 here: the first step back within the limit, as long as the
// steps beyond it, where its columns are unforced, may be too long for their forcing there). Before the
// split, a step ending at a crossing computed to rounding was rejected until short enough to pass:
// 311 and 302 rejections here.
TEST(SampledDriveFlowTest, ACrossingOfTheLimitCostsNoRejectedStep) {
  using M = ActuatorModel;
  const ActuatorModel unclipped = Triangle::StopFree(PaperModel());
  ActuatorModel clipped = unclipped;
  clipped.amplifier_limit_v = 1.0;
  FlowOptions dop853_only;
  dop853_only.exact_free_flight = false;
  const double duration_s = 0.3;
  const SampledDrive multisine = Multisine(20000.0, duration_s);
  const SineDrive sine{2.0, 10.0, 0.3};
  int crossings = 0;  // of the sine: 4 per period
  for (double t = 0; t < duration_s; t += 1e-5)
    crossings += (std::abs(sine.Voltage(t)) > 1.0) != (std::abs(sine.Voltage(t + 1e-5)) > 1.0);
  ASSERT_EQ(crossings, 12);
  FlowRequest request;
  request.parameters = {&M::gain_n_per_v, &M::amplifier_limit_v};
  auto rejected = [&](const ActuatorModel& model, const auto& drive) {
    return Flow(model, drive, {}, 0.0, duration_s, request, dop853_only).rejected_steps;
  };
  EXPECT_LE(rejected(clipped, multisine), rejected(unclipped, multisine));
  request.drive_amplitude = request.drive_frequency = true;
  EXPECT_LE(rejected(clipped, sine), rejected(unclipped, sine) + crossings);
}

struct SineCase {
  std::string name;
  ActuatorModel model;
};

// A sine sampled at fs: the hold misses it by at most V (w / fs)^2 / 8, so the motion it drives
// departs from the sine's by O(fs^-2): halving the interval quarters the difference (3 to 5 allows
// for the next order). Through contacts of a linear stop, a Hertzian stop (integrated over sqrt(p) at
// its ends, where steps now also end at samples), and the amplifier's clipping (whose corners the flow
// locates on the hold's straight lines).
TEST(SampledDriveFlowTest, ASampledSineConvergesToTheSineAtSecondOrder) {
  std::vector<SineCase> cases;
  cases.push_back({"paper", PaperModel()});
  ActuatorModel hertz = PaperModel();
  hertz.contact_law = ContactLaw::kHertzian;
  hertz.contact_stiffness = 2.65e8;
  cases.push_back({"hertzian", hertz});
  ActuatorModel clipped = PaperModel();
  clipped.amplifier_limit_v = 0.35;
  cases.push_back({"clipped", clipped});
  const SineDrive sine{0.5, 10.0, 0.3};
  const double duration_s = 0.3;
  for (const SineCase& c : cases) {
    const FlowResult reference = Flow(c.model, sine, State{}, 0.0, duration_s, {});
    ASSERT_GT(reference.contacts, 0) << c.name;
    double error[2];
    for (int i = 0; i < 2; ++i) {
      const double fs = 2000.0 * (1 << i);
      const FlowResult flow =
          Flow(c.model, Sampled(fs, duration_s, [&](double t) { return sine.Voltage(t); }), State{}, 0.0,
               duration_s, {});
      error[i] = std::hypot((flow.end.x_m - reference.end.x_m) / LengthScaleM(c.model),
                            (flow.end.v_m_per_s - reference.end.v_m_per_s) /
                                (LengthScaleM(c.model) * sine.AngularFrequency()));
      EXPECT_EQ(flow.contacts, reference.contacts) << c.name << " at " << fs << " Hz";
    }
    EXPECT_GT(error[1], 1e-9) << c.name << ": the hold's error must stand above the integrator's";
    EXPECT_GT(error[0] / error[1], 3.0) << c.name;
    EXPECT_LT(error[0] / error[1], 5.0) << c.name;
  }
}

// A multisine-like voltage (random phases, 5..200 Hz, amplitudes falling as 1 / f) at 5 kHz into
// paper + k3 with a damped stop: the columns d/d(initial state) and d/dp against central differences
// of the flow's end at a relative step of 1e-4 (truncation ~1e-8), flows run at 1e-13 so that their
// error over the step, 10 * 1e-13 / step in the sweep's scaling, is the quotient's noise. Agreement to
// 1e-6 of the column's size, or within that noise for a column that is nearly zero; the same for each
// column's x, v and blocked force at every sample (what an output-error fit's Jacobian is made of).
TEST(SampledDriveFlowTest, SensitivitiesAreTheFlowsFiniteDifferences) {
  using M = ActuatorModel;
  ActuatorModel model = PaperModel();
  model.cubic_stiffness_n_per_m3 = 4e7;
  model.contact_damping_n_s_per_m = 15.0;
  std::mt19937 random(20261127);
  std::uniform_real_distribution<double> phase(0.0, 2 * std::numbers::pi);
  std::vector<double> phases;
  for (int h = 1; h <= 40; ++h) phases.push_back(phase(random));
  const double duration_s = 0.3;
  const SampledDrive drive = Sampled(5000.0, duration_s, [&](double t) {
    double u = 0;
    for (int h = 1; h <= 40; ++h) u += 1.0 / h * std::sin(2 * std::numbers::pi * 5.0 * h * t + phases[h - 1]);
    return u;
  });
  const std::vector<double M::*> parameters = {&M::mass_kg,      &M::damping_n_s_per_m,
                                               &M::stiffness_n_per_m, &M::gain_n_per_v,
                                               &M::lower_stop_m, &M::contact_stiffness,
                                               &M::contact_damping_n_s_per_m, &M::cubic_stiffness_n_per_m3};
  FlowRequest request;
  request.monodromy = true;
  request.parameters = parameters;
  request.sample_count = 300;  // every 1 ms, with each column's x, v and force there
  request.sample_start_s = 0.0;
  request.sample_interval_s = 1e-3;
  request.sample_sensitivities = true;
  const State start{2e-4, -0.01};
  const FlowResult flow = Flow(model, drive, start, 0.0, duration_s, request);
  ASSERT_GT(flow.contacts, 2);
  const size_t columns = 2 + parameters.size();
  ASSERT_EQ(flow.sample_slopes.size(), 300 * columns * 3);
  FlowOptions tight;
  tight.relative_tolerance = 1e-13;
  tight.absolute_tolerance_m = 1e-17;
  tight.absolute_tolerance_m_per_s = 1e-14;
  FlowRequest samples_only = request;
  samples_only.monodromy = false;
  samples_only.parameters.clear();
  samples_only.sample_sensitivities = false;
  const double length = LengthScaleM(model), speed = length * 2 * std::numbers::pi * 10.0;
  double force_scale = 0.0;
  for (double f : flow.sample_force_n) force_scale = std::max(force_scale, std::abs(f));
  auto norm = [&](State s) { return std::hypot(s.x_m / length, s.v_m_per_s / speed); };
  // The flow of the model and start perturbed by e in one column's direction.
  using Perturbed = std::function<FlowResult(double e)>;
  auto check = [&](const std::string& what, size_t column, double step, const Perturbed& run) {
    const FlowResult a = run(step), b = run(-step), a_half = run(0.5 * step), b_half = run(-0.5 * step);
    const double noise = 10 * 1e-13 / step;  // the flows' error over the step, in the scaled units
    const State quotient{(a.end.x_m - b.end.x_m) / (2 * step), (a.end.v_m_per_s - b.end.v_m_per_s) / (2 * step)};
    const State analytic = flow.columns[column];
    const State difference{analytic.x_m - quotient.x_m, analytic.v_m_per_s - quotient.v_m_per_s};
    EXPECT_LT(norm(difference), 1e-6 * norm(quotient) + noise) << what;
    // At the samples: x, v and the force, each against the largest over the samples of its quotient.
    // Where a contact's start moves across a sample within the step, or next to a grazing contact
    // (where the motion is not smooth in the parameters), the quotient has not converged: a sample is
    // judged where the quotient at half the step agrees with it to 1e-6, and those are nearly all.
    double size[3] = {0, 0, 0}, error[3] = {0, 0, 0};
    int judged = 0;
    auto quotients = [](const FlowResult& p, const FlowResult& m, size_t n, double h, double* q) {
      q[0] = (p.samples[n].x_m - m.samples[n].x_m) / (2 * h);
      q[1] = (p.samples[n].v_m_per_s - m.samples[n].v_m_per_s) / (2 * h);
      q[2] = (p.sample_force_n[n] - m.sample_force_n[n]) / (2 * h);
    };
    std::vector<std::array<double, 3>> q(300), q_half(300);
    for (size_t n = 0; n < 300; ++n) {
      quotients(a, b, n, step, q[n].data());
      quotients(a_half, b_half, n, 0.5 * step, q_half[n].data());
      for (int k = 0; k < 3; ++k) size[k] = std::max(size[k], std::abs(q[n][k]));
    }
    for (size_t n = 0; n < 300; ++n) {
      bool converged = true;
      for (int k = 0; k < 3; ++k) converged = converged && std::abs(q[n][k] - q_half[n][k]) <= 1e-6 * size[k];
      if (!converged) continue;
      ++judged;
      for (int k = 0; k < 3; ++k)
        error[k] = std::max(error[k], std::abs(flow.sample_slopes[(n * columns + column) * 3 + k] - q[n][k]));
    }
    EXPECT_GE(judged, 290) << what;
    const double unit[3] = {length, speed, force_scale};
    // The force within a contact is k_s (1e4 k_p) times the penetration d - x, a difference of two
    // nearly equal displacements: its slope keeps fewer digits (3e-6).
    const double tolerance[3] = {1e-6, 1e-6, 3e-6};
    for (int k = 0; k < 3; ++k)
      EXPECT_LT(error[k], tolerance[k] * size[k] + noise * unit[k]) << what << " samples " << k;
  };
  const double dx = 1e-4 * length, dv = 1e-4 * speed;
  check("x0", 0, dx, [&](double e) {
    return Flow(model, drive, {start.x_m + e, start.v_m_per_s}, 0.0, duration_s, samples_only, tight);
  });
  check("v0", 1, dv, [&](double e) {
    return Flow(model, drive, {start.x_m, start.v_m_per_s + e}, 0.0, duration_s, samples_only, tight);
  });
  for (size_t p = 0; p < parameters.size(); ++p) {
    check("parameter " + std::to_string(p), 2 + p, 1e-4 * std::abs(model.*parameters[p]), [&](double e) {
      ActuatorModel perturbed = model;
      perturbed.*parameters[p] += e;
      return Flow(perturbed, drive, start, 0.0, duration_s, samples_only, tight);
    });
  }
}

// A stop met at a sample instant of the drive, where every step ends: the switch lands on the step's
// end up to rounding, and the step left to it is shorter than t resolves. With the stop 1e-15..1e-13 of
// its distance inside the motion's position at that instant, the flow must go on as it does with the
// stop 1e-9 inside, met clearly before the instant (the motion depends continuously on d): the end
// state the same to 1e-6 of the largest |x| and of |v|. (The code before threw "the step fell below the
// resolution of t" here.)
TEST(SampledDriveFlowTest, AStopMetAtASampleInstantIsPassed) {
  const double fs = 1000.0, duration_s = 0.1, meet_s = 0.05;
  const SampledDrive drive = Sampled(fs, duration_s, [](double t) { return -20.0 * t; });
  ActuatorModel stop_free = PaperModel();
  stop_free.lower_stop_m = ActuatorModel::kNoLowerStop;
  FlowRequest at_meeting;
  at_meeting.sample_count = 1;
  at_meeting.sample_start_s = meet_s;
  at_meeting.sample_interval_s = 1.0 / fs;
  const double x_meet = Flow(stop_free, drive, State{}, 0.0, meet_s, at_meeting).samples[0].x_m;
  ASSERT_LT(x_meet, 0.0);
  ActuatorModel reference = PaperModel();
  reference.lower_stop_m = x_meet * (1.0 - 1e-9);
  const FlowResult beside = Flow(reference, drive, State{}, 0.0, duration_s, {});
  ASSERT_GT(beside.contacts, 0);
  for (double inside : {1e-15, 3e-15, 1e-14, 3e-14, 1e-13}) {
    ActuatorModel m = PaperModel();
    m.lower_stop_m = x_meet * (1.0 - inside);
    FlowResult flow;
    ASSERT_NO_THROW(flow = Flow(m, drive, State{}, 0.0, duration_s, {})) << inside;
    const double largest_m = std::max(std::abs(beside.max_displacement_m), std::abs(beside.min_displacement_m));
    EXPECT_NEAR(flow.end.x_m, beside.end.x_m, 1e-6 * largest_m) << inside;
    EXPECT_NEAR(flow.end.v_m_per_s, beside.end.v_m_per_s, 1e-6 * std::abs(beside.end.v_m_per_s) + 1e-9) << inside;
  }
}

TEST(SampledDriveFlowTest, BadDrivesAndRequestsNameTheField) {
  const ActuatorModel model = PaperModel();
  auto field_of = [&](const SampledDrive& drive, const FlowRequest& request) -> std::string {
    try {
      Flow(model, drive, State{}, 0.0, 0.01, request);
    } catch (const InputError& e) {
      return e.field();
    }
    return "";
  };
  const SampledDrive good{1000.0, std::vector<double>(20, 0.1)};
  EXPECT_EQ(field_of(good, {}), "");
  FlowRequest harmonics;
  harmonics.harmonics = 2;
  EXPECT_EQ(field_of(good, harmonics), "harmonics");
  FlowRequest amplitude;
  amplitude.drive_amplitude = true;
  EXPECT_EQ(field_of(good, amplitude), "drive_amplitude");
  SampledDrive nan = good;
  nan.voltage_v[7] = std::nan("");
  EXPECT_EQ(field_of(nan, {}), "voltage_v");
  EXPECT_EQ(field_of(SampledDrive{1000.0, {0.1}}, {}), "voltage_v");
  EXPECT_EQ(field_of(SampledDrive{0.0, good.voltage_v}, {}), "sample_rate_hz");
}

}  // namespace
}  // namespace strokelab
