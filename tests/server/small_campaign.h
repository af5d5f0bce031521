// The small synthetic campaign of the campaign-job tests (campaign_jobs_test, remote_campaign_test):
// the paper's model at 4 frequencies x 3 amplitudes (two below the stop, one above it), 0.5 s at
// 51.2 kHz after 3 s of settling, with sensor and voltage noise: a fit of ~1 s.
#pragma once

#include <cstdint>
#include <filesystem>

#include "strokelab/data/recordings.h"
#include "strokelab/data/synth.h"

namespace strokelab::testing {

// Writes the campaign into `dir` and its truth into `truth`.
inline void WriteSmallCampaign(const std::filesystem::path& dir, const std::filesystem::path& truth, uint64_t seed) {
  SynthOptions options;
  options.frequencies_hz = {6, 8, 11, 13};
  options.amplitudes_v = {0.1, 0.3, 0.45};
  options.duration_s = 0.5;
  options.settle_s = 3.0;
  options.noise_rms_v = 2e-3 * DefaultSensitivity(ResponseKind::kForce);
  options.voltage_noise_rms_v = 1e-4;
  options.seed = seed;
  WriteSynthesis(Synthesize(PaperModel(), options), dir, truth);
}

}  // namespace strokelab::testing
