// Timings of the simulation engines and the signal analysis on the paper's record: 10 s at
// 51.2 kHz (paper section 3), paper model (Table 2). Run a Release build, e.g.
//   engines_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
// tests/bench/compare_scipy.py times the same record against scipy's solve_ivp.
#include <benchmark/benchmark.h>

#include <span>

#include "strokelab/engines/engine.h"
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
