// A broadband campaign that fits fast everywhere (in Release and under ASan): two short multisines of
// the paper's model that stay clear of the stop (0.05 and 0.1 V rms, 0.5 s at 4,096 Hz, 0.2 mV noise).
// For tests of what surrounds a broadband fit or diagnosis (its data, jobs, reports), not of its
// accuracy. The including test links strokelab::data.
#pragma once

#include <cstdint>

#include "strokelab/data/synth.h"
#include "strokelab/model/model.h"

namespace strokelab::testing {

inline Synthesis QuietMultisines(std::uint64_t seed) {
  SynthOptions o;
  o.excitation = Excitation::kMultisine;
  o.levels_v_rms = {0.05, 0.1};
  o.duration_s = 0.5;
  o.settle_s = 1.0;
  o.sample_rate_hz = 4096.0;
  o.noise_rms_v = 2e-4;
  o.seed = seed;
  return Synthesize(PaperModel(), o);
}

}  // namespace strokelab::testing
