// The broadband drives a test rig uses, sampled at fs (`strokelab synth --excitation`):
//
//   multisine  sum_k A cos(2 pi k f0 t + phi_k) over the lines k f0 in the band, f0 = 1 / period,
//              equal amplitudes, phases uniform in [0, 2 pi) (a random-phase multisine; Pintelon and
//              Schoukens, "System Identification: A Frequency Domain Approach", 2nd ed., Wiley 2012,
//              Sec. 2.2 and 3.4). The odd grid keeps the odd k only: the even lines stay free, and
//              even-order distortion shows there. Periodic in `period_s`.
//   noise      Gaussian noise band-limited to the band: the same sum over every line of a grid 1 / T
//              for the signal's whole length T, with Rayleigh amplitudes (random amplitude and phase,
//              Pintelon and Schoukens Sec. 3.4.1): not periodic within the record.
//   sweep      a logarithmic swept sine from the band's low to its high edge over `period_s`
//              (Farina, "Simultaneous measurement of impulse response and distortion with a swept-sine
//              technique", AES 108th Convention, 2000): phase 2 pi f1 T / ln(f2 / f1) (e^{t ln(f2/f1) / T} - 1)
//              for t in [0, T); before t = 0 it holds the sine at f1 (the settling part), after T at f2.
//
// Each signal is scaled to the given rms level (the sweep: amplitude sqrt(2) level). Samples are at
// t_n = t0 + n / fs; the random numbers come from `uniform` (values in [0, 1)), in a fixed order.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "strokelab/base/errors.h"

namespace strokelab {

enum class Excitation { kSteppedSine, kMultisine, kNoise, kSweep };
Excitation ParseExcitation(std::string_view text);  // throws InputError("excitation", ...)
const char* ToString(Excitation excitation);         // "stepped-sine", "multisine", "noise", "sweep"

struct BroadbandSignal {
  Excitation excitation = Excitation::kMultisine;
  double band_low_hz = 2.0;    // [Hz], > 0 for the sweep
  double band_high_hz = 200.0; // [Hz], below the Nyquist frequency
  double level_v_rms = 0.1;    // [V rms]
  bool odd_grid = true;        // multisine: odd multiples of 1 / period only
  double period_s = 1.0;       // multisine: its period; sweep: its length [s]

  // Nothing, or the offending field (band_low_hz, band_high_hz, level_v_rms, period_s), for a record
  // sampled at sample_rate_hz: the band must hold at least one line of the grid.
  std::optional<FieldError> IsValid(double sample_rate_hz) const;
};

// `count` samples at t_n = t0_s + n / fs. `length_s` is the noise's whole length T (its grid 1 / T);
// the other kinds ignore it.
std::vector<double> BroadbandVoltage(const BroadbandSignal& signal, double sample_rate_hz, double t0_s, size_t count,
                                     double length_s, const std::function<double()>& uniform);

}  // namespace strokelab
