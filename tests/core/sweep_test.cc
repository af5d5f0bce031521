// Steady-state sweeps of the paper's model against closed forms, against time-domain stepped-sine
// sweeps (the second method), and against what the paper reports and reference values.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "strokelab/steady/continuation.h"
#include "strokelab/engines/engine.h"
#include "strokelab/model/linear_response.h"
#include "strokelab/engines/record_summary.h"
#include "strokelab/signal/signal.h"
#include "strokelab/sweep/stepped_sine.h"
#include "strokelab/sweep/sweep.h"
#include "test_util.h"

namespace strokelab {
namespace {

double Omega(double f_hz) { return 2 * std::numbers::pi * f_hz; }

// The contacting response where it coexists with the free one: reached from a state at the stop.
SteadyState ContactingAttractor(double f_hz, double amplitude_v) {
  const PeriodMap map(PaperModel(), f_hz, amplitude_v);
  return SolveAttractor(map, {-0.9e-3, 0.0});
}

SweepResult Sweep(GridAxis frequency, GridAxis amplitude, int threads = 1, bool thresholds = true) {
  SweepSpec spec;
  spec.model = PaperModel();
  spec.frequency_hz = frequency;
  spec.amplitude_v = amplitude;
  spec.threads = threads;
  spec.thresholds = thresholds;
  return RunSweep(spec);
}

// Whether 300 drive periods from `start` (on a contacting orbit) still reach the stop.
bool KeepsContact(const Engine& engine, const ActuatorModel& model, double f_hz, double amplitude_v, State start) {
  SimulationOptions options;
  options.duration_s = 300 / f_hz;
  options.sample_rate_hz = f_hz * 512;
  options.initial = start;
  const SineDrive drive{amplitude_v, f_hz, 0.0};
  return Summarize(engine.Simulate(model, drive, options), drive).contacts > 0;
}

TEST(SaturationThresholdTest, GrazingAmplitudeIsTheClosedForm) {
  const SweepResult r = Sweep({8.0, 13.0, 2}, {0.3, 0.3, 1});
  ASSERT_EQ(r.saturation_threshold.size(), 2u);
  // V_sat: 0.2610 V at 8 Hz, 0.4629 V at 13 Hz. Root-finding on the orbit, not the grid.
  EXPECT_NEAR(r.saturation_threshold[0].grazing_amplitude_v, 0.2610, 5e-5);
  EXPECT_NEAR(r.saturation_threshold[1].grazing_amplitude_v, 0.4629, 5e-5);
  for (const SaturationThreshold& t : r.saturation_threshold)
    EXPECT_REL_NEAR(t.grazing_amplitude_v, LinearSaturationThresholdV(PaperModel(), Omega(t.frequency_hz)), 1e-9);
  // Below resonance the contacting response reaches down to grazing; above it, well below.
  EXPECT_REL_NEAR(r.saturation_threshold[0].lowest_contact_amplitude_v, r.saturation_threshold[0].grazing_amplitude_v,
                  1e-9);
  EXPECT_LT(r.saturation_threshold[1].lowest_contact_amplitude_v, 0.92 * r.saturation_threshold[1].grazing_amplitude_v);
}

TEST(SaturationThresholdTest, LowestContactAmplitudeAgreesWithTheTimeDomain) {
  // At 13 Hz the contacting response is bistable with the free one down to a fold near 0.41 V.
  const SweepResult r = Sweep({13.0, 13.0, 1}, {0.3, 0.3, 1});
  const double lowest = r.saturation_threshold[0].lowest_contact_amplitude_v;
  EXPECT_NEAR(lowest, 0.4136, 0.001);  // from rest the stop is reached near 0.415 V
  // Second method: start on the contacting orbit at 0.45 V and run 300 periods at the lower amplitude.
  const SteadyState contacting = ContactingAttractor(13.0, 0.45);
  ASSERT_EQ(contacting.figures.contacts, 1);
  auto keeps_contact = [&](double amplitude_v) {
    return KeepsContact(*MakeExactEngine(), PaperModel(), 13.0, amplitude_v, contacting.start);
  };
  EXPECT_TRUE(keeps_contact(lowest + 0.002));
  EXPECT_FALSE(keeps_contact(lowest - 0.002));
}

// The same with the coil's pole (a third state, model.h): the grazing amplitude against the linear
// closed form with the pole (linear_response.h), and the contacting branch's fold, which the
// continuation finds in three state dimensions, against CVODE's time domain.
TEST(SaturationThresholdTest, WithTheCoilsPoleTheThresholdsAgreeWithClosedFormAndTimeDomain) {
  ActuatorModel coil = PaperModel();
  coil.coil_time_constant_s = 2e-3 / 3.0;
  coil.back_emf_damping_n_s_per_m = 0.8;
  SweepSpec spec;
  spec.model = coil;
  spec.frequency_hz = {13.0, 13.0, 1};
  spec.amplitude_v = {0.3, 0.3, 1};
  const SweepResult r = RunSweep(spec);
  ASSERT_EQ(r.saturation_threshold.size(), 1u);
  const SaturationThreshold& t = r.saturation_threshold[0];
  EXPECT_REL_NEAR(t.grazing_amplitude_v, LinearSaturationThresholdV(coil, Omega(13.0)), 1e-9);
  // The pole moves the grazing amplitude by more than the tolerance: the test sees it.
  EXPECT_GT(std::abs(LinearSaturationThresholdV(PaperModel(), Omega(13.0)) - t.grazing_amplitude_v),
            1e-3 * t.grazing_amplitude_v);
  const double lowest = t.lowest_contact_amplitude_v;
  ASSERT_LT(lowest, 0.97 * t.grazing_amplitude_v);  // bistable below grazing, as without the pole
  const PeriodMap map(coil, 13.0, lowest + 0.02);
  const SteadyState contacting = SolveAttractor(map, {-0.9e-3, 0.0});
  ASSERT_EQ(contacting.figures.contacts, 1);
  ASSERT_EQ(contacting.multipliers.size(), 3u);
  auto keeps_contact = [&](double amplitude_v) {
    return KeepsContact(*MakeCvodeEngine(), coil, 13.0, amplitude_v, contacting.start);
  };
  EXPECT_TRUE(keeps_contact(lowest + 0.002));
  EXPECT_FALSE(keeps_contact(lowest - 0.002));
}

TEST(SaturationThresholdTest, BelowResonanceAFoldCanLieJustUnderGrazing) {
  // At 5.5 Hz (about a third of the resonance) the impact rings the suspension and the contacting
  // branch folds back 1.8e-4 below grazing. Second method: a stepped-amplitude ramp down in the
  // time domain, the state carried from step to step, lets go of the stop within one step of it.
  const SweepResult r = Sweep({5.5, 5.5, 1}, {0.3, 0.3, 1});
  const double lowest = r.saturation_threshold[0].lowest_contact_amplitude_v;
  const double grazing = r.saturation_threshold[0].grazing_amplitude_v;
  ASSERT_LT(lowest, grazing * (1 - 1e-4));
  const double step_v = 2e-6 * grazing;
  State state = ContactingAttractor(5.5, grazing * 1.001).start;
  double last_touching_v = NAN, first_free_v = NAN;
  for (double v = grazing * 1.0001; v > lowest - 10 * step_v; v -= step_v) {
    SimulationOptions options;
    options.duration_s = 1000 / 5.5;
    options.sample_rate_hz = 5.5 * 64;
    options.initial = state;
    const SineDrive drive{v, 5.5, 0.0};
    const Record run = MakeExactEngine()->Simulate(PaperModel(), drive, options);
    state = run.final_state;
    if (Summarize(run, drive).contacts == 0) {
      first_free_v = v;
      break;
    }
    last_touching_v = v;
  }
  EXPECT_GE(last_touching_v, lowest);
  EXPECT_LT(first_free_v, lowest + step_v);
}

// The jump interval at one amplitude from continuation, and where stepped-sine sweeps jump.
void ExpectJumpMatchesSteppedSine(double amplitude_v) {
  const GridAxis eq1{5.0, 5.0 * std::pow(1.02, 116), 117, true};
  const SweepResult r = Sweep(eq1, {amplitude_v, amplitude_v, 1}, 1, false);
  ASSERT_EQ(r.jump.size(), 1u) << amplitude_v;
  const JumpInterval& jump = r.jump[0];
  EXPECT_EQ(jump.from_kind, "grazing");
  EXPECT_EQ(jump.to_kind, "fold");
  // The grazing end is where the free response touches the stop: V_sat(f) = V (linear_response.h).
  EXPECT_REL_NEAR(LinearSaturationThresholdV(PaperModel(), Omega(jump.bistable_from_hz)), amplitude_v, 1e-9);

  const std::vector<double> grid = PaperFrequencyGridHz();
  std::vector<double> down(grid.rbegin(), grid.rend());
  SteppedSineOptions options;
  options.settle_periods = 100;
  const auto up_sweep = SteppedSineSweep(PaperModel(), amplitude_v, grid, options);
  const auto down_sweep = SteppedSineSweep(PaperModel(), amplitude_v, down, options);
  const std::vector<size_t> up_jumps = JumpIndices(up_sweep), down_jumps = JumpIndices(down_sweep);
  ASSERT_EQ(up_jumps.size(), 1u);
  ASSERT_EQ(down_jumps.size(), 1u);
  // The up-sweep leaves the contacting branch at its fold, within one frequency step.
  EXPECT_LE(up_sweep[up_jumps[0]].frequency_hz, jump.bistable_to_hz);
  EXPECT_GT(up_sweep[up_jumps[0] + 1].frequency_hz, jump.bistable_to_hz);
  // The down-sweep leaves the free branch where it grazes, within one step.
  EXPECT_GE(down_sweep[down_jumps[0]].frequency_hz, jump.bistable_from_hz);
  EXPECT_LT(down_sweep[down_jumps[0] + 1].frequency_hz, jump.bistable_from_hz);

  // Where the sweep reports both branches, their FRFs are the stepped-sine ones. The stepped sine
  // settles for 100 periods only, hence 1e-6.
  for (size_t i = 0; i < grid.size(); ++i) {
    const SweepPoint* up = nullptr;
    for (const SweepPoint& p : r.points)
      if (p.frequency_hz == r.frequency_hz[i] && p.branch == Branch::kUp) up = &p;
    ASSERT_NE(up, nullptr);
    EXPECT_TRUE(::strokelab::testing::NearRelative(up->h, up_sweep[i].h, 1e-6)) << grid[i] << " Hz";
  }
}

TEST(JumpTest, AtHalfAVoltMatchesSteppedSineSweeps) { ExpectJumpMatchesSteppedSine(0.5); }
TEST(JumpTest, AtSixTenthsOfAVoltMatchesSteppedSineSweeps) { ExpectJumpMatchesSteppedSine(0.6); }

TEST(JumpTest, FoldIsWhereAMultiplierReachesOne) {
  const SteadyState start = ContactingAttractor(13.8, 0.5);
  ASSERT_EQ(start.figures.contacts, 1);
  const ContinuedBranch branch =
      ContinueBranch(PaperModel(), ContinuationParameter::kFrequencyHz, 0.5, 13.8, start.start, 13.0, 14.5, true);
  const BranchEvent* fold = nullptr;
  for (const BranchEvent& e : branch.events)
    if (e.kind == BranchEvent::Kind::kFold) fold = &e;
  ASSERT_NE(fold, nullptr);
  double closest = INFINITY;
  for (const auto& mu : fold->point.multipliers) closest = std::min(closest, std::abs(mu - 1.0));
  EXPECT_LT(closest, 1e-4);
  EXPECT_NEAR(fold->point.parameter, 14.0683387, 1e-6);
}

// A corrector that fails far from any grazing point (here made to fail at the fold of paper + k3 +
// Hertzian contact's contacting branch at 18.57 Hz, ~0.79 V, by two Newton iterations at most) stops
// the branch there. It once restarted past the grazing point of the non-contacting response at
// 1.0974 V, 0.3 V away, and reported that grazing point as the contacting branch's end: the map's
// lowest contacting amplitude then read 1.0974 V where CVODE holds a stable contacting orbit at 0.85 V.
TEST(ContinuationTest, AStallFarFromGrazingStopsTheBranchInsteadOfJumping) {
  ActuatorModel model = PaperModel();
  model.cubic_stiffness_n_per_m3 = 2.5e7;
  model.contact_law = ContactLaw::kHertzian;
  model.contact_stiffness = 2.65e8;
  constexpr double kFrequencyHz = 18.5678, kStartV = 1.42665;  // 1.3 x grazing, as SweepColumn starts
  const PeriodMap map(model, kFrequencyHz, kStartV);
  const std::optional<SteadyState> start = Shoot(map, map.ClippedLinearStart(), 1);
  ASSERT_TRUE(start);
  ContinuationOptions crippled;
  crippled.stop_at_first_event = true;
  crippled.max_corrector_iterations = 2;
  crippled.min_step = 1e-3;
  const ContinuedBranch branch = ContinueBranch(model, ContinuationParameter::kAmplitudeV, kFrequencyHz, kStartV,
                                                start->start, 0.05, 2.0 * kStartV, false, crippled);
  for (const BranchEvent& e : branch.events) EXPECT_NE(e.kind, BranchEvent::Kind::kGrazing) << e.point.parameter;
  for (const BranchPoint& p : branch.points) EXPECT_TRUE(p.contacting()) << "at " << p.parameter << " V";
  EXPECT_EQ(branch.stopped_because.rfind("corrector failed", 0), 0u) << branch.stopped_because;
  EXPECT_LT(branch.points.back().parameter, 0.85);  // it got near the fold before it stalled
}

// A smooth model's row whose continuation stops short (paper + dry friction at 0.53 V: the corrector
// fails near 14 Hz, inside a bistable interval) is restarted past where it stopped. Every grid point's up
// and down orbits are then the attractors a stepped sweep settles on: SolveAttractor frequency after
// frequency, carrying the state from 5 Hz up and from 20 Hz down (the period map stepped in time, no
// continuation). Before the restart, the down orbit at 13.68 Hz was the up orbit, and the jump interval
// was missing; the interval across the restart's gap is one.
TEST(SweepRowTest, ARowWhoseContinuationStopsShortIsRestarted) {
  ActuatorModel model = PaperModel();
  model.friction_force_n = 0.003;
  constexpr double kAmplitudeV = 0.53;
  std::vector<double> grid;
  for (int i = 0; i < 20; ++i) grid.push_back(5.0 + 15.0 * i / 19.0);
  const SweepRowResult row = SweepRow(model, kAmplitudeV, grid);
  ASSERT_EQ(row.jumps.size(), 1u);
  EXPECT_EQ(row.jumps[0].from_kind, "grazing");
  EXPECT_EQ(row.jumps[0].to_kind, "fold");
  EXPECT_LT(row.jumps[0].bistable_from_hz, grid[11]);  // 13.68 Hz is bistable
  EXPECT_GT(row.jumps[0].bistable_to_hz, grid[11]);

  // The first harmonic of the force [N] a stepped sweep settles on at each frequency of `order`.
  auto stepped = [&](std::vector<double> order) {
    std::vector<double> force(order.size());
    State state = PeriodMap(model, order.front(), kAmplitudeV).ClippedLinearStart();
    for (size_t i = 0; i < order.size(); ++i) {
      const SteadyState settled = SolveAttractor(PeriodMap(model, order[i], kAmplitudeV), state);
      state = settled.start;
      const double omega = 2.0 * std::numbers::pi * order[i];
      force[i] = model.mass_kg * omega * omega * std::abs(settled.figures.x1);
    }
    return force;
  };
  const std::vector<double> up = stepped(grid);
  std::vector<double> down = stepped(std::vector<double>(grid.rbegin(), grid.rend()));
  std::reverse(down.begin(), down.end());
  size_t unstable = 0;
  for (size_t i = 0; i < grid.size(); ++i) {
    for (const SweepPoint& p : row.points) {
      if (std::abs(p.frequency_hz - grid[i]) > 1e-9) continue;
      if (p.branch == Branch::kUp) {
        EXPECT_NEAR(p.first_harmonic_force_n, up[i], 1e-6 * up[i]) << grid[i] << " Hz, up";
      }
      if (p.branch == Branch::kDown) {
        EXPECT_NEAR(p.first_harmonic_force_n, down[i], 1e-6 * down[i]) << grid[i] << " Hz, down";
      }
      if (p.branch == Branch::kUnstable) ++unstable;
    }
  }
  EXPECT_GT(std::abs(up[11] / down[11] - 1.0), 0.1) << "13.68 Hz: two attractors";
  EXPECT_EQ(unstable, 1u);  // the saddle between them at 13.68 Hz
}

TEST(PeriodDoublingTest, JustPastGrazingAt8HzTheResponseIsPeriod2) {
  // At 8 Hz, 0.262-0.267 V, the period-1 orbit is unstable (a Floquet
  // multiplier below -1) and the response is period-2.
  const SweepResult r = Sweep({8.0, 8.0, 1}, {0.264, 0.264, 1}, 1, false);
  bool saw_unstable_period1 = false;
  for (const SweepPoint& p : r.points) {
    if (p.branch == Branch::kUp || p.branch == Branch::kDown) {
      EXPECT_EQ(p.period, 2);
      EXPECT_TRUE(p.stable);
      EXPECT_NEAR(p.contacts_per_period, 0.5, 1e-12);  // one impact every other period
    } else {
      saw_unstable_period1 = true;
      EXPECT_EQ(p.period, 1);
      EXPECT_GT(p.max_multiplier, 1.0);
    }
  }
  EXPECT_TRUE(saw_unstable_period1);
}

TEST(AttractorTest, SettledAttractorIsTheOneTheTimeDomainReaches) {
  // A paper-like model with a second stop at +1.45 mm (the diagnosis test's second_stop truth), at
  // 11 Hz / 0.5 V: from rest the motion settles on a period-2 orbit that touches the upper stop every
  // other period, while a stable two-contact period-1 orbit coexists (SolveAttractor's early Newton
  // lands there). Second method: 200 periods of the exact engine from rest.
  ActuatorModel m = PaperModel();
  m.stiffness_n_per_m = 114.493;
  m.damping_n_s_per_m = 1.19997;
  m.gain_n_per_v = 0.288994;
  m.lower_stop_m = -1.05036e-3;
  m.contact_stiffness = 1.17959e6;
  m.upper_stop_m = 1.45e-3;
  const PeriodMap map(m, 11.0, 0.5);
  const std::optional<SteadyState> settled = SettledAttractor(map, State{0.0, 0.0});
  ASSERT_TRUE(settled.has_value());
  EXPECT_EQ(settled->period, 2);
  EXPECT_TRUE(settled->stable);
  EXPECT_DOUBLE_EQ(settled->ContactsPerPeriod(), 1.5);
  const SteadyState newton_first = SolveAttractor(map, State{0.0, 0.0});
  EXPECT_EQ(newton_first.period, 1);
  EXPECT_TRUE(newton_first.stable);
  EXPECT_DOUBLE_EQ(newton_first.ContactsPerPeriod(), 2.0);

  SimulationOptions options;
  options.duration_s = 200 / 11.0;
  options.sample_rate_hz = 11.0 * 512;
  const Record run = MakeExactEngine()->Simulate(m, SineDrive{0.5, 11.0, 0.0}, options);
  size_t upper = 0, lower = 0;
  for (const ContactInterval& c : run.contacts)
    if (c.start_s > options.duration_s - 20 / 11.0) ++(c.upper ? upper : lower);
  EXPECT_EQ(upper, 10u);  // one every other period over the last 20
  EXPECT_EQ(lower, 20u);
  // The state after 200 periods is on the settled orbit (at phase 0 of one of its two periods).
  const State a = settled->start, b = map.Apply(a), end = run.final_state;
  const double off = std::min(std::hypot(end.x_m - a.x_m, (end.v_m_per_s - a.v_m_per_s) / (2 * std::numbers::pi * 11.0)),
                              std::hypot(end.x_m - b.x_m, (end.v_m_per_s - b.v_m_per_s) / (2 * std::numbers::pi * 11.0)));
  EXPECT_LT(off, 1e-9);  // m; the transient decays by ~0.18 per period
}

// SettledAttractor stops its plain periods once the motion repeats with period 1 or 2: the orbit it
// returns must be the one all 400 periods and the period search reach (the procedure it shortens),
// for a period-1 attractor (paper model, 8 Hz / 0.5 V, multipliers ~1e-3) and a period-2 one (8 Hz /
// 0.264 V, just past grazing), to the shooting tolerance.
TEST(AttractorTest, SettlingStopsOnceTheMotionRepeatsAndFindsTheSameOrbit) {
  for (const double amplitude_v : {0.5, 0.264}) {
    SCOPED_TRACE(amplitude_v);
    const PeriodMap map(PaperModel(), 8.0, amplitude_v);
    const std::optional<SteadyState> settled = SettledAttractor(map, map.ClippedLinearStart());
    ASSERT_TRUE(settled.has_value());
    State y = map.ClippedLinearStart();
    for (int i = 0; i < ShootingOptions{}.settle_periods; ++i) y = map.Apply(y);
    int period = 0;
    for (State z = map.Apply(y); period < 16; z = map.Apply(z))
      if (++period, std::hypot(z.x_m - y.x_m, z.v_m_per_s - y.v_m_per_s) < 1e-12) break;
    const std::optional<SteadyState> reference = Shoot(map, y, period);
    ASSERT_TRUE(reference.has_value());
    EXPECT_EQ(settled->period, amplitude_v == 0.5 ? 1 : 2);
    EXPECT_EQ(settled->period, reference->period);
    // The same orbit, though perhaps another of its phases for period 2: one of its periods' starts.
    double closest = INFINITY;
    State z = reference->start;
    for (int k = 0; k < reference->period; ++k, z = map.Apply(z))
      closest = std::min(closest, std::hypot((settled->start.x_m - z.x_m) / 1e-3,  // x / L, v / (w L)
                                             (settled->start.v_m_per_s - z.v_m_per_s) / 0.05));
    EXPECT_LT(closest, 1e-9);
  }
}

// Newton's iterates use Linearize, the reported orbit Trace: the two must agree bit for bit on what
// both compute, on a contacting orbit (switches, saltation) and a free one.
TEST(PeriodMapTest, LinearizeIsTraceWithoutTheFigures) {
  struct Case {
    double f_hz, amplitude_v;
    bool contacts;
  };
  for (const Case c : {Case{8.0, 0.5, true}, Case{30.0, 0.2, false}}) {
    const PeriodMap map(PaperModel(), c.f_hz, c.amplitude_v);
    const State y = map.ClippedLinearStart();
    const OrbitFigures full = map.Trace(y, 2), light = map.Linearize(y, 2);
    EXPECT_EQ(light.end.x_m, full.end.x_m);
    EXPECT_EQ(light.end.v_m_per_s, full.end.v_m_per_s);
    EXPECT_EQ(light.monodromy, full.monodromy);
    EXPECT_EQ(light.contacts, full.contacts);
    EXPECT_EQ(full.contacts > 0, c.contacts) << c.f_hz << " Hz";
    EXPECT_TRUE(std::isnan(light.min_displacement_m)) << "figures it does not compute must not look computed";
  }
}

TEST(SweepEngineTest, ResultsDoNotDependOnTheThreadCount) {
  const GridAxis f{6.0, 16.0, 24}, v{0.2, 0.6, 5};
  const SweepResult one = Sweep(f, v, 1), two = Sweep(f, v, 2);
  ASSERT_EQ(one.points.size(), two.points.size());
  for (size_t i = 0; i < one.points.size(); ++i) {
    EXPECT_EQ(one.points[i].frequency_hz, two.points[i].frequency_hz);
    EXPECT_EQ(one.points[i].branch, two.points[i].branch);
    EXPECT_EQ(one.points[i].h, two.points[i].h);
    EXPECT_EQ(one.points[i].min_displacement_m, two.points[i].min_displacement_m);
    EXPECT_EQ(one.points[i].period, two.points[i].period);
  }
  ASSERT_EQ(one.jump.size(), two.jump.size());
  for (size_t i = 0; i < one.jump.size(); ++i) EXPECT_EQ(one.jump[i].bistable_to_hz, two.jump[i].bistable_to_hz);
  for (size_t i = 0; i < one.saturation_threshold.size(); ++i)
    EXPECT_EQ(one.saturation_threshold[i].lowest_contact_amplitude_v,
              two.saturation_threshold[i].lowest_contact_amplitude_v);
}

TEST(SweepEngineTest, LinearResponseBelowSaturationIsEq3) {
  const SweepResult r = Sweep({5.0, 50.0, 30}, {0.1, 0.2, 2}, 1, false);
  for (const SweepPoint& p : r.points) {
    EXPECT_EQ(p.contacts_per_period, 0.0);
    EXPECT_REL_NEAR(p.h, ForceFrf(PaperModel(), Omega(p.frequency_hz)), 1e-9);
  }
}

TEST(SweepEngineTest, CancellationStopsTheSweep) {
  SweepSpec spec;
  spec.model = PaperModel();
  spec.frequency_hz = {5.0, 50.0, 200};
  spec.amplitude_v = {0.1, 0.6, 50};
  std::atomic<bool> cancel{false};
  size_t calls = 0;
  EXPECT_THROW(RunSweep(spec,
                        [&](const SweepProgress& p) {
                          ++calls;
                          EXPECT_EQ(p.total, 50u * 200u + 200u);  // grid points and threshold columns
                          cancel = true;
                        },
                        &cancel),
               Cancelled);
  EXPECT_EQ(calls, 1u);
}

// Progress comes in grid points, a row's as its continuation passes them (issue 16, point 11: a
// smooth model's row takes seconds, and a bar per row stood still that long): more reports than rows
// and columns, each count above the one before, the last the whole grid and its columns.
TEST(SweepEngineTest, ProgressCountsGridPointsAsTheRowsPassThem) {
  SweepSpec spec;
  spec.model = PaperModel();
  spec.frequency_hz = {5.0, 20.0, 30};
  spec.amplitude_v = {0.2, 0.4, 2};
  spec.threads = 2;
  std::vector<size_t> done;
  RunSweep(spec, [&](const SweepProgress& p) {
    EXPECT_EQ(p.total, 2u * 30u + 30u);
    done.push_back(p.done);
  });
  ASSERT_GT(done.size(), 2u + 30u);
  EXPECT_TRUE(std::is_sorted(done.begin(), done.end()));
  EXPECT_EQ(std::adjacent_find(done.begin(), done.end()), done.end()) << "a report without progress";
  EXPECT_EQ(done.back(), 90u);
}

// A strongly softening suspension (k3 = -1e9 N/m^3: the restoring force turns at 0.36 mm, no upper
// stop) escapes to infinity at 0.5 V but not at 1 mV: that row's steady states fail numerically.
// By default the failure fails the sweep; with skip_failed_units it leaves a hole and is listed.
TEST(SweepEngineTest, FailedRowsFailTheSweepOrLeaveAListedHole) {
  SweepSpec spec;
  spec.model = PaperModel();
  spec.model.cubic_stiffness_n_per_m3 = -1e9;
  spec.frequency_hz = {8.0, 9.0, 2};
  spec.amplitude_v = {0.001, 0.5, 2};
  spec.thresholds = false;
  spec.threads = 2;
  EXPECT_THROW(RunSweep(spec), NumericalError);
  spec.skip_failed_units = true;
  const SweepResult r = RunSweep(spec);
  ASSERT_EQ(r.failures.size(), 1u);
  EXPECT_EQ(r.failures[0].rfind("row at 0.5 V: ", 0), 0u) << r.failures[0];
  ASSERT_GE(r.points.size(), 2u);
  for (const SweepPoint& p : r.points) EXPECT_EQ(p.amplitude_v, 0.001);
  EXPECT_EQ(r.amplitude_v.size(), 2u);  // the grid as asked
  spec.model = PaperModel();
  EXPECT_TRUE(RunSweep(spec).failures.empty());
}

TEST(SweepEngineTest, BadSpecsNameTheField) {
  SweepSpec spec;
  spec.frequency_hz = {50.0, 5.0, 10};
  try {
    Validate(spec);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "frequency_hz.to");
  }
  spec.frequency_hz = {5.0, 50.0, 0};
  EXPECT_THROW(Validate(spec), InputError);
  spec.frequency_hz = {5.0, 50.0, 10};
  spec.threads = 0;
  try {
    Validate(spec);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "threads");
  }
}

}  // namespace
}  // namespace strokelab
