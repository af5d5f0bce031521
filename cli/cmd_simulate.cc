// strokelab simulate: one record of a model under a sine drive, started from rest.
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "commands.h"
#include "format.h"
#include "strokelab/base/json_number.h"
#include "strokelab/engines/engine.h"
#include "strokelab/base/errors.h"
#include "strokelab/model/model_json.h"
#include "strokelab/engines/record_summary.h"
#include "strokelab/base/json_parse.h"

namespace strokelab::cli {
namespace {

constexpr const char* kSimulateHelp = R"(usage: strokelab simulate [options]

  --model NAME|FILE      preset (paper, linear) or a JSON model file          [paper]
  --set KEY=VALUE        override a model parameter (repeatable), e.g. --set k3=4e7
  --frequency-hz F       drive frequency [Hz]                                 (required)
  --amplitude-v V        drive amplitude [V]                                  (required)
  --phase-rad P          drive phase [rad]                                    [0]
  --duration-s T         record length [s]                                    [10]
  --sample-rate-hz FS    output sample rate [Hz]                              [51200]
  --method M             auto | exact | cvode | ode3                          [auto]
  --out FILE.csv         write the series: time_s,voltage_V,displacement_m,velocity_m_per_s,force_N,contact
  --json                 print the steady-state summary (last whole second) as one JSON object

auto takes the exact engine for a piecewise-linear model and cvode for any other (k2, k3, friction,
Hertzian contact), and the output says which it took and why. The record starts from rest. Summary
figures are taken over the last whole drive periods that fit in the last second of the record.
)";

double Finite(double value) { return std::isfinite(value) ? value : 0.0; }

void WriteCsv(const std::string& path, const Record& record, const ActuatorModel& model, const SineDrive& drive) {
  std::ofstream out(path);
  if (!out) throw InputError("--out", "cannot open '" + path + "' for writing");
  out << "time_s,voltage_V,displacement_m,velocity_m_per_s,force_N,contact\n";
  char line[256];
  for (size_t n = 0; n < record.size(); ++n) {
    const double t = record.TimeS(n);
    const double v = record.velocity_m_per_s.empty() ? std::nan("") : record.velocity_m_per_s[n];
    std::snprintf(line, sizeof line, "%.9g,%.9g,%.12g,%.12g,%.12g,%d\n", t, ClippedVoltage(model, drive.Voltage(t)),
                  record.displacement_m[n], v, record.force_n[n], record.in_contact[n]);
    out << line;
  }
  if (!out) throw InputError("--out", "write to '" + path + "' failed");
}

}  // namespace

ActuatorModel LoadModel(const Args& args) {
  const std::string name = args.GetOr("--model", "paper");
  ActuatorModel model;
  if (std::filesystem::is_regular_file(name)) {
    std::ifstream in(name);
    const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    nlohmann::json json;
    try {
      json = ParseJson(text);
    } catch (const nlohmann::json::exception& e) {  // syntax, or a number beyond a double
      throw InputError("--model " + name, std::string("not valid JSON: ") + e.what());
    }
    model = ModelFromJson(json, name + ":");
  } else if (name.size() > 5 && name.substr(name.size() - 5) == ".json") {
    throw InputError("--model", "model file '" + name + "' not found");
  } else {
    try {
      model = PresetModel(name);
    } catch (const InputError& e) {
      throw InputError("--model", e.bare_message());
    }
  }
  for (const std::string& assignment : args.GetAll("--set")) {
    try {
      ApplyOverride(&model, assignment);
    } catch (const InputError& e) {
      throw InputError("--set " + e.field(), e.bare_message());
    }
  }
  Validate(model);
  return model;
}

int RunSimulate(const std::vector<std::string>& argv) {
  const Args args(argv,
                  {"--model", "--set", "--frequency-hz", "--amplitude-v", "--phase-rad", "--duration-s",
                   "--sample-rate-hz", "--method", "--out"},
                  {"--json", "--help"}, {"--set"});
  if (args.Has("--help")) {
    std::cout << kSimulateHelp;
    return 0;
  }
  if (!args.Get("--frequency-hz")) throw InputError("--frequency-hz", "is required");
  if (!args.Get("--amplitude-v")) throw InputError("--amplitude-v", "is required");
  const ActuatorModel model = LoadModel(args);
  SineDrive drive;
  drive.frequency_hz = args.Number("--frequency-hz", 0);
  drive.amplitude_v = args.Number("--amplitude-v", 0);
  drive.phase_rad = args.Number("--phase-rad", 0);
  try {
    Validate(drive);
  } catch (const InputError& e) {
    const std::string flag = e.field() == "frequency_hz" ? "--frequency-hz"
                             : e.field() == "amplitude_v" ? "--amplitude-v"
                                                          : "--phase-rad";
    throw InputError(flag, e.bare_message());
  }
  SimulationOptions options;
  options.duration_s = args.Number("--duration-s", 10.0);
  options.sample_rate_hz = args.Number("--sample-rate-hz", 51200.0);
  try {
    Validate(options);
  } catch (const InputError& e) {
    throw InputError(e.field() == "sample_rate_hz" ? "--sample-rate-hz" : "--duration-s", e.bare_message());
  }
  // The summary's first harmonic needs the drive frequency below Nyquist (else the signal layer
  // refuses it under its own name, "orders", after the whole simulation).
  if (drive.frequency_hz >= options.sample_rate_hz / 2)
    throw InputError("--sample-rate-hz", "must be more than twice --frequency-hz (" + General(drive.frequency_hz, 6) +
                                             " Hz) for the summary's first harmonic, got " +
                                             General(options.sample_rate_hz, 6));
  MethodChoice choice;
  try {
    choice = ChooseMethod(args.GetOr("--method", "auto"), model);
  } catch (const InputError& e) {
    throw InputError("--method", e.bare_message());
  }
  const auto engine = MakeEngine(choice.method);
  // The output buffers are allocated (and their pages touched) before the clock starts: wall_time_s
  // is the simulation's time, not the operating system's first-touch cost (~7 ms for 13 MB).
  Record record;
  const size_t samples = options.SampleCount();
  record.displacement_m.assign(samples, 0.0);
  record.force_n.assign(samples, 0.0);
  record.velocity_m_per_s.assign(samples, 0.0);
  record.in_contact.assign(samples, 0);
  const auto start = std::chrono::steady_clock::now();
  engine->Simulate(model, drive, options, &record);
  const double wall_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const RecordSummary summary = Summarize(record, drive);
  if (const auto out = args.Get("--out")) WriteCsv(*out, record, model, drive);

  if (args.Has("--json")) {
    nlohmann::json json = {
        {"method", choice.Describe()},
        {"frequency_hz", drive.frequency_hz},
        {"amplitude_v", drive.amplitude_v},
        {"duration_s", options.duration_s},
        {"sample_rate_hz", options.sample_rate_hz},
        {"window_periods", summary.window.periods},
        {"min_displacement_m", summary.min_displacement_m},
        {"max_displacement_m", summary.max_displacement_m},
        {"contacts", summary.contacts},
        {"mean_contact_ms", JsonNumber(summary.mean_contact_ms)},
        {"contact_time_rsd", JsonNumber(summary.contact_time_rsd)},
        {"peak_force_n", summary.peak_force_n},
        {"first_harmonic_force_n", summary.first_harmonic_force_n},
        {"first_harmonic_phase_rad", summary.first_harmonic_phase_rad},
        {"wall_time_s", wall_time_s},
        {"model", ModelToJson(model)},
    };
    std::cout << json.dump(2) << "\n";
    return 0;
  }
  std::printf("method %s\n", choice.Describe().c_str());
  std::printf("%.6g Hz, %.6g V, %.6g s at %.6g Hz (%zu samples) in %.3f ms\n",
              drive.frequency_hz, drive.amplitude_v, options.duration_s, options.sample_rate_hz, record.size(),
              wall_time_s * 1e3);
  std::printf("steady state over the last %.0f periods:\n", summary.window.periods);
  std::printf("  displacement      %.6g .. %.6g mm\n", summary.min_displacement_m * 1e3,
              summary.max_displacement_m * 1e3);
  std::printf("  contacts          %zu, mean contact time %.4g ms\n", summary.contacts, Finite(summary.mean_contact_ms));
  std::printf("  peak force        %.6g N\n", summary.peak_force_n);
  std::printf("  first harmonic    %.9g N at %.6f rad\n", summary.first_harmonic_force_n,
              summary.first_harmonic_phase_rad);
  return 0;
}

}  // namespace strokelab::cli
