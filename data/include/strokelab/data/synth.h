// Synthetic campaigns with known truth (`strokelab synth`): a model simulated as the test rig would
// record it, with sensor noise, a DC offset, mains hum and parameters perturbed from their nominal
// values, so that fitting and diagnosis can be tested on campaigns whose truth only the test knows.
//
// Each record is one stepped-sine step (amplitudes outer, frequencies inner: record k is amplitude
// k / F, frequency k % F), simulated from rest for settle_s + duration_s with the drive
// v_in = V sin(2 pi f (1 + drive_frequency_error) t + theta_k) starting at t = 0; the last duration_s
// are kept and re-timed from 0. With a broadband excitation (excitation.h) each record is one level of
// levels_v_rms instead: the signal's own random numbers per record, the multisine's period and the
// sweep's length are duration_s (the kept part starts a period, or the sweep, at t = 0; the settling
// part before it repeats the multisine, or holds the sweep's first frequency), and the motion is the
// variational flow's (variational_flow.h) driven by the first-order hold of the generated samples. The
// channels, in sensor volts as written:
//
//   voltage   v_in(t) + voltage_offset_v + N(0, voltage_noise_rms_v^2)   (before the amplifier: unclipped)
//   response  s_true r(t) + offset_v + hum_v sin(2 pi hum_hz t + phi_k) + N(0, noise_rms_v^2)
//
// with r the model's response in physical units (force: blocked force f = m_p x'' [N];
// acceleration: x'' [m/s^2]; velocity: x' [m/s]; displacement: x [m]), phi_k a random hum phase per
// record, theta_k a random drive phase per record (random_drive_phase; else 0) and s_true the
// sensitivity the sensor really has (the written one unless perturbed or sensitivity_error is set).
// The manifest says nothing of the truth (it keeps the nominal frequency f); Synthesis::truth does
// (written as truth.json).
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "strokelab/identify/campaign.h"
#include "strokelab/engines/engine.h"
#include "strokelab/model/model.h"
#include "strokelab/data/excitation.h"
#include "strokelab/data/mapping.h"
#include "strokelab/data/recordings.h"

namespace strokelab {

struct SynthOptions {
  std::vector<double> frequencies_hz = {6, 7, 8, 9, 11, 13};  // drive frequencies [Hz] (inner loop)
  std::vector<double> amplitudes_v = {0.1, 0.3, 0.4, 0.5};    // drive amplitudes [V] (outer loop)
  // A broadband campaign when not kSteppedSine: one record per level [V rms], band and grid from
  // `broadband` (its level and period are set per record).
  Excitation excitation = Excitation::kSteppedSine;
  BroadbandSignal broadband;
  std::vector<double> levels_v_rms = {0.05, 0.15, 0.3};
  double duration_s = 1.0;                                    // kept length of each record [s]
  double settle_s = 10.0;                                     // simulated from rest before the kept part [s]
  double sample_rate_hz = 51200.0;                            // fs [Hz]
  ResponseKind response = ResponseKind::kForce;
  double sensitivity = 0.0;          // written to the manifest [V per N, m/s^2, m/s or m]; 0: DefaultSensitivity
  bool nominal = false;              // the manifest calls the sensitivity nominal (absolute_scale false)
  double noise_rms_v = 0.0;          // Gaussian noise on the response channel [sensor V rms]
  double voltage_noise_rms_v = 0.0;  // Gaussian noise on the voltage channel [V rms]
  double offset_v = 0.0;             // DC offset on the response channel [sensor V]
  double hum_v = 0.0;                // mains hum amplitude on the response channel [sensor V]
  double hum_hz = 50.0;              // mains frequency [Hz]
  double voltage_offset_v = 0.0;     // DC offset on the voltage channel [V]
  // The signal generator's true / nominal frequency - 1, in (-1, 1) [dimensionless]: the manifest
  // keeps the nominal frequency, as a rig's would.
  double drive_frequency_error = 0.0;
  bool random_drive_phase = false;  // each drive starts at its own phase in [-pi, pi), drawn from the seed
  // The sensor's true / written sensitivity - 1, > -1 [dimensionless]: a fixed departure, where
  // perturb's "sensitivity" draws one (the two do not go together).
  double sensitivity_error = 0.0;
  // Relative perturbations (key, r): the value used is nominal * (1 + r u), u uniform in [-1, 1]
  // drawn from the seed, in the order given. Keys: model parameter keys or JSON names (model.h), or
  // "sensitivity" (the sensor's true sensitivity departs from the written one). r in [0, 1)
  // [dimensionless]. A zero or infinite parameter stays so.
  std::vector<std::pair<std::string, double>> perturb;
  std::uint64_t seed = 1;
  std::optional<Method> method;  // none: ChooseMethod's auto (exact for piecewise-linear models, else cvode);
                                 // broadband campaigns take none (the variational flow drives any model)
  std::string actuator = "inertial actuator, test rig";
  int threads = 0;  // records simulated side by side; 0: one thread per core

  // Nothing, or the offending field (frequencies_hz, amplitudes_v, duration_s, settle_s, sample_rate_hz,
  // sensitivity, noise_rms_v, voltage_noise_rms_v, offset_v, hum_v, hum_hz, voltage_offset_v,
  // drive_frequency_error, sensitivity_error, perturb, threads; broadband: levels_v_rms, method and
  // BroadbandSignal's fields).
  std::optional<FieldError> IsValid() const;
};

struct Synthesis {
  Campaign campaign;    // response in physical units of the written sensitivity (WriteCampaign's inverse)
  WriteOptions write;   // the written sensitivity
  ActuatorModel model;  // the model actually simulated (after perturbation)
  Method method = Method::kExact;  // the stepped sines' engine
  std::string engine;              // what simulated the records: ToString(method), or the flow for broadband
  // truth.json: model, nominal model, perturbations, sensitivities, noise, seed; the voltage offset,
  // frequency error and each record's drive phase only when set (so that older truths stay as they were)
  nlohmann::json truth;
};

// Results depend on the options and the seed only, not on the thread count.
Synthesis Synthesize(const ActuatorModel& model, const SynthOptions& options);

// WriteCampaign(synthesis.campaign, dir, synthesis.write) (format kCsv), or WriteMappedCampaign with
// the written sensitivity (UFF 58 ASCII or binary, WAV of `wav_format`; mapping.h), and the truth as
// JSON at `truth_path` (empty: dir / "truth.json").
void WriteSynthesis(const Synthesis& synthesis, const std::filesystem::path& dir,
                    const std::filesystem::path& truth_path = {}, CampaignFormat format = CampaignFormat::kCsv,
                    WavSampleFormat wav_format = WavSampleFormat::kFloat32);

}  // namespace strokelab
