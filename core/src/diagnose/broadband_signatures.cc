// Signatures of a broadband record's misfit (broadband_diagnose.h, step 3), from the base model's
// residuals and motion at every sample: where in the state space, near which events and at which
// frequencies the residual stands above the noise.
#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <numbers>
#include <unsupported/Eigen/FFT>

#include "diagnose_internal.h"
#include "strokelab/base/nan.h"
#include "strokelab/identify/broadband_campaign.h"

namespace strokelab::internal {
namespace {

constexpr double kContactWindowS = 2e-3;  // "near a contact": within 2 ms of a sample in contact
constexpr double kTailShare = 0.2;        // "far out", "slow", "fast": the outer fifth of the samples
constexpr size_t kWelchLength = 512;      // spectra: Hann windows of 512 samples, half overlapping

// Samples of one part: its residual over its noise level squared (mean 1 under noise alone), and the
// model's state there.
struct Sample {
  double chi2 = 0.0;
  double x = 0.0, v = 0.0;  // x relative to the part's mean [m], v [m/s]
  bool near_contact = false;
};

// The samples where the model's motion is inside one of its stops.
std::vector<bool> ModelContacts(const ActuatorModel& model, const BroadbandRecordFit& fit) {
  std::vector<bool> contact(fit.x_m.size(), false);
  for (size_t i = 0; i < contact.size(); ++i) {
    const double x = fit.x_m[i];
    contact[i] = (model.HasLowerStop() && x < model.lower_stop_m) || (model.HasUpperStop() && x > model.upper_stop_m);
  }
  return contact;
}

// The samples within kContactWindowS of a marked one, at the sample rate fs.
std::vector<bool> WithinContactWindow(const std::vector<bool>& marked, double fs) {
  const size_t n = marked.size(), reach = static_cast<size_t>(std::ceil(kContactWindowS * fs));
  std::vector<bool> near(n, false);
  for (size_t i = 0; i < n; ++i)
    if (marked[i])
      for (size_t k = i - std::min(i, reach); k < std::min(n, i + reach + 1); ++k) near[k] = true;
  return near;
}

std::vector<Sample> SamplesOf(std::span<const Recording> parts, std::span<const BroadbandRecordFit> fits,
                              const ActuatorModel& model) {
  std::vector<Sample> out;
  for (size_t r = 0; r < parts.size(); ++r) {
    const BroadbandRecordFit& f = fits[r];
    const std::vector<bool> near = WithinContactWindow(ModelContacts(model, f), parts[r].sample_rate_hz);
    double mean = 0.0;
    size_t finite = 0;
    for (double x : f.x_m)
      if (std::isfinite(x)) mean += x, ++finite;
    mean /= std::max<size_t>(1, finite);
    for (size_t i = 0; i < f.residual.size(); ++i) {
      if (!std::isfinite(f.residual[i])) continue;
      const double z = f.residual[i] / f.noise_rms;
      out.push_back({z * z, f.x_m[i] - mean, f.v_m_per_s[i], near[i]});
    }
  }
  return out;
}

// The q-quantile of `values` (0 <= q <= 1).
double Quantile(std::vector<double> values, double q) {
  if (values.empty()) return kNaN;
  const size_t k = std::min(values.size() - 1, static_cast<size_t>(q * static_cast<double>(values.size())));
  std::nth_element(values.begin(), values.begin() + static_cast<long>(k), values.end());
  return values[k];
}

// Evidence that the residual's chi-square per sample differs between the samples `in` selects and the
// rest (or those `against` selects): the difference of the two means, whose standard error under
// noise alone (independent samples of chi-square(1)) is sqrt(2 / n_in + 2 / n_out).
template <typename In, typename Against>
Evidence Contrast(const std::vector<Sample>& samples, std::string kind, const std::string& where,
                  const std::string& elsewhere, std::vector<Effect> points_to, In in, Against against) {
  double sum_in = 0, sum_out = 0;
  size_t n_in = 0, n_out = 0;
  for (const Sample& s : samples) {
    if (in(s)) sum_in += s.chi2, ++n_in;
    else if (against(s)) sum_out += s.chi2, ++n_out;
  }
  Evidence e;
  e.kind = std::move(kind);
  if (n_in < 8 || n_out < 8) {
    e.value = kNaN;
    e.summary = "too few samples " + where + " to compare";
    return e;
  }
  const double mean_in = sum_in / n_in, mean_out = sum_out / n_out;
  e.value = mean_in - mean_out;
  e.standard_error = std::sqrt(2.0 / n_in + 2.0 / n_out);
  e.significance = std::abs(e.value) / e.standard_error;
  e.summary = "the residual's chi-square per sample is " + FormatFigure(mean_in) + " " + where + " against " +
              FormatFigure(mean_out) + " " + elsewhere + " (1 is noise; the difference is " +
              FormatFigure(e.significance) + " standard errors)";
  if (e.value > 0) e.points_to = std::move(points_to);
  return e;
}

// Welch estimates over every part: the residual's power over its noise level per bin (1 is white
// noise), and its magnitude-squared coherence with the drive, on a common bin grid of kWelchLength.
struct Spectra {
  std::vector<double> frequency_hz, residual_over_noise, coherence, drive_power;
  int averages = 0;
};
Spectra WelchSpectra(std::span<const Recording> parts, std::span<const BroadbandRecordFit> fits) {
  Spectra s;
  const size_t bins = kWelchLength / 2 + 1;
  std::vector<double> window(kWelchLength), suu(bins, 0.0), srr(bins, 0.0);
  std::vector<std::complex<double>> sru(bins, 0.0);
  double window_power = 0.0;
  for (size_t k = 0; k < kWelchLength; ++k) {
    window[k] = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * k / kWelchLength);
    window_power += window[k] * window[k];
  }
  Eigen::FFT<double> fft;
  std::vector<double> u(kWelchLength), r(kWelchLength);
  std::vector<std::complex<double>> u_bins, r_bins;
  double fs = 0.0;
  for (size_t p = 0; p < parts.size(); ++p) {
    const Recording& part = parts[p];
    fs = part.sample_rate_hz;
    for (size_t start = 0; start + kWelchLength <= part.size(); start += kWelchLength / 2) {
      bool finite = true;
      for (size_t k = 0; k < kWelchLength; ++k) {
        u[k] = part.voltage_v[start + k] * window[k];
        r[k] = fits[p].residual[start + k] / fits[p].noise_rms * window[k];
        finite = finite && std::isfinite(r[k]);
      }
      if (!finite) continue;
      fft.fwd(u_bins, u);
      fft.fwd(r_bins, r);
      for (size_t k = 0; k < bins; ++k) {
        suu[k] += std::norm(u_bins[k]);
        srr[k] += std::norm(r_bins[k]);
        sru[k] += r_bins[k] * std::conj(u_bins[k]);
      }
      ++s.averages;
    }
  }
  if (s.averages == 0) return s;
  for (size_t k = 1; k < bins; ++k) {
    s.frequency_hz.push_back(static_cast<double>(k) * fs / kWelchLength);
    s.residual_over_noise.push_back(srr[k] / (s.averages * window_power));
    s.coherence.push_back(suu[k] > 0 && srr[k] > 0 ? std::norm(sru[k]) / (suu[k] * srr[k]) : 0.0);
    s.drive_power.push_back(suu[k]);
  }
  return s;
}

// The drive's band: bins whose drive power is within 20 dB of its largest.
std::vector<bool> DriveBand(const Spectra& s) {
  const double peak = s.drive_power.empty() ? 0.0 : *std::max_element(s.drive_power.begin(), s.drive_power.end());
  std::vector<bool> band(s.drive_power.size());
  for (size_t k = 0; k < band.size(); ++k) band[k] = s.drive_power[k] >= 0.01 * peak;
  return band;
}

}  // namespace

std::vector<Evidence> BroadbandSignatures(std::span<const Recording> parts, std::span<const BroadbandRecordFit> fits,
                                          const ActuatorModel& model) {
  const std::vector<Sample> samples = SamplesOf(parts, fits, model);
  std::vector<double> x_abs, v_abs;
  for (const Sample& s : samples) x_abs.push_back(std::abs(s.x)), v_abs.push_back(std::abs(s.v));
  const double far = Quantile(x_abs, 1.0 - kTailShare);
  const double slow = Quantile(v_abs, kTailShare), fast = Quantile(v_abs, 1.0 - kTailShare);
  auto rest = [](const Sample&) { return true; };
  std::vector<Evidence> out;
  out.push_back(Contrast(samples, "residual_far_out", "where the model's displacement is in its outer fifth",
                         "elsewhere", {Effect::kCubicStiffness, Effect::kForceFactor},
                         [&](const Sample& s) { return std::abs(s.x) >= far; }, rest));
  out.push_back(Contrast(samples, "residual_asymmetry", "at the outer fifth's positive side",
                         "at its negative side", {Effect::kQuadraticStiffness, Effect::kForceFactor, Effect::kSecondStop},
                         [&](const Sample& s) { return s.x >= far; }, [&](const Sample& s) { return s.x <= -far; }));
  out.push_back(Contrast(samples, "residual_at_low_velocity", "at the slowest fifth of the motion", "elsewhere",
                         {Effect::kDryFriction}, [&](const Sample& s) { return std::abs(s.v) <= slow; }, rest));
  out.push_back(Contrast(samples, "residual_at_high_velocity", "at the fastest fifth of the motion", "elsewhere",
                         {Effect::kQuadraticDamping}, [&](const Sample& s) { return std::abs(s.v) >= fast; }, rest));
  if (std::any_of(samples.begin(), samples.end(), [](const Sample& s) { return s.near_contact; }))
    out.push_back(Contrast(samples, "residual_near_contacts", "within 2 ms of the model's contacts", "elsewhere",
                           {Effect::kHertzianContact, Effect::kContactDamping},
                           [](const Sample& s) { return s.near_contact; }, rest));

  // The spectrum and the coherence with the drive: a misfit linear in the drive (a dynamic the linear
  // part lacks, such as the coil's electrical pole) is coherent with it; a nonlinearity's is mostly not.
  const Spectra spectra = WelchSpectra(parts, fits);
  if (spectra.averages > 1) {
    const std::vector<bool> band = DriveBand(spectra);
    double in_band = 0, out_band = 0, coherence = 0, peak = 0, peak_hz = kNaN;
    size_t band_bins = 0, out_bins = 0;
    for (size_t k = 0; k < band.size(); ++k) {
      const double excess = spectra.residual_over_noise[k] - 1.0;
      if (band[k]) in_band += excess, coherence += spectra.coherence[k], ++band_bins;
      else out_band += excess, ++out_bins;
      if (excess > peak) peak = excess, peak_hz = spectra.frequency_hz[k];
    }
    Evidence spectrum;
    spectrum.kind = "residual_spectrum";
    // Each bin's power over noise averages `averages` squared Hann-windowed transforms: under noise its
    // standard error is about 1 / sqrt(averages / 2) (half-overlapping windows are correlated).
    const double bin_se = std::sqrt(2.0 / spectra.averages);
    spectrum.value = band_bins ? in_band / band_bins : kNaN;
    spectrum.standard_error = bin_se / std::sqrt(std::max<size_t>(1, band_bins));
    spectrum.significance = std::isfinite(spectrum.value) ? std::abs(spectrum.value) / spectrum.standard_error : 0.0;
    spectrum.summary = "the residual's power over noise's is " + FormatFigure(1.0 + spectrum.value) +
                       " within the drive's band and " + FormatFigure(out_bins ? 1.0 + out_band / out_bins : kNaN) +
                       " outside it (1 is noise); its largest excess is at " + FormatFigure(peak_hz) + " Hz";
    out.push_back(spectrum);
    Evidence coherent;
    coherent.kind = "residual_coherence";
    // Under noise alone the estimate's mean is about 1 / averages (its bias), with a spread of the same size.
    const double bias = 1.0 / spectra.averages;
    coherent.value = band_bins ? coherence / band_bins : kNaN;
    coherent.standard_error = bias / std::sqrt(std::max<size_t>(1, band_bins));
    coherent.significance =
        std::isfinite(coherent.value) ? std::max(0.0, coherent.value - bias) / coherent.standard_error : 0.0;
    coherent.summary = "the residual's coherence with the drive over its band is " + FormatFigure(coherent.value) +
                       " (about " + FormatFigure(bias) + " for noise alone): " +
                       (coherent.value > 0.5 ? "the misfit is mostly linear in the drive"
                                             : "the misfit is mostly not linear in the drive");
    if (coherent.value > 0.5) coherent.points_to = {Effect::kCoilInductance, Effect::kAmplifierSaturation};
    out.push_back(coherent);
  }
  return out;
}

double ResidualPeakFrequencyHz(const Recording& part, const BroadbandRecordFit& fit) {
  const Spectra s = WelchSpectra(std::span(&part, 1), std::span(&fit, 1));
  double peak = -std::numeric_limits<double>::infinity(), peak_hz = kNaN;
  for (size_t k = 0; k < s.frequency_hz.size(); ++k)
    if (s.residual_over_noise[k] > peak) peak = s.residual_over_noise[k], peak_hz = s.frequency_hz[k];
  return peak_hz;
}

std::pair<double, double> NearContactShares(const Recording& part, ResponseKind kind, const BroadbandRecordFit& fit,
                                            const ActuatorModel& model) {
  std::vector<bool> contact = ModelContacts(model, fit);
  const std::vector<bool> impact = RecordImpacts(part, kind);
  for (size_t i = 0; i < impact.size() && i < contact.size(); ++i)
    if (impact[i]) contact[i] = true;
  const std::vector<bool> near = WithinContactWindow(contact, part.sample_rate_hz);
  double excess_near = 0, excess = 0;
  size_t n_near = 0, n = 0;
  for (size_t i = 0; i < fit.residual.size(); ++i) {
    if (!std::isfinite(fit.residual[i])) continue;
    const double z = fit.residual[i] / fit.noise_rms, e = z * z - 1.0;
    excess += e, ++n;
    if (near[i]) excess_near += e, ++n_near;
  }
  if (n_near == 0) return {kNaN, kNaN};
  return {excess > 0 ? excess_near / excess : kNaN, static_cast<double>(n_near) / std::max<size_t>(1, n)};
}

}  // namespace strokelab::internal
