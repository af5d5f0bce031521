#include "strokelab/engines/record_summary.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace strokelab {

RecordSummary Summarize(const Record& record, const SineDrive& drive, double span_s) {
  RecordSummary summary;
  const double fs = record.sample_rate_hz;
  summary.window = LastWholePeriods(record.size(), fs, drive.frequency_hz, span_s);
  const SampleWindow w = summary.window;

  const auto x_begin = record.displacement_m.begin() + static_cast<std::ptrdiff_t>(w.begin);
  const auto x_end = record.displacement_m.begin() + static_cast<std::ptrdiff_t>(w.end);
  const auto [x_min, x_max] = std::minmax_element(x_begin, x_end);
  summary.min_displacement_m = *x_min;
  summary.max_displacement_m = *x_max;

  double peak = 0.0;
  for (size_t n = w.begin; n < w.end; ++n) peak = std::max(peak, std::abs(record.force_n[n]));
  summary.peak_force_n = peak;

  // Contacts that start inside the window; durations from the closed ones.
  const double window_start_s = static_cast<double>(w.begin) / fs;
  const double window_end_s = static_cast<double>(w.end) / fs;
  std::vector<double> durations_s;
  for (const ContactInterval& c : record.contacts) {
    if (c.start_s < window_start_s || c.start_s >= window_end_s) continue;
    ++summary.contacts;
    if (c.closed) durations_s.push_back(c.DurationS());
  }
  const ContactTimeStatistics stats = ContactTimeStats(durations_s);
  summary.mean_contact_ms = stats.count > 0 ? stats.mean_s * 1e3 : std::nan("");
  summary.contact_time_rsd = stats.rsd;

  // The phase of H = C1(f) / C1(v_in), with the unclipped drive's C1 known in closed form:
  // v_in = V sin(w t + phi) = Re(V e^{j(phi - pi/2)} e^{j w t}).
  const std::complex<double> force_c1 = FirstHarmonic(record.force_n, fs, drive.frequency_hz, w);
  summary.first_harmonic_force_n = std::abs(force_c1);
  summary.first_harmonic_phase_rad = std::arg(force_c1 * std::polar(1.0, -(drive.phase_rad - M_PI / 2)));
  return summary;
}

}  // namespace strokelab
