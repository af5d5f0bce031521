// Timings of the steady-state sweep engine (sweep.h) and of one steady state (steady_state.h) on the
// paper model (Table 2), and on the two smooth models of issue 12's speed targets: paper + k3 = 4e7
// N/m^3 ("k3") and paper + k3 = 2.5e7 N/m^3 with Hertzian contact, k_s = 2.65e8 N/m^1.5
// ("k3_hertzian"). Run a Release build, e.g.
//   sweep_bench                                   # everything, ~1 min on 2 cores (plus the smooth
//                                                 # cases: ~1 min more with the CVODE period map)
//   sweep_bench --benchmark_filter=Steady         # only the one-steady-state microbenchmarks
//   sweep_bench --benchmark_filter='k3|Smooth'    # only the smooth models
// A sweep takes ~1 s, so the grid benchmarks run a fixed small number of iterations in real time
// (wall clock: the pool's threads do the work, not the benchmark thread). Counters:
//   points_per_s           grid points (frequency x amplitude) per second of wall time
//   points_per_s_per_core  the same divided by the thread count (1 on one thread; on 2 threads
//                          lower than that when the load is uneven or the machine is busy)
//   steady_states          points reported (up + down + unstable branches) per sweep
// tests/bench/compare_scipy.py --sweep (--smooth) times `strokelab sweep` on the paper model (on the
// k3 model) against brute-force integration with scipy's LSODA.
#include <benchmark/benchmark.h>

#include <cmath>
#include <stdexcept>

#include "strokelab/model/model.h"
#include "strokelab/signal/signal.h"
#include "strokelab/steady/steady_state.h"
#include "strokelab/sweep/sweep.h"

namespace strokelab {
namespace {

constexpr int kSweepIterations = 3;  // ~1-2 s each; 3 gives a usable median without repetitions

void Report(benchmark::State& state, const SweepSpec& spec, size_t steady_states) {
  const double grid_points = static_cast<double>(spec.frequency_hz.points) * spec.amplitude_v.points;
  const double total = grid_points * static_cast<double>(state.iterations());
  state.counters["points_per_s"] = benchmark::Counter(total, benchmark::Counter::kIsRate);
  state.counters["points_per_s_per_core"] =
      benchmark::Counter(total / spec.threads, benchmark::Counter::kIsRate);
  state.counters["grid_points"] = grid_points;
  state.counters["steady_states"] = static_cast<double>(steady_states);
  state.counters["threads"] = spec.threads;
}

void RunAndReport(benchmark::State& state, const SweepSpec& spec) {
  size_t steady_states = 0;
  for (auto _ : state) {
    SweepResult result = RunSweep(spec);
    steady_states = result.points.size();
    benchmark::DoNotOptimize(result.points.data());
  }
  Report(state, spec, steady_states);
}

// (a), (b): a 200 x 200 linear grid, 5 .. 50 Hz x 0.1 .. 0.6 V; range(0) threads, range(1)
// thresholds (saturation threshold per frequency and jump intervals per amplitude) on or off.
void BM_Sweep200x200(benchmark::State& state) {
  SweepSpec spec;
  spec.model = PaperModel();
  spec.frequency_hz = GridAxis{5.0, 50.0, 200, false};
  spec.amplitude_v = GridAxis{0.1, 0.6, 200, false};
  spec.threads = static_cast<int>(state.range(0));
  spec.thresholds = state.range(1) != 0;
  RunAndReport(state, spec);
}
BENCHMARK(BM_Sweep200x200)
    ->ArgNames({"threads", "thresholds"})
    ->Args({1, 1})
    ->Args({2, 1})
    ->Args({1, 0})
    ->Args({2, 0})
    ->Iterations(kSweepIterations)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

// (c): the paper's grid, Eq. 1 (117 frequencies, 5 Hz * 1.02^(n-1)) x 0.1 .. 0.6 V in 0.1 V steps
// (section 3), one thread, thresholds on: what `strokelab sweep --grid eq1` computes.
void BM_SweepPaperGrid(benchmark::State& state) {
  const std::vector<double> eq1 = PaperFrequencyGridHz(117);
  SweepSpec spec;
  spec.model = PaperModel();
  spec.frequency_hz = GridAxis{eq1.front(), eq1.back(), static_cast<int>(eq1.size()), true};
  spec.amplitude_v = GridAxis{0.1, 0.6, 6, false};
  spec.threads = 1;
  spec.thresholds = state.range(0) != 0;
  // The geometric axis must reproduce Eq. 1, or this is not the paper's grid.
  const std::vector<double> axis = spec.frequency_hz.Values();
  for (size_t i = 0; i < eq1.size(); ++i) {
    if (std::abs(axis[i] - eq1[i]) > 1e-9 * eq1[i]) {
      state.SkipWithError("geometric GridAxis does not reproduce paper Eq. 1");
      return;
    }
  }
  RunAndReport(state, spec);
}
BENCHMARK(BM_SweepPaperGrid)
    ->ArgName("thresholds")
    ->Arg(1)
    ->Arg(0)
    ->Iterations(5)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

// The smooth models (see the top): the cubic stiffening the diagnosis names on campaign-a, and with it
// the contact stiffness that grows with impact strength (the paper's Sec. 5-6).
ActuatorModel CubicModel() {
  ActuatorModel model = PaperModel();
  model.cubic_stiffness_n_per_m3 = 4e7;
  return model;
}

ActuatorModel CubicHertzianModel() {
  ActuatorModel model = PaperModel();
  model.cubic_stiffness_n_per_m3 = 2.5e7;
  model.contact_law = ContactLaw::kHertzian;
  model.contact_stiffness = 2.65e8;
  return model;
}

// One steady state at 8 Hz / 0.5 V; Newton from the clipped linear start (the sweep's start at the
// first grid frequency).
void ShootAt8Hz05V(benchmark::State& state, const ActuatorModel& model) {
  const PeriodMap map(model, 8.0, 0.5);
  const State start = map.ClippedLinearStart();
  int newton = 0, contacts = 0;
  for (auto _ : state) {
    const std::optional<SteadyState> s = Shoot(map, start, 1);
    if (!s) {
      state.SkipWithError("Shoot did not converge at 8 Hz / 0.5 V");
      return;
    }
    newton = s->newton_iterations;
    contacts = s->figures.contacts;
    benchmark::DoNotOptimize(s->figures.x1);
  }
  state.counters["newton_iterations"] = newton;
  state.counters["contacts_per_period"] = contacts;
}

// Paper model at 8 Hz / 0.5 V: saturating, period 1, one contact per period.
void BM_SteadyShoot_8Hz_0_5V(benchmark::State& state) { ShootAt8Hz05V(state, PaperModel()); }
BENCHMARK(BM_SteadyShoot_8Hz_0_5V)->Unit(benchmark::kMicrosecond);

void BM_SteadyShootSmooth_8Hz_0_5V(benchmark::State& state, ActuatorModel (*model)()) {
  ShootAt8Hz05V(state, model());
}
BENCHMARK_CAPTURE(BM_SteadyShootSmooth_8Hz_0_5V, k3, CubicModel)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_SteadyShootSmooth_8Hz_0_5V, k3_hertzian, CubicHertzianModel)->Unit(benchmark::kMicrosecond);

// The sweep's own call at a grid point (SolveAttractor from the clipped linear start): plain
// iterations, Newton on period 1 and its multipliers, and on when period 1 is unstable.
void AttractorAt(benchmark::State& state, const ActuatorModel& model, double frequency_hz, double amplitude_v) {
  const PeriodMap map(model, frequency_hz, amplitude_v);
  const State start = map.ClippedLinearStart();
  int period = 0, contacts = 0;
  for (auto _ : state) {
    const SteadyState s = SolveAttractor(map, start);
    period = s.period;
    contacts = s.figures.contacts;
    benchmark::DoNotOptimize(s.figures.x1);
  }
  state.counters["period"] = period;
  state.counters["contacts_per_orbit"] = contacts;
}

// A smooth model at 8 Hz / 0.5 V: period 1, one contact per period.
void BM_SteadyAttractorSmooth_8Hz_0_5V(benchmark::State& state, ActuatorModel (*model)()) {
  AttractorAt(state, model(), 8.0, 0.5);
}
BENCHMARK_CAPTURE(BM_SteadyAttractorSmooth_8Hz_0_5V, k3, CubicModel)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_SteadyAttractorSmooth_8Hz_0_5V, k3_hertzian, CubicHertzianModel)
    ->Unit(benchmark::kMicrosecond);

// 8 Hz / 0.264 V: just past grazing, where the response is period 2: the period-1
// orbit is unstable, so SolveAttractor settles by plain iteration and shoots on period 2.
void BM_SteadyAttractor_8Hz_0_264V(benchmark::State& state) { AttractorAt(state, PaperModel(), 8.0, 0.264); }
BENCHMARK(BM_SteadyAttractor_8Hz_0_264V)->Unit(benchmark::kMicrosecond);

// The cost unit under both: one drive period of the map without and with the monodromy and figures
// (8 Hz / 0.5 V, on the orbit); range(0) = trace.
void PeriodMapAt8Hz05V(benchmark::State& state, const ActuatorModel& model) {
  const PeriodMap map(model, 8.0, 0.5);
  const std::optional<SteadyState> s = Shoot(map, map.ClippedLinearStart(), 1);
  if (!s) {
    state.SkipWithError("Shoot did not converge at 8 Hz / 0.5 V");
    return;
  }
  const bool trace = state.range(0) != 0;
  for (auto _ : state) {
    if (trace) {
      OrbitFigures f = map.Trace(s->start, 1);
      benchmark::DoNotOptimize(f);
    } else {
      State y = map.Apply(s->start);
      benchmark::DoNotOptimize(y);
    }
  }
  state.counters["periods_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

// The paper model: the closed form.
void BM_PeriodMap_8Hz_0_5V(benchmark::State& state) { PeriodMapAt8Hz05V(state, PaperModel()); }
BENCHMARK(BM_PeriodMap_8Hz_0_5V)->ArgName("trace")->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

void BM_PeriodMapSmooth_8Hz_0_5V(benchmark::State& state, ActuatorModel (*model)()) {
  PeriodMapAt8Hz05V(state, model());
}
BENCHMARK_CAPTURE(BM_PeriodMapSmooth_8Hz_0_5V, k3, CubicModel)
    ->ArgName("trace")->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_PeriodMapSmooth_8Hz_0_5V, k3_hertzian, CubicHertzianModel)
    ->ArgName("trace")->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// Issue 12's first speed target: paper + k3 = 4e7, steady states with Floquet multipliers, points
// only, on one core; the grid of compare_scipy.py --smooth (5 .. 20 Hz x 0.1 .. 0.6 V, 20 x 6). No
// fixed iteration count: one sweep takes 16-25 s with the CVODE period map (one iteration then), and
// the benchmark repeats it to its minimum time once it is fast.
void BM_SweepSmooth20x6(benchmark::State& state) {
  SweepSpec spec;
  spec.model = CubicModel();
  spec.frequency_hz = GridAxis{5.0, 20.0, 20, false};
  spec.amplitude_v = GridAxis{0.1, 0.6, 6, false};
  spec.threads = 1;
  spec.thresholds = false;
  RunAndReport(state, spec);
}
BENCHMARK(BM_SweepSmooth20x6)->UseRealTime()->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace strokelab

BENCHMARK_MAIN();
