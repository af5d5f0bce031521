// The synth side of gen2 campaign shapes that tests reproduce (tools/gen2).
#pragma once

#include "strokelab/data/synth.h"

namespace strokelab::testing {

// gen2's accelerometer at 44.1 kHz (seeds 9706-9709): 6 x 3 stepped sines from 4.5 to 12 Hz, each
// a whole number of samples a period, 1.5 s kept after 5 s of settling, 0.5 mV of noise.
inline SynthOptions Gen2Accelerometer44kHz() {
  SynthOptions o;
  o.frequencies_hz = {4.5, 6, 7.5, 9, 10.5, 12};
  o.amplitudes_v = {0.15, 0.3, 0.45};
  o.duration_s = 1.5;
  o.settle_s = 5.0;
  o.sample_rate_hz = 44100.0;
  o.response = ResponseKind::kAcceleration;
  o.noise_rms_v = 0.0005;
  return o;
}

}  // namespace strokelab::testing
