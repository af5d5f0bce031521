// Synthetic campaigns (strokelab/synth.h).
#include "strokelab/data/synth.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>
#include <random>
#include <set>

#include "strokelab/base/json_number.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/parallel_for.h"
#include "strokelab/engines/variational_flow.h"
#include "strokelab/model/dynamics.h"
#include "strokelab/model/model_json.h"
#include "format_number.h"

namespace strokelab {
namespace {

using data_internal::Num;

// Random numbers fixed by the seed and a stream index on every platform: mt19937_64 and seed_seq
// are specified by the standard; the uniform and normal transforms are done here (the standard
// library's distributions are implementation-defined).
class Random {
 public:
  Random(std::uint64_t seed, std::uint64_t stream) {
    std::seed_seq sequence{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32),
                           static_cast<std::uint32_t>(stream), static_cast<std::uint32_t>(stream >> 32)};
    engine_.seed(sequence);
  }
  // Uniform in [0, 1).
  double Uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  // Standard normal (Box-Muller, both values used).
  double Normal() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    const double u1 = 1.0 - Uniform();  // (0, 1]
    const double u2 = Uniform();
    const double radius = std::sqrt(-2.0 * std::log(u1));
    spare_ = radius * std::sin(2.0 * std::numbers::pi * u2);
    has_spare_ = true;
    return radius * std::cos(2.0 * std::numbers::pi * u2);
  }

 private:
  std::mt19937_64 engine_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

std::optional<FieldError> FiniteError(double value, const char* field, bool positive, bool allow_zero = true) {
  if (!std::isfinite(value) || (positive && (value < 0 || (!allow_zero && value == 0))))
    return FieldError{field, std::string("must be a finite number") + (positive ? (allow_zero ? " >= 0" : " > 0") : "") +
                                 ", got " + Num(value)};
  return std::nullopt;
}

// The samples first .. first + kept - 1 of a broadband record: the drive's samples over the whole
// simulated span (0 .. total / fs, settling included) and the response there, from rest.
struct BroadbandRun {
  std::vector<double> voltage_v;  // total + 1 samples, sample first at the kept part's t = 0
  std::vector<double> response;   // kept samples, physical units
};
BroadbandRun SimulateBroadband(const ActuatorModel& model, const SynthOptions& options, double level_v_rms,
                               size_t total, size_t first, Random* random) {
  const double fs = options.sample_rate_hz;
  BroadbandSignal signal = options.broadband;
  signal.excitation = options.excitation;
  signal.level_v_rms = level_v_rms;
  signal.period_s = options.duration_s;
  BroadbandRun run;
  run.voltage_v = BroadbandVoltage(signal, fs, -static_cast<double>(first) / fs, total + 1,
                                   static_cast<double>(total + 1) / fs, [random] { return random->Uniform(); });
  const SampledDrive drive{fs, run.voltage_v};
  FlowRequest request;
  request.sample_count = static_cast<int>(total - first);
  request.sample_start_s = static_cast<double>(first) / fs;
  request.sample_interval_s = 1.0 / fs;
  FlowOptions flow_options;
  flow_options.max_steps = std::max<long>(flow_options.max_steps, 20 * static_cast<long>(total));
  const FlowResult flow = Flow(model, drive, State{}, 0.0, static_cast<double>(total) / fs, request, flow_options);
  run.response.resize(flow.samples.size());
  for (size_t n = 0; n < flow.samples.size(); ++n)
    run.response[n] = ResponseOf(options.response, model.mass_kg, flow.samples[n], flow.sample_force_n[n]);
  return run;
}

}  // namespace

std::optional<FieldError> SynthOptions::IsValid() const {
  if (auto error = FiniteError(sample_rate_hz, "sample_rate_hz", true, false)) return error;
  const double nyquist_hz = 0.5 * sample_rate_hz;
  if (frequencies_hz.empty()) return FieldError{"frequencies_hz", "needs at least one frequency"};
  for (double f : frequencies_hz) {
    if (auto error = FiniteError(f, "frequencies_hz", true, false)) return error;
    if (f >= nyquist_hz)
      return FieldError{"frequencies_hz", Num(f) + " Hz is not below the Nyquist frequency " + Num(nyquist_hz) + " Hz"};
  }
  if (amplitudes_v.empty()) return FieldError{"amplitudes_v", "needs at least one amplitude"};
  for (double a : amplitudes_v)
    if (auto error = FiniteError(a, "amplitudes_v", true)) return error;
  if (auto error = FiniteError(duration_s, "duration_s", true, false)) return error;
  if (std::llround(duration_s * sample_rate_hz) < 2)
    return FieldError{"duration_s", "a record must hold at least 2 samples"};
  if (auto error = FiniteError(settle_s, "settle_s", true)) return error;
  if (auto error = FiniteError(sensitivity, "sensitivity", false)) return error;
  if (auto error = FiniteError(noise_rms_v, "noise_rms_v", true)) return error;
  if (auto error = FiniteError(voltage_noise_rms_v, "voltage_noise_rms_v", true)) return error;
  if (auto error = FiniteError(offset_v, "offset_v", false)) return error;
  if (auto error = FiniteError(hum_v, "hum_v", true)) return error;
  if (auto error = FiniteError(hum_hz, "hum_hz", true, false)) return error;
  if (auto error = FiniteError(voltage_offset_v, "voltage_offset_v", false)) return error;
  if (!std::isfinite(drive_frequency_error) || std::abs(drive_frequency_error) >= 1)
    return FieldError{"drive_frequency_error", "must be a finite number in (-1, 1), got " + Num(drive_frequency_error)};
  for (double f : frequencies_hz) {
    const double true_hz = f * (1.0 + drive_frequency_error);
    if (true_hz >= nyquist_hz)
      return FieldError{"drive_frequency_error", "drives " + Num(f) + " Hz at " + Num(true_hz) +
                                                     " Hz, not below the Nyquist frequency " + Num(nyquist_hz) + " Hz"};
  }
  if (!std::isfinite(sensitivity_error) || sensitivity_error <= -1)
    return FieldError{"sensitivity_error", "must be a finite number > -1, got " + Num(sensitivity_error)};
  std::set<std::string> keys;
  for (const auto& [key, relative] : perturb) {
    std::string name = key;
    if (key != "sensitivity") {
      try {
        name = FindParameter(key).key;
      } catch (const InputError& e) {
        return FieldError{"perturb", "'" + key + "': " + e.bare_message() + " or sensitivity"};
      }
    }
    if (!keys.insert(name).second) return FieldError{"perturb", "'" + key + "' is perturbed twice"};
    if (!std::isfinite(relative) || relative < 0 || relative >= 1)
      return FieldError{"perturb", "'" + key + "': the relative perturbation must be in [0, 1), got " + Num(relative)};
  }
  if (sensitivity_error != 0 && keys.count("sensitivity") != 0)
    return FieldError{"sensitivity_error", "and a 'sensitivity' perturbation do not go together: give one"};
  if (threads < 0) return FieldError{"threads", "must be >= 0"};
  if (excitation != Excitation::kSteppedSine) {
    if (method) return FieldError{"method", "a broadband campaign is simulated by the variational flow: give no method"};
    if (levels_v_rms.empty()) return FieldError{"levels_v_rms", "needs at least one level"};
    for (double level : levels_v_rms)
      if (auto error = FiniteError(level, "levels_v_rms", true)) return error;
    BroadbandSignal signal = broadband;
    signal.excitation = excitation;
    signal.period_s = duration_s;
    if (auto error = signal.IsValid(sample_rate_hz)) {
      if (error->field == "period_s") error->field = "duration_s";
      return error;
    }
  }
  return std::nullopt;
}

Synthesis Synthesize(const ActuatorModel& nominal_model, const SynthOptions& options) {
  Validate(options);
  Validate(nominal_model);
  Synthesis out;
  const double written_sensitivity =
      options.sensitivity != 0 ? options.sensitivity : DefaultSensitivity(options.response);
  double true_sensitivity = written_sensitivity * (1.0 + options.sensitivity_error);

  // Perturbations, drawn in the order given from stream 0.
  Random parameter_random(options.seed, 0);
  out.model = nominal_model;
  nlohmann::json perturbations = nlohmann::json::array();
  for (const auto& [key, relative] : options.perturb) {
    const double u = 2.0 * parameter_random.Uniform() - 1.0;
    const double factor = 1.0 + relative * u;
    double nominal = 0.0, actual = 0.0;
    std::string name = key;
    if (key == "sensitivity") {
      nominal = written_sensitivity;
      true_sensitivity = actual = written_sensitivity * factor;
    } else {
      const ParameterInfo& info = FindParameter(key);
      name = info.key;
      nominal = nominal_model.*(info.field);
      actual = std::isfinite(nominal) ? nominal * factor : nominal;
      out.model.*(info.field) = actual;
    }
    perturbations.push_back({{"key", name},
                             {"relative_half_width", relative},
                             {"factor", factor},
                             {"nominal", JsonNumber(nominal)},
                             {"actual", JsonNumber(actual)}});
  }
  try {
    Validate(out.model);
  } catch (const InputError& e) {
    throw InputError("perturb", "the perturbed model is not valid: " + std::string(e.what()));
  }
  out.method = ChooseMethod(options.method ? ToString(*options.method) : "auto", out.model).method;
  const bool broadband = options.excitation != Excitation::kSteppedSine;
  out.engine = broadband ? "flow" : ToString(out.method);

  SimulationOptions simulation;
  simulation.duration_s = options.settle_s + options.duration_s;
  simulation.sample_rate_hz = options.sample_rate_hz;
  simulation.record_velocity = options.response == ResponseKind::kVelocity;
  Validate(simulation);
  const size_t total = simulation.SampleCount();
  const size_t kept =
      std::min<size_t>(total, static_cast<size_t>(std::llround(options.duration_s * options.sample_rate_hz)));
  const size_t first = total - kept;

  const size_t frequencies = options.frequencies_hz.size();
  const size_t count = broadband ? options.levels_v_rms.size() : frequencies * options.amplitudes_v.size();
  Campaign& campaign = out.campaign;
  campaign.actuator = options.actuator;
  campaign.response = options.response;
  campaign.absolute_scale = !options.nominal;
  campaign.records.resize(count);
  std::vector<double> hum_phases(count), drive_phases(count);

  ParallelFor(count, [&](size_t k) {
    // Stream 1 + k: the hum phase, then the drive phase (when random), then the noise sample by sample.
    Random random(options.seed, 1 + k);
    const double hum_phase = 2.0 * std::numbers::pi * random.Uniform();
    hum_phases[k] = hum_phase;
    Recording& rec = campaign.records[k];
    std::vector<double> voltage(kept), response(kept);
    if (broadband) {
      const BroadbandRun run = SimulateBroadband(out.model, options, options.levels_v_rms[k], total, first, &random);
      std::copy_n(run.voltage_v.begin() + static_cast<long>(first), kept, voltage.begin());
      response = run.response;
      rec.broadband = true;
    } else {
      const double nominal_hz = options.frequencies_hz[k % frequencies];
      SineDrive drive;
      drive.frequency_hz = nominal_hz * (1.0 + options.drive_frequency_error);
      drive.amplitude_v = options.amplitudes_v[k / frequencies];
      if (options.random_drive_phase) drive.phase_rad = 2.0 * std::numbers::pi * random.Uniform() - std::numbers::pi;
      drive_phases[k] = drive.phase_rad;
      Record record;
      MakeEngine(out.method)->Simulate(out.model, drive, simulation, &record);
      for (size_t n = 0; n < kept; ++n) {
        voltage[n] = drive.Voltage(static_cast<double>(first + n) / options.sample_rate_hz);
        const State y{record.displacement_m[first + n],
                      record.velocity_m_per_s.empty() ? 0.0 : record.velocity_m_per_s[first + n]};
        response[n] = ResponseOf(options.response, out.model.mass_kg, y, record.force_n[first + n]);
      }
      rec.nominal_frequency_hz = nominal_hz;
      rec.nominal_amplitude_v = drive.amplitude_v;
    }
    char name[32];
    std::snprintf(name, sizeof name, "rec_%03zu.csv", k + 1);
    rec.name = name;
    rec.sample_rate_hz = options.sample_rate_hz;
    rec.voltage_v.resize(kept);
    rec.response.resize(kept);
    const double hum_omega = 2.0 * std::numbers::pi * options.hum_hz;
    for (size_t n = 0; n < kept; ++n) {
      const double t_kept = static_cast<double>(n) / options.sample_rate_hz;
      rec.voltage_v[n] = voltage[n] + options.voltage_offset_v + options.voltage_noise_rms_v * random.Normal();
      const double volts = true_sensitivity * response[n] + options.offset_v +
                           options.hum_v * std::sin(hum_omega * t_kept + hum_phase) + options.noise_rms_v * random.Normal();
      rec.response[n] = volts / written_sensitivity;
    }
  }, static_cast<size_t>(options.threads));  // 0: one thread per core

  out.write.sensitivity = written_sensitivity;
  nlohmann::json records = nlohmann::json::array();
  for (size_t k = 0; k < count; ++k) {
    if (broadband) {
      records.push_back({{"file", campaign.records[k].name},
                         {"level_v_rms", options.levels_v_rms[k]},
                         {"hum_phase_rad", hum_phases[k]}});
      continue;
    }
    records.push_back({{"file", campaign.records[k].name},
                       {"frequency_hz", campaign.records[k].nominal_frequency_hz},
                       {"amplitude_v", campaign.records[k].nominal_amplitude_v},
                       {"hum_phase_rad", hum_phases[k]}});
    if (options.random_drive_phase) records.back()["drive_phase_rad"] = drive_phases[k];
  }
  out.truth = {
      {"format", "strokelab-synth-truth/1"},
      {"model", ModelToJson(out.model)},
      {"nominal_model", ModelToJson(nominal_model)},
      {"perturbations", perturbations},
      {"method", out.engine},
      {"response", ToString(options.response)},
      {"sensitivity_written", written_sensitivity},
      {"sensitivity_true", true_sensitivity},
      {"nominal_sensitivity", options.nominal},
      {"noise_rms_v", options.noise_rms_v},
      {"voltage_noise_rms_v", options.voltage_noise_rms_v},
      {"offset_v", options.offset_v},
      {"hum_v", options.hum_v},
      {"hum_hz", options.hum_hz},
      {"seed", options.seed},
      {"settle_s", options.settle_s},
      {"duration_s", options.duration_s},
      {"sample_rate_hz", options.sample_rate_hz},
      {"records", records},
  };
  // The newer imperfections only when set, so that the truths of campaigns without them stay as they were.
  if (options.voltage_offset_v != 0) out.truth["voltage_offset_v"] = options.voltage_offset_v;
  if (options.drive_frequency_error != 0) out.truth["drive_frequency_error"] = options.drive_frequency_error;
  if (options.sensitivity_error != 0) out.truth["sensitivity_error"] = options.sensitivity_error;
  if (broadband) {
    out.truth["excitation"] = {{"kind", ToString(options.excitation)},
                               {"band_low_hz", options.broadband.band_low_hz},
                               {"band_high_hz", options.broadband.band_high_hz},
                               {"period_s", options.duration_s}};
    if (options.excitation == Excitation::kMultisine) out.truth["excitation"]["odd_grid"] = options.broadband.odd_grid;
  }
  return out;
}

void WriteSynthesis(const Synthesis& synthesis, const std::filesystem::path& dir,
                    const std::filesystem::path& truth_path, CampaignFormat format, WavSampleFormat wav_format) {
  if (format == CampaignFormat::kCsv) {
    WriteCampaign(synthesis.campaign, dir, synthesis.write);
  } else {
    MappedWriteOptions mapped;
    mapped.format = format;
    mapped.wav_format = wav_format;
    mapped.sensitivity = synthesis.write.sensitivity;
    WriteMappedCampaign(synthesis.campaign, dir, mapped);
  }
  const std::filesystem::path path = truth_path.empty() ? dir / "truth.json" : truth_path;
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot open '" + path.string() + "' for writing");
  out << synthesis.truth.dump(2) << "\n";
  if (!out.flush()) throw std::runtime_error("writing '" + path.string() + "' failed");
}

}  // namespace strokelab
