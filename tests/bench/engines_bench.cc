// Timings of the simulation engines and the signal analysis on the paper's record: 10 s at
// 51.2 kHz (paper section 3), paper model (Table 2); and of the variational flow on a sampled
// record. Run a Release build, e.g.
//   engines_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
// tests/bench/compare_scipy.py times the same record against scipy's solve_ivp.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <span>

#include "strokelab/engines/engine.h"
#include "strokelab/engines/variational_flow.h"
#include "strokelab/model/model.h"
#include "strokelab/engines/record_summary.h"
#include "strokelab/signal/signal.h"

namespace strokelab {
namespace {

SineDrive Drive(double frequency_hz, double amplitude_v) {
  SineDrive drive;
  drive.frequency_hz = frequency_hz;
  drive.amplitude_v = amplitude_v;
  return drive;
}

// Times one engine on the 10 s record. The Record is reused across iterations and sized by a
// warm-up call, so the loop measures the integration, not allocating and first touching ~13 MB of
// output (that costs ~6.5 ms once per process, more than the exact engine itself).
void BM_Simulate(benchmark::State& state, Method method, double frequency_hz, double amplitude_v) {
  const ActuatorModel model = PaperModel();
  const SineDrive drive = Drive(frequency_hz, amplitude_v);
  const SimulationOptions options;  // 10 s at 51.2 kHz, from rest
  const auto engine = MakeEngine(method);
  Record record;
  engine->Simulate(model, drive, options, &record);  // warm-up: sizes the buffers
  for (auto _ : state) {
    engine->Simulate(model, drive, options, &record);
    benchmark::DoNotOptimize(record.force_n.data());
    benchmark::ClobberMemory();
  }
  state.counters["samples_per_s"] = benchmark::Counter(static_cast<double>(state.iterations() * record.size()),
                                                       benchmark::Counter::kIsRate);
  state.counters["contacts"] = static_cast<double>(record.contacts.size());
}

// 8 Hz / 0.5 V: saturating, one contact per period with every engine.
BENCHMARK_CAPTURE(BM_Simulate, exact_8Hz_0.5V, Method::kExact, 8.0, 0.5)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Simulate, cvode_8Hz_0.5V, Method::kCvode, 8.0, 0.5)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Simulate, ode3_8Hz_0.5V, Method::kOde3, 8.0, 0.5)->Unit(benchmark::kMillisecond);
// 13 Hz / 0.3 V: below the stop from rest (contact from ~0.415 V), so no switching.
BENCHMARK_CAPTURE(BM_Simulate, exact_13Hz_0.3V, Method::kExact, 13.0, 0.3)->Unit(benchmark::kMillisecond);
// 5 Hz / 0.6 V: deep saturation, two impacts per drive period (the mass bounces off the stop),
// so 10 contacts/s against 8 at 8 Hz; each still lasts ~0.49 ms (linear stop, paper Eq. 4).
BENCHMARK_CAPTURE(BM_Simulate, exact_5Hz_0.6V, Method::kExact, 5.0, 0.6)->Unit(benchmark::kMillisecond);

// The steady-state summary the CLI prints (last second of the record).
// The variational flow as the broadband fit runs it: 1 s of a multisine record at 8,192 Hz (40
// harmonics of 5 Hz, random phases, 1.2 / h V each: it hits the stop), with the columns of the start,
// k_p, c_p, g, d, k_s and, for a clipping model, its level, at every sample. `exact`: the free flight's exact
// map where it applies (FlowOptions::exact_free_flight); else DOP853 throughout. A level of 0: no
// clipping (the counter clipped_share: the share of samples beyond the level). A cubic stiffness
// k3 [N/m^3] makes the free flight nonlinear: DOP853 throughout.
void BM_SampledFlow(benchmark::State& state, double limit_v, double k3, bool exact) {
  using M = ActuatorModel;
  const double fs = 8192.0, duration_s = 1.0;
  std::mt19937 random(20261130);
  std::uniform_real_distribution<double> phase(0.0, 2 * std::numbers::pi);
  std::vector<double> phases;
  for (int h = 1; h <= 40; ++h) phases.push_back(phase(random));
  SampledDrive drive{fs, {}};
  for (int k = 0; k <= static_cast<int>(duration_s * fs); ++k) {
    double u = 0;
    for (int h = 1; h <= 40; ++h) u += 1.2 / h * std::sin(2 * std::numbers::pi * 5.0 * h * k / fs + phases[h - 1]);
    drive.voltage_v.push_back(u);
  }
  ActuatorModel model = PaperModel();
  model.cubic_stiffness_n_per_m3 = k3;
  FlowRequest request;
  request.monodromy = true;  // the segments' starts are unknowns too
  request.parameters = {&M::stiffness_n_per_m, &M::damping_n_s_per_m, &M::gain_n_per_v, &M::lower_stop_m,
                        &M::contact_stiffness};
  if (limit_v > 0) {
    model.amplifier_limit_v = limit_v;
    request.parameters.push_back(&M::amplifier_limit_v);
  }
  request.sample_count = static_cast<int>(drive.voltage_v.size());
  request.sample_interval_s = 1.0 / fs;
  request.sample_sensitivities = true;
  FlowOptions options;
  options.exact_free_flight = exact;
  FlowResult flow;
  for (auto _ : state) {
    flow = Flow(model, drive, State{}, 0.0, duration_s, request, options);
    benchmark::DoNotOptimize(flow.sample_slopes.data());
  }
  state.counters["samples_per_s"] = benchmark::Counter(static_cast<double>(state.iterations() * request.sample_count),
                                                       benchmark::Counter::kIsRate);
  state.counters["steps"] = static_cast<double>(flow.steps);
  state.counters["rejected"] = static_cast<double>(flow.rejected_steps);
  state.counters["exact_steps"] = static_cast<double>(flow.exact_steps);
  state.counters["contacts"] = static_cast<double>(flow.contacts);
  if (limit_v > 0)
    state.counters["clipped_share"] =
        static_cast<double>(std::count_if(drive.voltage_v.begin(), drive.voltage_v.end(),
                                          [&](double u) { return std::abs(u) > limit_v; })) /
        static_cast<double>(drive.voltage_v.size());
}

BENCHMARK_CAPTURE(BM_SampledFlow, paper_exact, 0.0, 0.0, true)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SampledFlow, paper_dop853, 0.0, 0.0, false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SampledFlow, clipped_2V_exact, 2.0, 0.0, true)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SampledFlow, clipped_2V_dop853, 2.0, 0.0, false)->Unit(benchmark::kMillisecond);
// Clipped hard: about a third of the samples beyond 1 V.
BENCHMARK_CAPTURE(BM_SampledFlow, clipped_1V_exact, 1.0, 0.0, true)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SampledFlow, clipped_1V_dop853, 1.0, 0.0, false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_SampledFlow, k3_1.5e7, 0.0, 1.5e7, true)->Unit(benchmark::kMillisecond);

void BM_Summarize(benchmark::State& state) {
  const SineDrive drive = Drive(8.0, 0.5);
  const Record record = MakeExactEngine()->Simulate(PaperModel(), drive, SimulationOptions{});
  for (auto _ : state) {
    RecordSummary summary = Summarize(record, drive);
    benchmark::DoNotOptimize(summary);
  }
}
BENCHMARK(BM_Summarize)->Unit(benchmark::kMicrosecond);

// Least-squares harmonic amplitudes over one second (51,200 samples, 8 whole periods at 8 Hz).
void BM_HarmonicAmplitudes(benchmark::State& state) {
  const int orders = static_cast<int>(state.range(0));
  const SineDrive drive = Drive(8.0, 0.5);
  const Record record = MakeExactEngine()->Simulate(PaperModel(), drive, SimulationOptions{});
  const SampleWindow window = LastWholePeriods(record.size(), record.sample_rate_hz, drive.frequency_hz);
  const std::span<const double> force(record.force_n);
  for (auto _ : state) {
    auto amplitudes = HarmonicAmplitudes(force, record.sample_rate_hz, drive.frequency_hz, window, orders);
    benchmark::DoNotOptimize(amplitudes.data());
  }
  state.counters["samples_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations() * window.size()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_HarmonicAmplitudes)->Arg(1)->Arg(10)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace strokelab

BENCHMARK_MAIN();
