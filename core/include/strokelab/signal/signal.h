// Signal analysis for simulated and recorded signals alike:
// complex amplitudes at the drive frequency and its harmonics, first-order FRFs (paper section 3),
// Hann-windowed spectra (paper Fig. 3), spikes and contact times (paper section 4.1, Fig. 8),
// RSD (paper Eq. 6 with its square root restored), k_s from contact time (paper Eq. 5 and the exact
// damped relation), and the stepped-sine frequency grid (paper Eq. 1).
#pragma once

#include <complex>
#include <cstddef>
#include <span>
#include <vector>

namespace strokelab {

// A window [begin, end) of sample indices holding a whole number of drive periods.
struct SampleWindow {
  size_t begin = 0;
  size_t end = 0;
  double periods = 0.0;  // whole drive periods covered (dimensionless)
  size_t size() const { return end - begin; }
};

// The last whole drive periods of a record of `sample_count` samples that fit in `span_s` seconds
// (at least one period, if the record holds one): the steady-state window of the CLI summaries.
// Throws InputError("frequency_hz") if the record is shorter than one period.
SampleWindow LastWholePeriods(size_t sample_count, double sample_rate_hz, double frequency_hz, double span_s = 1.0);

// Complex amplitudes C_h (h = 1..orders) of signal(t) ~ c_0 + sum_h Re(C_h exp(j h w t)), by linear
// least squares over the window, with t = n / fs the absolute time of sample n (so phases are
// comparable between channels). Exact for any signal made of those harmonics, whatever the window.
std::vector<std::complex<double>> HarmonicAmplitudes(std::span<const double> signal, double sample_rate_hz,
                                                     double frequency_hz, SampleWindow window, int orders);
// C_1 only.
std::complex<double> FirstHarmonic(std::span<const double> signal, double sample_rate_hz, double frequency_hz,
                                   SampleWindow window);

// First-order FRF at the drive frequency: C_1(output) / C_1(drive) (paper section 3).
std::complex<double> FirstOrderFrf(std::span<const double> output, std::span<const double> drive,
                                   double sample_rate_hz, double frequency_hz, SampleWindow window);

// One-sided amplitude spectrum with a Hann window (paper Fig. 3), scaled so that a sinusoid of
// amplitude A at a bin frequency reads A.
struct Spectrum {
  std::vector<double> frequency_hz;
  std::vector<double> amplitude;  // same unit as the signal
};
Spectrum HannSpectrum(std::span<const double> signal, double sample_rate_hz);

// The root mean square of a signal about its mean (a record's level with its offset taken out).
double RmsAboutMean(std::span<const double> signal);

// A force spike left by an impact on a stop.
struct Spike {
  size_t peak_index = 0;
  double peak_time_s = 0.0;
  double peak_height = 0.0;     // peak minus the smooth baseline, signal units (negative for downward spikes)
  double start_s = 0.0;         // estimated contact start
  double end_s = 0.0;           // estimated contact end
  double ContactTimeS() const { return end_s - start_s; }
};
struct SpikeOptions {
  // A spike rises above the baseline by more than this many robust standard deviations.
  double threshold_sigmas = 8.0;
  // Harmonics of the drive kept in the smooth baseline.
  int baseline_harmonics = 5;
};
// Finds the one-sided impact spikes in a force signal over a window and estimates each contact's
// duration as the half-sine base width (Nagurka and Huang, paper Eq. 4): 1.5 x the width at half height,
// with start_s/end_s centred on the half-height midpoint. Only the window's samples are analysed; a spike
// whose half-height crossing lies outside the window is not reported. The polarity is the side of the
// larger extreme deviation from the baseline; flagged runs closer than a few samples count as one spike.
// Throws InputError naming a bad argument.
std::vector<Spike> DetectSpikes(std::span<const double> force, double sample_rate_hz, double drive_frequency_hz,
                                SampleWindow window, const SpikeOptions& options = {});

// Mean contact time and its relative standard deviation, paper Eq. 6 with the square root restored
// (as printed it has none): RSD = sqrt(sum (dT_n - E[dT])^2 / (N - 1)) / E[dT]. NaN for N < 2.
struct ContactTimeStatistics {
  size_t count = 0;
  double mean_s = 0.0;
  double rsd = 0.0;  // dimensionless
};
ContactTimeStatistics ContactTimeStats(std::span<const double> contact_times_s);

// Paper Eq. 5: k_s = m_p (pi / dT)^2 (assumes k_s >> k_p, no damping) [N/m].
double ContactStiffnessEq5(double mass_kg, double contact_time_s);
// The exact relation for a damped linear contact: dT = pi / w_d with
// w_d^2 = (k_p + k_s) / m_p - (c / 2 m_p)^2, c = c_p + c_s, solved for k_s [N/m].
double ContactStiffnessDamped(double mass_kg, double contact_time_s, double suspension_stiffness_n_per_m,
                              double total_damping_n_s_per_m);
// The damped half-period pi / w_d of the contact oscillator [s].
double ContactHalfPeriodS(double mass_kg, double suspension_stiffness_n_per_m, double contact_stiffness_n_per_m,
                          double total_damping_n_s_per_m);

// Paper Eq. 1: w(n) = 10 pi 1.02^(n-1) rad/s, i.e. f(n) = 5 Hz 1.02^(n-1), n = 1..count [Hz].
std::vector<double> PaperFrequencyGridHz(int count = 117);

}  // namespace strokelab
