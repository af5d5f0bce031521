// strokelab synth: a synthetic campaign (recordings layout) from any model, with the truth apart.
#include <cstdint>
#include <filesystem>
#include <iostream>
#include <map>
#include <string>
#include <string_view>
#include <tuple>
#include <vector>

#include "commands.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/parse.h"
#include "strokelab/data/mapping.h"
#include "strokelab/data/synth.h"

namespace strokelab::cli {
namespace {

constexpr const char* kSynthHelp = R"(usage: strokelab synth --out DIR [options]

Writes a stepped-sine or broadband campaign as the test rig exports it (manifest.json + rec_NNN.csv,
or with --format UFF 58 or WAV files + mapping.json) from a model, and the truth (model used,
perturbations, noise, seed) apart in truth.json, which the manifest does not mention. Each record is
simulated from rest for settle + duration and the last duration kept.

  --out DIR                campaign directory (created)                              (required)
  --truth FILE             where truth.json goes                                     [DIR/truth.json]
  --model NAME|FILE        preset (paper, linear) or a JSON model file               [paper]
  --set KEY=VALUE          override a model parameter (repeatable), e.g. --set k3=4e7
  --frequencies-hz LIST    drive frequencies [Hz], inner loop                        [6,7,8,9,11,13]
  --amplitudes-v LIST      drive amplitudes [V], outer loop                          [0.1,0.3,0.4,0.5]
  --excitation KIND        stepped-sine, or a broadband drive: multisine (random phases, equal
                           amplitudes, period = duration), noise (Gaussian, band-limited) or sweep
                           (logarithmic over the band in one duration)               [stepped-sine]
  --levels-v-rms LIST      broadband: one record per drive level [V rms]             [0.05,0.15,0.3]
  --band-hz LOW:HIGH       broadband: the drive's band [Hz]                           [2:200]
  --grid odd|full          multisine: odd multiples of 1 / duration only (the even lines show
                           even-order distortion), or every line                      [odd]
  --duration-s T           kept record length [s]                                    [1]
  --settle-s S             simulated before the kept part [s]                        [10]
  --sample-rate-hz FS      [Hz]                                                      [51200]
  --response KIND          force | acceleration | velocity | displacement            [force]
  --sensitivity X          sensor sensitivity written to the manifest [V per unit]   [force 0.02248,
                           acceleration 0.0102, velocity 1, displacement 1000]
  --nominal                the manifest calls the sensitivity nominal (absolute scale unknown)
  --noise-rms R            Gaussian noise on the response channel [sensor V rms]     [0]
  --voltage-noise-rms R    Gaussian noise on the voltage channel [V rms]             [0]
  --offset-v O             DC offset on the response channel [sensor V]              [0]
  --hum-v H                mains hum amplitude on the response channel [sensor V]    [0]
  --hum-hz F               mains frequency [Hz]                                      [50]
  --perturb K=R,...        relative perturbations, value x (1 + R u), u uniform in [-1, 1] from
                           the seed; keys: model parameters or 'sensitivity' (true sensor vs written)
  --seed N                 random seed (perturbations, noise, hum phases)            [1]
  --method M               auto | exact | cvode | ode3           [auto: exact if piecewise linear, else cvode]
                           (stepped sines; broadband records are the variational flow's, any model)
  --actuator TEXT          the manifest's actuator description
  --threads N              records simulated side by side; 0: one per core           [0]
  --format F               csv | uff58 (UFF dataset 58, ASCII) | uff58b (binary) | wav; UFF and WAV
                           files come with mapping.json (data/README.md)              [csv]
  --wav-format W           WAV samples: int16 | int24 | int32 | float32                [float32]
)";

std::vector<double> NumberList(const std::string& text, const std::string& flag) {
  std::vector<double> values;
  size_t start = 0;
  while (true) {
    const size_t comma = text.find(',', start);
    const std::string item = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    values.push_back(ParseNumber(item, flag));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return values;
}

std::vector<std::pair<std::string, double>> PerturbList(const std::vector<std::string>& texts) {
  std::vector<std::pair<std::string, double>> out;
  for (const std::string& text : texts) {
    size_t start = 0;
    while (true) {
      const size_t comma = text.find(',', start);
      const std::string item = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
      const size_t eq = item.find('=');
      if (eq == std::string::npos || eq == 0)
        throw InputError("--perturb", "expected KEY=RELATIVE, got '" + item + "'");
      out.emplace_back(item.substr(0, eq), ParseNumber(item.substr(eq + 1), "--perturb"));
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
  }
  return out;
}

}  // namespace

int RunSynth(const std::vector<std::string>& argv) {
  const Args args(argv,
                  {"--out",
                   "--truth",
                   "--model",
                   "--set",
                   "--frequencies-hz",
                   "--amplitudes-v",
                   "--excitation",
                   "--levels-v-rms",
                   "--band-hz",
                   "--grid",
                   "--duration-s",
                   "--settle-s",
                   "--sample-rate-hz",
                   "--response",
                   "--sensitivity",
                   "--noise-rms",
                   "--voltage-noise-rms",
                   "--offset-v",
                   "--hum-v",
                   "--hum-hz",
                   "--perturb",
                   "--seed",
                   "--method",
                   "--actuator",
                   "--threads",
                   "--format",
                   "--wav-format"},
                  {"--nominal", "--help"}, {"--set", "--perturb"});
  if (args.Has("--help")) {
    std::cout << kSynthHelp;
    return 0;
  }
  const auto out_dir = args.Get("--out");
  if (!out_dir) throw InputError("--out", "is required (the campaign directory to write)");
  const ActuatorModel model = LoadModel(args);

  SynthOptions options;
  if (const auto list = args.Get("--frequencies-hz")) options.frequencies_hz = NumberList(*list, "--frequencies-hz");
  if (const auto list = args.Get("--amplitudes-v")) options.amplitudes_v = NumberList(*list, "--amplitudes-v");
  try {
    options.excitation = ParseExcitation(args.GetOr("--excitation", "stepped-sine"));
  } catch (const InputError& e) {
    throw InputError("--excitation", e.bare_message());
  }
  const bool broadband = options.excitation != Excitation::kSteppedSine;
  for (const char* flag : {"--levels-v-rms", "--band-hz", "--grid"})
    if (args.Has(flag) && !broadband) throw InputError(flag, "applies to a broadband --excitation only");
  for (const char* flag : {"--frequencies-hz", "--amplitudes-v"})
    if (args.Has(flag) && broadband) throw InputError(flag, "applies to --excitation stepped-sine only");
  if (const auto list = args.Get("--levels-v-rms")) options.levels_v_rms = NumberList(*list, "--levels-v-rms");
  std::tie(options.broadband.band_low_hz, options.broadband.band_high_hz) =
      args.Range("--band-hz", options.broadband.band_low_hz, options.broadband.band_high_hz);
  const std::string grid = args.GetOr("--grid", "odd");
  if (grid != "odd" && grid != "full") throw InputError("--grid", "expected odd or full, got '" + grid + "'");
  if (args.Has("--grid") && options.excitation != Excitation::kMultisine)
    throw InputError("--grid", "applies to --excitation multisine only");
  options.broadband.odd_grid = grid == "odd";
  options.duration_s = args.Number("--duration-s", options.duration_s);
  options.settle_s = args.Number("--settle-s", options.settle_s);
  options.sample_rate_hz = args.Number("--sample-rate-hz", options.sample_rate_hz);
  try {
    options.response = ParseResponseKind(args.GetOr("--response", "force"));
  } catch (const InputError& e) {
    throw InputError("--response", e.bare_message());
  }
  options.sensitivity = args.Number("--sensitivity", 0.0);
  options.nominal = args.Has("--nominal");
  options.noise_rms_v = args.Number("--noise-rms", 0.0);
  options.voltage_noise_rms_v = args.Number("--voltage-noise-rms", 0.0);
  options.offset_v = args.Number("--offset-v", 0.0);
  options.hum_v = args.Number("--hum-v", 0.0);
  options.hum_hz = args.Number("--hum-hz", options.hum_hz);
  options.perturb = PerturbList(args.GetAll("--perturb"));
  if (const auto seed = args.Get("--seed")) {
    size_t used = 0;
    try {
      options.seed = std::stoull(*seed, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != seed->size() || (*seed)[0] == '-')
      throw InputError("--seed", "expected a non-negative integer, got '" + *seed + "'");
  }
  if (const auto method = args.Get("--method")) {
    try {  // perturbations keep a zero term zero, so the nominal model has the simulated model's terms
      const MethodChoice choice = ChooseMethod(*method, model);
      if (*method != "auto") options.method = choice.method;
    } catch (const InputError& e) {
      throw InputError("--method", e.bare_message());
    }
  }
  if (const auto actuator = args.Get("--actuator")) options.actuator = *actuator;
  options.threads = args.Integer("--threads", 0);
  const CampaignFormat format = ParseCampaignFormat(args.GetOr("--format", "csv"), "--format");
  const WavSampleFormat wav_format = ParseWavSampleFormat(args.GetOr("--wav-format", "float32"), "--wav-format");
  if (args.Has("--wav-format") && format != CampaignFormat::kWav)
    throw InputError("--wav-format", "applies to --format wav only");

  Synthesis synthesis;
  try {
    synthesis = Synthesize(model, options);
  } catch (const InputError& e) {
    static const std::map<std::string, std::string> kFlags = {{"frequencies_hz", "--frequencies-hz"},
                                                              {"amplitudes_v", "--amplitudes-v"},
                                                              {"levels_v_rms", "--levels-v-rms"},
                                                              {"band_low_hz", "--band-hz"},
                                                              {"band_high_hz", "--band-hz"},
                                                              {"duration_s", "--duration-s"},
                                                              {"settle_s", "--settle-s"},
                                                              {"sample_rate_hz", "--sample-rate-hz"},
                                                              {"sensitivity", "--sensitivity"},
                                                              {"noise_rms_v", "--noise-rms"},
                                                              {"voltage_noise_rms_v", "--voltage-noise-rms"},
                                                              {"offset_v", "--offset-v"},
                                                              {"hum_v", "--hum-v"},
                                                              {"hum_hz", "--hum-hz"},
                                                              {"perturb", "--perturb"},
                                                              {"threads", "--threads"},
                                                              {"method", "--method"}};
    const auto flag = kFlags.find(e.field());
    if (flag == kFlags.end()) throw;
    throw InputError(flag->second, e.bare_message());
  }
  const std::filesystem::path truth_path = args.Has("--truth") ? std::filesystem::path(*args.Get("--truth"))
                                                               : std::filesystem::path(*out_dir) / "truth.json";
  WriteSynthesis(synthesis, *out_dir, truth_path, format, wav_format);
  std::cout << "wrote " << synthesis.campaign.records.size() << " records ("
            << (format == CampaignFormat::kCsv ? "" : std::string(ToString(format)) + ", ")
            << ToString(synthesis.campaign.response)
            << (synthesis.campaign.records.empty() || !synthesis.campaign.records[0].broadband
                    ? ""
                    : std::string(", ") + ToString(options.excitation))
            << ", method " << synthesis.engine << ") to " << *out_dir << "; truth in " << truth_path.string()
            << "\n";
  return 0;
}

}  // namespace strokelab::cli
