// Complex amplitudes of the drive harmonics by linear least squares, the steady-state window, the
// first-order FRF (paper section 3) and the stepped-sine grid (paper Eq. 1).
//
// The fit. With theta_n = w n / fs and the basis [1, cos(h theta), sin(h theta)], h = 1..H, the normal
// equations G beta = b need
//   b = sum_n x_n [1, cos(h theta_n), sin(h theta_n)]       O(N H), accumulated below, and
//   G = sum_n phi_n phi_n^T,                                  whose entries are, by the product rules
//       cos a cos b = (cos(a-b) + cos(a+b))/2 etc., sums S(m) = sum_n exp(j m theta_n), m = 0..2H,
//       a geometric series with a closed form (the Dirichlet kernel), O(H).
// With at least one whole period in the window G is close to diag(N, N/2, ..., N/2), so the normal
// equations lose nothing worth mentioning against QR. FitHarmonicFamilies fits several series (drive
// harmonics and mains hum) by the same normal equations, G's entries from sums at c_k -+ c_l (JointGram:
// O(K^2) sums for K sinusoids, where one series needs O(H), so FitHarmonics keeps its own).
//
// The phasors exp(j h theta_n) are never computed by sin/cos per sample and harmonic: each block of
// kBlockSamples samples starts from an exact phasor (angle reduced to one cycle with fmod, so sample
// numbers of 10^7 keep full accuracy) and multiplies it by a table exp(j w k / fs), k < kBlockSamples;
// harmonic h+1 is harmonic h times the fundamental. The rounding error stays at a few ulps per block
// and grows like h ulps with the order.
#include <Eigen/Dense>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <sstream>
#include <string>

#include "strokelab/signal/harmonic_fit.h"
#include "strokelab/base/errors.h"
#include "strokelab/signal/signal.h"
#include "require_positive.h"

namespace strokelab {
namespace {

using signal_internal::RequirePositiveFinite;

constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr size_t kBlockSamples = 256;
// Below this reciprocal condition number the kept samples do not determine the harmonics.
constexpr double kMinReciprocalCondition = 1e-12;

// exp(j 2 pi cycles), with the angle reduced to one cycle first so that a large sample number costs
// no accuracy beyond the rounding of `cycles` itself.
std::complex<double> PhasorAtCycles(double cycles) {
  return std::polar(1.0, kTwoPi * std::fmod(cycles, 1.0));
}

// Columns of the basis: 0 is the offset, then cos and sin of each harmonic.
size_t CosColumn(int h) { return static_cast<size_t>(2 * h - 1); }
size_t SinColumn(int h) { return static_cast<size_t>(2 * h); }

// sum_i a[i] b[i] with four partial sums: breaks the dependency chain so that it runs at throughput.
double Dot(const double* a, const double* b, size_t n) {
  double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
  size_t i = 0;
  for (; i + 4 <= n; i += 4) {
    s0 += a[i] * b[i];
    s1 += a[i + 1] * b[i + 1];
    s2 += a[i + 2] * b[i + 2];
    s3 += a[i + 3] * b[i + 3];
  }
  for (; i < n; ++i) s0 += a[i] * b[i];
  return (s0 + s1) + (s2 + s3);
}

// Unit phasors exp(j h w t_n) over a block of consecutive samples, one harmonic after the other.
class PhasorBlock {
 public:
  explicit PhasorBlock(double cycles_per_sample) {
    for (size_t k = 0; k < kBlockSamples; ++k) {
      const std::complex<double> z = PhasorAtCycles(cycles_per_sample * static_cast<double>(k));
      step_cos_[k] = z.real();
      step_sin_[k] = z.imag();
    }
    cycles_per_sample_ = cycles_per_sample;
  }

  // Starts a block of `length` <= kBlockSamples samples at absolute sample `first`, at harmonic 1.
  void Start(size_t first, size_t length) {
    length_ = length;
    const std::complex<double> z0 = PhasorAtCycles(cycles_per_sample_ * static_cast<double>(first));
    for (size_t k = 0; k < length; ++k) {
      fundamental_cos_[k] = z0.real() * step_cos_[k] - z0.imag() * step_sin_[k];
      fundamental_sin_[k] = z0.real() * step_sin_[k] + z0.imag() * step_cos_[k];
    }
    cos_ = fundamental_cos_;
    sin_ = fundamental_sin_;
  }

  // Harmonic h -> h + 1: exp(j (h+1) theta) = exp(j h theta) exp(j theta).
  void NextHarmonic() {
    for (size_t k = 0; k < length_; ++k) {
      const double c = cos_[k] * fundamental_cos_[k] - sin_[k] * fundamental_sin_[k];
      const double s = cos_[k] * fundamental_sin_[k] + sin_[k] * fundamental_cos_[k];
      cos_[k] = c;
      sin_[k] = s;
    }
  }

  const double* cos() const { return cos_.data(); }
  const double* sin() const { return sin_.data(); }

 private:
  using Block = std::array<double, kBlockSamples>;
  double cycles_per_sample_ = 0.0;
  size_t length_ = 0;
  Block step_cos_{}, step_sin_{};              // exp(j w k / fs), k = 0..kBlockSamples-1
  Block fundamental_cos_{}, fundamental_sin_{};
  Block cos_{}, sin_{};                        // the current harmonic
};

// b = sum_i values[i] phi(first + i), in basis-column order.
Eigen::VectorXd ProjectOntoBasis(std::span<const double> values, size_t first, double cycles_per_sample,
                                 int orders) {
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(2 * orders + 1);
  PhasorBlock block(cycles_per_sample);
  for (size_t i0 = 0; i0 < values.size(); i0 += kBlockSamples) {
    const size_t length = std::min(kBlockSamples, values.size() - i0);
    const double* x = values.data() + i0;
    for (size_t k = 0; k < length; ++k) rhs[0] += x[k];
    if (orders == 0) continue;
    block.Start(first + i0, length);
    for (int h = 1; h <= orders; ++h) {
      if (h > 1) block.NextHarmonic();
      rhs[CosColumn(h)] += Dot(x, block.cos(), length);
      rhs[SinColumn(h)] += Dot(x, block.sin(), length);
    }
  }
  return rhs;
}

// S(m) = sum_{n=first}^{first+count-1} exp(j m theta_n), m = 0..2 orders, in closed form:
// exp(j m theta_mid) sin(pi m c N) / sin(pi m c) with c = f / fs and theta_mid the angle at the
// window's middle. Needs 2 orders c < 1 (checked by the caller: harmonics below Nyquist), so that
// sin(pi m c) > 0 for m >= 1.
std::vector<std::complex<double>> PhasorSums(size_t first, size_t count, double cycles_per_sample, int orders) {
  const double n = static_cast<double>(count);
  const double middle = static_cast<double>(first) + 0.5 * (n - 1.0);
  std::vector<std::complex<double>> sums(2 * orders + 1);
  sums[0] = n;
  for (int m = 1; m <= 2 * orders; ++m) {
    const double c = m * cycles_per_sample;
    const double dirichlet = std::sin(std::numbers::pi * std::fmod(c * n, 2.0)) / std::sin(std::numbers::pi * c);
    sums[m] = dirichlet * PhasorAtCycles(c * middle);
  }
  return sums;
}

// G = sum_n phi_n phi_n^T over a contiguous window, from the sums S(m) (product-to-sum rules).
Eigen::MatrixXd ClosedFormGram(size_t first, size_t count, double cycles_per_sample, int orders) {
  const std::vector<std::complex<double>> s = PhasorSums(first, count, cycles_per_sample, orders);
  auto c = [&](int m) { return s[std::abs(m)].real(); };                     // sum cos(m theta)
  auto sn = [&](int m) { return m < 0 ? -s[-m].imag() : s[m].imag(); };     // sum sin(m theta)
  Eigen::MatrixXd gram(2 * orders + 1, 2 * orders + 1);
  gram(0, 0) = c(0);
  for (int h = 1; h <= orders; ++h) {
    gram(0, CosColumn(h)) = gram(CosColumn(h), 0) = c(h);
    gram(0, SinColumn(h)) = gram(SinColumn(h), 0) = sn(h);
    for (int k = 1; k <= orders; ++k) {
      gram(CosColumn(h), CosColumn(k)) = 0.5 * (c(h - k) + c(h + k));
      gram(SinColumn(h), SinColumn(k)) = 0.5 * (c(h - k) - c(h + k));
      gram(CosColumn(h), SinColumn(k)) = gram(SinColumn(k), CosColumn(h)) = 0.5 * (sn(h + k) + sn(k - h));
    }
  }
  return gram;
}

// G -= phi_n phi_n^T: takes sample n out of the Gram matrix (excluded samples are few).
void RemoveFromGram(Eigen::MatrixXd* gram, size_t n, double cycles_per_sample, int orders) {
  Eigen::VectorXd phi(2 * orders + 1);
  phi[0] = 1.0;
  const std::complex<double> z1 = PhasorAtCycles(cycles_per_sample * static_cast<double>(n));
  std::complex<double> z = z1;
  for (int h = 1; h <= orders; ++h) {
    phi[CosColumn(h)] = z.real();
    phi[SinColumn(h)] = z.imag();
    z *= z1;
  }
  gram->noalias() -= phi * phi.transpose();
}

void CheckWindow(std::span<const double> signal, SampleWindow window) {
  if (window.begin >= window.end || window.end > signal.size()) {
    std::ostringstream message;
    message << "[" << window.begin << ", " << window.end << ") is not a non-empty range within the "
            << signal.size() << " samples of the signal";
    throw InputError("window", message.str());
  }
}

// One series' frequency and orders. Harmonics at or above Nyquist alias onto each other and make the
// basis degenerate.
void CheckSeries(double sample_rate_hz, double frequency_hz, int orders) {
  RequirePositiveFinite(frequency_hz, "frequency_hz");
  if (orders < 0) throw InputError("orders", "must be >= 0");
  if (orders * frequency_hz >= 0.5 * sample_rate_hz) {
    throw InputError("orders", "harmonic " + std::to_string(orders) + " of " + std::to_string(frequency_hz) +
                                   " Hz is not below the Nyquist frequency " +
                                   std::to_string(0.5 * sample_rate_hz) + " Hz");
  }
}

// The window can hold `unknowns` coefficients, and `excluded` has one entry per window sample.
void CheckSamples(SampleWindow window, size_t unknowns, std::span<const char> excluded) {
  if (window.size() < unknowns) {
    throw InputError("window", "holds " + std::to_string(window.size()) + " samples, fewer than the " +
                                   std::to_string(unknowns) + " coefficients to fit");
  }
  if (!excluded.empty() && excluded.size() != window.size()) {
    throw InputError("excluded", "must have one entry per window sample");
  }
}

// beta = G^-1 b by LDLT; NumericalError where the Gram matrix is singular (the samples kept do not
// determine `what`).
Eigen::VectorXd SolveNormalEquations(const Eigen::MatrixXd& gram, const Eigen::VectorXd& rhs, const std::string& what) {
  if (!rhs.allFinite()) throw InputError("signal", "holds a non-finite sample in the analysed window");
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(gram);
  if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > kMinReciprocalCondition)) {
    throw NumericalError("harmonic fit: the samples kept do not determine " + what + " (Gram matrix singular)");
  }
  Eigen::VectorXd beta = ldlt.solve(rhs);
  if (!beta.allFinite()) throw NumericalError("harmonic fit: non-finite coefficients");
  return beta;
}

// sum_{n=first}^{first+count-1} exp(j 2 pi x n) for any |x| < 1 (the Dirichlet kernel, as PhasorSums).
std::complex<double> PhasorSum(size_t first, size_t count, double x) {
  const double n = static_cast<double>(count);
  const double middle = static_cast<double>(first) + 0.5 * (n - 1.0);
  if (x == 0.0) return n;
  return std::sin(std::numbers::pi * std::fmod(x * n, 2.0)) / std::sin(std::numbers::pi * x) *
         PhasorAtCycles(x * middle);
}

// G = sum_n phi_n phi_n^T for the basis [1, cos(2 pi c_k n), sin(2 pi c_k n)], k over `cycles` (per
// sample, each in (0, 1/2)), over a contiguous window: the product rules give sums at c_k -+ c_l.
Eigen::MatrixXd JointGram(size_t first, size_t count, std::span<const double> cycles) {
  const auto columns = static_cast<Eigen::Index>(2 * cycles.size() + 1);
  Eigen::MatrixXd gram(columns, columns);
  gram(0, 0) = static_cast<double>(count);
  for (size_t k = 0; k < cycles.size(); ++k) {
    const std::complex<double> single = PhasorSum(first, count, cycles[k]);
    gram(0, 2 * k + 1) = gram(2 * k + 1, 0) = single.real();
    gram(0, 2 * k + 2) = gram(2 * k + 2, 0) = single.imag();
    for (size_t l = 0; l < cycles.size(); ++l) {
      const std::complex<double> difference = PhasorSum(first, count, cycles[k] - cycles[l]);
      const std::complex<double> sum = PhasorSum(first, count, cycles[k] + cycles[l]);
      gram(2 * k + 1, 2 * l + 1) = 0.5 * (difference.real() + sum.real());
      gram(2 * k + 2, 2 * l + 2) = 0.5 * (difference.real() - sum.real());
      gram(2 * k + 1, 2 * l + 2) = gram(2 * l + 2, 2 * k + 1) = 0.5 * (sum.imag() - difference.imag());
    }
  }
  return gram;
}

}  // namespace

namespace internal {

HarmonicFit FitHarmonics(std::span<const double> signal, double sample_rate_hz, double frequency_hz,
                         SampleWindow window, int orders, std::span<const char> excluded) {
  RequirePositiveFinite(sample_rate_hz, "sample_rate_hz");
  CheckWindow(signal, window);
  CheckSeries(sample_rate_hz, frequency_hz, orders);
  CheckSamples(window, static_cast<size_t>(2 * orders + 1), excluded);

  const double cycles_per_sample = frequency_hz / sample_rate_hz;
  std::span<const double> values = signal.subspan(window.begin, window.size());
  Eigen::MatrixXd gram = ClosedFormGram(window.begin, window.size(), cycles_per_sample, orders);
  std::vector<double> kept;  // the window with excluded samples zeroed: they drop out of b
  if (!excluded.empty()) {
    kept.assign(values.begin(), values.end());
    for (size_t i = 0; i < kept.size(); ++i) {
      if (excluded[i]) {
        kept[i] = 0.0;
        RemoveFromGram(&gram, window.begin + i, cycles_per_sample, orders);
      }
    }
    values = kept;
  }
  const Eigen::VectorXd rhs = ProjectOntoBasis(values, window.begin, cycles_per_sample, orders);
  const Eigen::VectorXd beta = SolveNormalEquations(gram, rhs, std::to_string(orders) + " harmonics");

  // a cos + b sin = Re((a - j b) exp(j h theta)).
  HarmonicFit fit;
  fit.offset = beta[0];
  fit.amplitudes.reserve(orders);
  for (int h = 1; h <= orders; ++h) fit.amplitudes.emplace_back(beta[CosColumn(h)], -beta[SinColumn(h)]);
  return fit;
}

std::vector<HarmonicFit> FitHarmonicFamilies(std::span<const double> signal, double sample_rate_hz,
                                             std::span<const HarmonicFamily> families, SampleWindow window,
                                             std::span<const char> excluded) {
  // Closer than this many frequency bins two sinusoids part by at most 2 pi 1e-3 rad (0.63 %) over the window.
  constexpr double kCoincidentBins = 1e-3;
  RequirePositiveFinite(sample_rate_hz, "sample_rate_hz");
  CheckWindow(signal, window);
  if (families.empty()) throw InputError("families", "must name at least one harmonic series");
  struct Column {
    size_t family;
    int harmonic;
  };
  std::vector<Column> columns;
  std::vector<double> cycles;  // per sample, one per column
  for (size_t i = 0; i < families.size(); ++i) {
    CheckSeries(sample_rate_hz, families[i].frequency_hz, families[i].orders);
    for (int h = 1; h <= families[i].orders; ++h) {
      const double c = h * families[i].frequency_hz / sample_rate_hz;
      const bool coincident = std::any_of(cycles.begin(), cycles.end(), [&](double other) {
        return std::abs(c - other) * static_cast<double>(window.size()) < kCoincidentBins;
      });
      if (coincident) continue;
      columns.push_back({i, h});
      cycles.push_back(c);
    }
  }
  CheckSamples(window, 2 * columns.size() + 1, excluded);

  std::span<const double> values = signal.subspan(window.begin, window.size());
  Eigen::MatrixXd gram = JointGram(window.begin, window.size(), cycles);
  std::vector<double> kept;  // the window with excluded samples zeroed: they drop out of b
  if (!excluded.empty()) {
    kept.assign(values.begin(), values.end());
    Eigen::VectorXd phi(gram.rows());
    phi[0] = 1.0;
    for (size_t i = 0; i < kept.size(); ++i) {
      if (!excluded[i]) continue;
      kept[i] = 0.0;
      for (size_t k = 0; k < cycles.size(); ++k) {
        const std::complex<double> z = PhasorAtCycles(cycles[k] * static_cast<double>(window.begin + i));
        phi[2 * k + 1] = z.real();
        phi[2 * k + 2] = z.imag();
      }
      gram.noalias() -= phi * phi.transpose();
    }
    values = kept;
  }
  Eigen::VectorXd rhs(gram.rows());
  for (size_t i = 0; i < families.size(); ++i) {
    const Eigen::VectorXd projected =
        ProjectOntoBasis(values, window.begin, families[i].frequency_hz / sample_rate_hz, families[i].orders);
    if (i == 0) rhs[0] = projected[0];
    for (size_t k = 0; k < columns.size(); ++k) {
      if (columns[k].family != i) continue;
      rhs[2 * k + 1] = projected[CosColumn(columns[k].harmonic)];
      rhs[2 * k + 2] = projected[SinColumn(columns[k].harmonic)];
    }
  }
  const Eigen::VectorXd beta = SolveNormalEquations(gram, rhs, std::to_string(columns.size()) + " sinusoids");

  std::vector<HarmonicFit> fits(families.size());
  for (size_t i = 0; i < families.size(); ++i) fits[i].amplitudes.assign(families[i].orders, 0.0);
  fits[0].offset = beta[0];
  for (size_t k = 0; k < columns.size(); ++k)
    fits[columns[k].family].amplitudes[columns[k].harmonic - 1] = {beta[2 * k + 1], -beta[2 * k + 2]};
  return fits;
}

void EvaluateHarmonics(const HarmonicFit& fit, double sample_rate_hz, double frequency_hz, SampleWindow window,
                       std::span<double> out) {
  if (out.size() != window.size()) throw InputError("out", "must have one entry per window sample");
  const int orders = static_cast<int>(fit.amplitudes.size());
  PhasorBlock block(frequency_hz / sample_rate_hz);
  for (size_t i0 = 0; i0 < out.size(); i0 += kBlockSamples) {
    const size_t length = std::min(kBlockSamples, out.size() - i0);
    double* y = out.data() + i0;
    std::fill(y, y + length, fit.offset);
    if (orders == 0) continue;
    block.Start(window.begin + i0, length);
    for (int h = 1; h <= orders; ++h) {
      if (h > 1) block.NextHarmonic();
      // Re(C exp(j h theta)) = Re(C) cos(h theta) - Im(C) sin(h theta).
      const double a = fit.amplitudes[h - 1].real();
      const double b = -fit.amplitudes[h - 1].imag();
      for (size_t k = 0; k < length; ++k) y[k] += a * block.cos()[k] + b * block.sin()[k];
    }
  }
}

}  // namespace internal

SampleWindow LastWholePeriods(size_t sample_count, double sample_rate_hz, double frequency_hz, double span_s) {
  RequirePositiveFinite(sample_rate_hz, "sample_rate_hz");
  RequirePositiveFinite(frequency_hz, "frequency_hz");
  RequirePositiveFinite(span_s, "span_s");
  const double samples_per_period = sample_rate_hz / frequency_hz;
  // The tolerance lets a record of exactly P periods (up to the rounding of fs / f) count as P.
  constexpr double kWholeTolerance = 1e-9;
  const double periods_in_record = std::floor(static_cast<double>(sample_count) / samples_per_period + kWholeTolerance);
  if (periods_in_record < 1.0) {
    std::ostringstream message;
    message << "a record of " << sample_count << " samples at " << sample_rate_hz << " Hz ("
            << static_cast<double>(sample_count) / sample_rate_hz << " s) holds less than one period of "
            << frequency_hz << " Hz";
    throw InputError("frequency_hz", message.str());
  }
  const double periods = std::clamp(std::floor(span_s * frequency_hz + kWholeTolerance), 1.0, periods_in_record);
  const size_t count = std::min(sample_count, static_cast<size_t>(std::llround(periods * samples_per_period)));
  return SampleWindow{sample_count - count, sample_count, periods};
}

std::vector<std::complex<double>> HarmonicAmplitudes(std::span<const double> signal, double sample_rate_hz,
                                                     double frequency_hz, SampleWindow window, int orders) {
  if (orders < 1) throw InputError("orders", "must be >= 1 (got " + std::to_string(orders) + ")");
  return internal::FitHarmonics(signal, sample_rate_hz, frequency_hz, window, orders).amplitudes;
}

std::complex<double> FirstHarmonic(std::span<const double> signal, double sample_rate_hz, double frequency_hz,
                                   SampleWindow window) {
  return HarmonicAmplitudes(signal, sample_rate_hz, frequency_hz, window, 1)[0];
}

std::complex<double> FirstOrderFrf(std::span<const double> output, std::span<const double> drive,
                                   double sample_rate_hz, double frequency_hz, SampleWindow window) {
  const std::complex<double> drive_amplitude = FirstHarmonic(drive, sample_rate_hz, frequency_hz, window);
  if (!(std::abs(drive_amplitude) > 0.0)) {
    throw InputError("drive", "has no component at the drive frequency over the window");
  }
  return FirstHarmonic(output, sample_rate_hz, frequency_hz, window) / drive_amplitude;
}

// Paper Eq. 1: w(n) = 10 pi 1.02^(n-1) rad/s.
std::vector<double> PaperFrequencyGridHz(int count) {
  if (count < 1) throw InputError("count", "must be >= 1 (got " + std::to_string(count) + ")");
  constexpr double kFirstHz = 5.0;    // 10 pi rad/s
  constexpr double kRatio = 1.02;     // dimensionless step
  std::vector<double> grid(count);
  for (int n = 1; n <= count; ++n) grid[n - 1] = kFirstHz * std::pow(kRatio, n - 1);
  return grid;
}

}  // namespace strokelab
