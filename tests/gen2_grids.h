// The synth side of gen2 campaign shapes that tests reproduce (tools/gen2).
#pragma once

#include "strokelab/data/synth.h"
#include "strokelab/model/model.h"

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

// The paper model with the parameters gen2 drew for its control 9706 (the accelerometer at 44.1 kHz).
inline ActuatorModel Gen2Control9706() {
  ActuatorModel m = PaperModel();
  m.damping_n_s_per_m = 1.183820154900177;
  m.stiffness_n_per_m = 124.92920447054878;
  m.gain_n_per_v = 0.2960544821068345;
  m.lower_stop_m = -0.0010455116107510216;
  m.contact_stiffness = 1356975.314758823;
  return m;
}

}  // namespace strokelab::testing
