// Signal analysis against closed forms: harmonics of synthetic signals, the least-squares fit against
// a dense QR solve, Hann spectra of bin-centred sinusoids, the steady-state window and paper Eq. 1.
#include "strokelab/signal/signal.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <cmath>
#include <complex>
#include <numbers>
#include <random>
#include <vector>

#include "strokelab/base/errors.h"
#include "strokelab/signal/harmonic_fit.h"
#include "test_util.h"

namespace strokelab {
namespace {

using ::testing::HasSubstr;
using Complex = std::complex<double>;

using ::strokelab::testing::kPi;
using ::strokelab::testing::kFs;
// Exact-arithmetic results computed in double: rounding only, a few hundred ulps at most.
constexpr double kRoundingRel = 1e-10;

// c0 + sum_h Re(C_h exp(j h w t)), t = n / fs.
std::vector<double> HarmonicSignal(size_t count, double fs, double f, double offset,
                                   const std::vector<Complex>& amplitudes) {
  std::vector<double> x(count, offset);
  for (size_t n = 0; n < count; ++n) {
    const double t = static_cast<double>(n) / fs;
    for (size_t h = 1; h <= amplitudes.size(); ++h) {
      x[n] += std::real(amplitudes[h - 1] * std::polar(1.0, 2.0 * kPi * f * static_cast<double>(h) * t));
    }
  }
  return x;
}

std::string InputErrorField(auto&& call) {
  try {
    call();
  } catch (const InputError& e) {
    return e.field();
  }
  return "<no InputError>";
}

// ---- LastWholePeriods ---------------------------------------------------------------------------

TEST(LastWholePeriodsTest, IntegerSamplesPerPeriod) {
  // 10 s at 8 Hz: the last second is 8 periods of exactly 6400 samples.
  const SampleWindow w = LastWholePeriods(512000, kFs, 8.0, 1.0);
  EXPECT_EQ(w.periods, 8.0);
  EXPECT_EQ(w.end, 512000u);
  EXPECT_EQ(w.size(), 51200u);
}

TEST(LastWholePeriodsTest, NonIntegerSamplesPerPeriodRoundsTheCount) {
  const double f = 5.0 * std::pow(1.02, 10);  // 6.0950 Hz: 8400.3 samples per period
  const SampleWindow w = LastWholePeriods(512000, kFs, f, 1.0);
  EXPECT_EQ(w.periods, 6.0);
  EXPECT_EQ(w.end, 512000u);
  EXPECT_EQ(w.size(), static_cast<size_t>(std::llround(6.0 * kFs / f)));
}

TEST(LastWholePeriodsTest, AtLeastOnePeriodAndAtMostTheRecord) {
  // A span shorter than a period still gives one period.
  EXPECT_EQ(LastWholePeriods(512000, kFs, 8.0, 0.01).periods, 1.0);
  // A span longer than the record gives the whole periods the record holds: 1.5 s at 8 Hz -> 12.
  const SampleWindow w = LastWholePeriods(76800, kFs, 8.0, 100.0);
  EXPECT_EQ(w.periods, 12.0);
  EXPECT_EQ(w.begin, 0u);
}

TEST(LastWholePeriodsTest, RecordShorterThanOnePeriodNamesFrequency) {
  try {
    LastWholePeriods(6399, kFs, 8.0);  // one 8 Hz period needs 6400 samples
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "frequency_hz");
    EXPECT_THAT(e.what(), HasSubstr("less than one period of 8 Hz"));
  }
  EXPECT_EQ(LastWholePeriods(6400, kFs, 8.0).periods, 1.0);
  EXPECT_EQ(InputErrorField([] { LastWholePeriods(100, 0.0, 8.0); }), "sample_rate_hz");
  EXPECT_EQ(InputErrorField([] { LastWholePeriods(100, kFs, std::nan("")); }), "frequency_hz");
  EXPECT_EQ(InputErrorField([] { LastWholePeriods(100000, kFs, 8.0, -1.0); }), "span_s");
}

// ---- HarmonicAmplitudes -------------------------------------------------------------------------

const std::vector<Complex> kKnownHarmonics = {{0.3, -0.2}, {-0.05, 0.04}, {0.0, 0.01}, {0.002, 0.0}, {-1e-3, -2e-3}};

TEST(HarmonicAmplitudesTest, RecoversKnownHarmonicsOnANonIntegerPeriodWindow) {
  const double f = 7.3;  // 7013.7 samples per period
  const std::vector<double> x = HarmonicSignal(3 * 51200, kFs, f, 0.125, kKnownHarmonics);
  const SampleWindow window = LastWholePeriods(x.size(), kFs, f, 1.0);
  ASSERT_GT(window.begin, 0u);
  const std::vector<Complex> c = HarmonicAmplitudes(x, kFs, f, window, 5);
  ASSERT_EQ(c.size(), 5u);
  for (size_t h = 0; h < 5; ++h) EXPECT_REL_NEAR(c[h], kKnownHarmonics[h], kRoundingRel) << "h = " << h + 1;
}

TEST(HarmonicAmplitudesTest, ExactOnAnyWindowNotOnlyWholePeriods) {
  const double f = 7.3;
  const std::vector<double> x = HarmonicSignal(30000, kFs, f, -0.4, kKnownHarmonics);
  // 1.7 periods starting at an arbitrary sample.
  const SampleWindow window{1234, 1234 + 11923, 0.0};
  const std::vector<Complex> c = HarmonicAmplitudes(x, kFs, f, window, 5);
  for (size_t h = 0; h < 5; ++h) EXPECT_REL_NEAR(c[h], kKnownHarmonics[h], kRoundingRel) << "h = " << h + 1;
}

TEST(HarmonicAmplitudesTest, HigherOrdersThanPresentReadZero) {
  const double f = 7.3;
  const std::vector<double> x = HarmonicSignal(3 * 51200, kFs, f, 0.125, kKnownHarmonics);
  const SampleWindow window = LastWholePeriods(x.size(), kFs, f, 1.0);
  const std::vector<Complex> c = HarmonicAmplitudes(x, kFs, f, window, 40);
  ASSERT_EQ(c.size(), 40u);
  for (size_t h = 0; h < 5; ++h) EXPECT_REL_NEAR(c[h], kKnownHarmonics[h], kRoundingRel) << "h = " << h + 1;
  for (size_t h = 5; h < 40; ++h) EXPECT_LT(std::abs(c[h]), 1e-12) << "h = " << h + 1;
}

TEST(HarmonicAmplitudesTest, PhaseStaysAccurateHundredsOfSecondsIn) {
  // 300 s at 1 kHz; the window is the last second, t in [299, 300) s: phases still refer to t = 0.
  const double fs = 1000.0;
  const double f = 5.0 * std::pow(1.02, 100);  // 36.22 Hz, about 10865 cycles before the window
  const std::vector<double> x = HarmonicSignal(300000, fs, f, 0.0, {{0.7, 0.7}, {0.0, -0.1}});
  const SampleWindow window = LastWholePeriods(x.size(), fs, f, 1.0);
  const std::vector<Complex> c = HarmonicAmplitudes(x, fs, f, window, 2);
  // The synthetic signal itself carries the rounding of w t at t = 300 s: about 1e5 rad * 1e-16.
  EXPECT_REL_NEAR(c[0], Complex(0.7, 0.7), kRoundingRel);
  EXPECT_REL_NEAR(c[1], Complex(0.0, -0.1), kRoundingRel);
}

TEST(HarmonicAmplitudesTest, MatchesDenseQrLeastSquaresOnNoise) {
  // A signal outside the span of the basis: the fit must be the least-squares solution itself.
  std::mt19937 rng(42);
  std::normal_distribution<double> noise(0.0, 1.0);
  const double f = 11.7;
  std::vector<double> x(20000);
  for (double& v : x) v = noise(rng);
  const SampleWindow window{2500, 20000, 0.0};
  const int orders = 4;
  Eigen::MatrixXd a(window.size(), 2 * orders + 1);
  Eigen::VectorXd b(window.size());
  for (size_t i = 0; i < window.size(); ++i) {
    const double theta = 2.0 * kPi * f * static_cast<double>(window.begin + i) / kFs;
    a(i, 0) = 1.0;
    for (int h = 1; h <= orders; ++h) {
      a(i, 2 * h - 1) = std::cos(h * theta);
      a(i, 2 * h) = std::sin(h * theta);
    }
    b[i] = x[window.begin + i];
  }
  const Eigen::VectorXd beta = a.householderQr().solve(b);
  const std::vector<Complex> c = HarmonicAmplitudes(x, kFs, f, window, orders);
  for (int h = 1; h <= orders; ++h) {
    EXPECT_REL_NEAR(c[h - 1], Complex(beta[2 * h - 1], -beta[2 * h]), kRoundingRel) << "h = " << h;
  }
}

TEST(HarmonicAmplitudesTest, FirstHarmonicFitsTheFundamentalAlone) {
  const double f = 9.91;  // 5166.5 samples per period
  const SampleWindow window = LastWholePeriods(100000, kFs, f, 1.0);
  // Offset and fundamental only: exact.
  const std::vector<double> pure = HarmonicSignal(100000, kFs, f, 0.3, {kKnownHarmonics[0]});
  EXPECT_REL_NEAR(FirstHarmonic(pure, kFs, f, window), kKnownHarmonics[0], kRoundingRel);
  // With higher harmonics present, a fit of C_1 alone is exact only on an exact whole number of
  // periods; the window's sample count is rounded (9 periods = 46498.5 samples), so the unmodelled
  // harmonics leak in at the 1e-5 level. Fitting them too removes the leak.
  const std::vector<double> rich = HarmonicSignal(100000, kFs, f, 0.3, kKnownHarmonics);
  EXPECT_REL_NEAR(FirstHarmonic(rich, kFs, f, window), kKnownHarmonics[0], 1e-4);
  EXPECT_REL_NEAR(HarmonicAmplitudes(rich, kFs, f, window, 5)[0], kKnownHarmonics[0], kRoundingRel);
}

TEST(HarmonicAmplitudesTest, FirstOrderFrfOfTwoChannels) {
  // v_in = V sin(w t), i.e. C_1 = -j V; the output is H v_in with a known H and a third harmonic.
  const double f = 13.0, volts = 0.4;
  const Complex h_true = std::polar(0.29, -2.1);
  const Complex c_drive(0.0, -volts);
  const std::vector<double> drive = HarmonicSignal(102400, kFs, f, 0.0, {c_drive});
  const std::vector<double> output = HarmonicSignal(102400, kFs, f, 0.02, {h_true * c_drive, 0.0, {0.01, 0.003}});
  const SampleWindow window = LastWholePeriods(drive.size(), kFs, f, 1.0);
  EXPECT_REL_NEAR(FirstOrderFrf(output, drive, kFs, f, window), h_true, kRoundingRel);
}

TEST(HarmonicAmplitudesTest, RejectsBadArgumentsNamingTheField) {
  const std::vector<double> x(1000, 1.0);
  const SampleWindow all{0, 1000, 0.0};
  EXPECT_EQ(InputErrorField([&] { HarmonicAmplitudes(x, kFs, 100.0, all, 0); }), "orders");
  EXPECT_EQ(InputErrorField([&] { HarmonicAmplitudes(x, kFs, 100.0, all, 300); }), "orders");  // above Nyquist
  EXPECT_EQ(InputErrorField([&] { HarmonicAmplitudes(x, kFs, 100.0, SampleWindow{10, 1001, 0.0}, 1); }), "window");
  EXPECT_EQ(InputErrorField([&] { HarmonicAmplitudes(x, kFs, 100.0, SampleWindow{10, 10, 0.0}, 1); }), "window");
  EXPECT_EQ(InputErrorField([&] { HarmonicAmplitudes(x, kFs, 0.0, all, 1); }), "frequency_hz");
  std::vector<double> with_nan = x;
  with_nan[500] = std::nan("");
  EXPECT_EQ(InputErrorField([&] { HarmonicAmplitudes(with_nan, kFs, 100.0, all, 1); }), "signal");
  const std::vector<double> silent(1000, 0.0);
  EXPECT_EQ(InputErrorField([&] { FirstOrderFrf(x, silent, kFs, 100.0, all); }), "drive");
}

// ---- FitHarmonicFamilies ------------------------------------------------------------------------

// Drive harmonics of 7 Hz and a 50 Hz hum with two overtones over 0.43 s (three drive periods): the
// hum lies 0.43 frequency bins from harmonic 7, so the series are far from orthogonal. On noise, with
// samples left out, the joint fit is the least-squares solution of a dense QR solve on the same basis.
TEST(FitHarmonicFamiliesTest, MatchesDenseQrLeastSquaresBesideNearlyEqualFrequencies) {
  std::mt19937 rng(43);
  std::normal_distribution<double> noise(0.0, 1.0);
  const std::vector<internal::HarmonicFamily> families{{7.0, 10}, {50.0, 3}};
  std::vector<double> x(30000);
  for (double& v : x) v = noise(rng);
  const SampleWindow window{8055, 8055 + 3 * 7314, 3.0};  // 3 periods of 7 Hz at 51.2 kHz
  std::vector<char> excluded(window.size(), 0);
  for (size_t i = 4000; i < 4100; ++i) excluded[i] = 1;
  int columns = 1;
  for (const auto& family : families) columns += 2 * family.orders;
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(window.size(), columns);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(window.size());
  for (size_t i = 0; i < window.size(); ++i) {
    if (excluded[i]) continue;  // a zero row leaves the least-squares solution as it is without it
    a(i, 0) = 1.0;
    int column = 1;
    for (const auto& family : families) {
      const double theta = 2.0 * kPi * family.frequency_hz * static_cast<double>(window.begin + i) / kFs;
      for (int h = 1; h <= family.orders; ++h, column += 2) {
        a(i, column) = std::cos(h * theta);
        a(i, column + 1) = std::sin(h * theta);
      }
    }
    b[i] = x[window.begin + i];
  }
  const Eigen::VectorXd beta = a.householderQr().solve(b);
  const std::vector<internal::HarmonicFit> fits = internal::FitHarmonicFamilies(x, kFs, families, window, excluded);
  ASSERT_EQ(fits.size(), 2u);
  EXPECT_NEAR(fits[0].offset, beta[0], 1e-10 * std::abs(beta[0]) + 1e-14);
  EXPECT_EQ(fits[1].offset, 0.0);
  int column = 1;
  for (size_t i = 0; i < families.size(); ++i) {
    ASSERT_EQ(fits[i].amplitudes.size(), static_cast<size_t>(families[i].orders));
    for (int h = 1; h <= families[i].orders; ++h, column += 2) {
      EXPECT_REL_NEAR(fits[i].amplitudes[h - 1], Complex(beta[column], -beta[column + 1]), 1e-8)
          << "family " << i << ", h = " << h;
    }
  }
}

// Noise-free drive harmonics and hum 0.43 bins apart are recovered exactly. A hum overtone on a drive
// harmonic (50 Hz on harmonic 5 of 10 Hz) is the same sinusoid: the drive's harmonic holds both and the
// sum is exact.
TEST(FitHarmonicFamiliesTest, RecoversSeriesExactlyAndLetsACoincidentHarmonicHoldBoth) {
  const SampleWindow window{0, 3 * 7314, 3.0};
  const std::vector<double> drive = HarmonicSignal(window.end, kFs, 7.0, 0.2, kKnownHarmonics);
  const std::vector<Complex> hum_truth{{1e-3, 2e-3}, {0.0, 0.0}, {-4e-4, 1e-4}};
  const std::vector<double> hum = HarmonicSignal(window.end, kFs, 50.0, 0.0, hum_truth);
  std::vector<double> x(window.end);
  for (size_t n = 0; n < x.size(); ++n) x[n] = drive[n] + hum[n];
  const std::vector<internal::HarmonicFamily> families{{7.0, static_cast<int>(kKnownHarmonics.size())}, {50.0, 3}};
  const std::vector<internal::HarmonicFit> fits = internal::FitHarmonicFamilies(x, kFs, families, window);
  EXPECT_NEAR(fits[0].offset, 0.2, 1e-12);
  for (size_t h = 0; h < kKnownHarmonics.size(); ++h)
    EXPECT_NEAR(std::abs(fits[0].amplitudes[h] - kKnownHarmonics[h]), 0.0, 1e-11) << "drive h = " << h + 1;
  for (size_t h = 0; h < hum_truth.size(); ++h)
    EXPECT_NEAR(std::abs(fits[1].amplitudes[h] - hum_truth[h]), 0.0, 1e-11) << "hum h = " << h + 1;

  const std::vector<double> on_h5 = HarmonicSignal(window.end, kFs, 10.0, 0.0, {0.1, 0.0, 0.0, 0.0, {0.01, 0.0}});
  const std::vector<double> hum_on_h5 = HarmonicSignal(window.end, kFs, 50.0, 0.0, {{0.0, 0.02}});
  for (size_t n = 0; n < x.size(); ++n) x[n] = on_h5[n] + hum_on_h5[n];
  const std::vector<internal::HarmonicFamily> coincident{{10.0, 6}, {50.0, 1}};
  const std::vector<internal::HarmonicFit> both = internal::FitHarmonicFamilies(x, kFs, coincident, window);
  EXPECT_EQ(both[1].amplitudes[0], Complex(0.0, 0.0));
  EXPECT_NEAR(std::abs(both[0].amplitudes[4] - Complex(0.01, 0.02)), 0.0, 1e-12);
  EXPECT_NEAR(std::abs(both[0].amplitudes[0] - Complex(0.1, 0.0)), 0.0, 1e-12);
}

TEST(FitHarmonicFamiliesTest, RejectsBadArgumentsNamingTheField) {
  const std::vector<double> x(1000, 1.0);
  const SampleWindow all{0, 1000, 0.0};
  EXPECT_EQ(InputErrorField([&] { internal::FitHarmonicFamilies(x, kFs, {}, all); }), "families");
  const std::vector<internal::HarmonicFamily> above_nyquist{{100.0, 2}, {50.0, 600}};
  EXPECT_EQ(InputErrorField([&] { internal::FitHarmonicFamilies(x, kFs, above_nyquist, all); }), "orders");
  const std::vector<internal::HarmonicFamily> no_frequency{{100.0, 2}, {0.0, 1}};
  EXPECT_EQ(InputErrorField([&] { internal::FitHarmonicFamilies(x, kFs, no_frequency, all); }), "frequency_hz");
  const std::vector<internal::HarmonicFamily> two{{100.0, 2}, {50.0, 1}};
  EXPECT_EQ(InputErrorField([&] { internal::FitHarmonicFamilies(x, kFs, two, SampleWindow{0, 6, 0.0}); }), "window");
  EXPECT_EQ(InputErrorField([&] { internal::FitHarmonicFamilies(x, kFs, two, all, std::vector<char>(3, 0)); }),
            "excluded");
}

// ---- HannSpectrum --------------------------------------------------------------------------------

// The Hann kernel reaches one bin either side, so a bin-centred sinusoid reads exactly, up to the
// FFT's rounding (about log2(N) ulps).
constexpr double kSpectrumRel = 1e-12;

TEST(HannSpectrumTest, BinCentredSinusoidReadsItsAmplitude) {
  for (const size_t count : {4096u, 1000u, 1001u}) {  // power of two, even, odd
    const double fs = 1024.0;
    const size_t bin = 100;
    const double f = static_cast<double>(bin) * fs / static_cast<double>(count);
    std::vector<double> x(count);
    for (size_t n = 0; n < count; ++n) x[n] = 0.25 + 1.7 * std::sin(2.0 * kPi * f * static_cast<double>(n) / fs + 0.4);
    const Spectrum s = HannSpectrum(x, fs);
    ASSERT_EQ(s.amplitude.size(), count / 2 + 1) << count;
    EXPECT_REL_NEAR(s.frequency_hz[bin], f, 1e-15);
    EXPECT_REL_NEAR(s.amplitude[bin], 1.7, kSpectrumRel) << count;
    EXPECT_REL_NEAR(s.amplitude[0], 0.25, kSpectrumRel) << count;  // DC, no mirror image
    // Leakage: the Hann kernel puts a quarter into each neighbour and nothing further.
    EXPECT_REL_NEAR(s.amplitude[bin + 1], 1.7 / 2.0, kSpectrumRel);
    EXPECT_LT(s.amplitude[bin + 3], 1e-12);
  }
}

TEST(HannSpectrumTest, RejectsTooShortOrNonFiniteSignals) {
  EXPECT_EQ(InputErrorField([] { HannSpectrum(std::vector<double>{1.0}, 100.0); }), "signal");
  EXPECT_EQ(InputErrorField([] { HannSpectrum(std::vector<double>{1.0, INFINITY}, 100.0); }), "signal");
  EXPECT_EQ(InputErrorField([] { HannSpectrum(std::vector<double>{1.0, 2.0}, -1.0); }), "sample_rate_hz");
}

// ---- Paper Eq. 1 ---------------------------------------------------------------------------------

TEST(PaperFrequencyGridTest, Eq1FirstAndLastValues) {
  const std::vector<double> grid = PaperFrequencyGridHz();
  ASSERT_EQ(grid.size(), 117u);
  EXPECT_EQ(grid.front(), 5.0);                        // 10 pi rad/s
  EXPECT_REL_NEAR(grid[1], 5.1, 1e-15);
  EXPECT_REL_NEAR(grid.back(), 5.0 * std::pow(1.02, 116), 1e-15);
  EXPECT_NEAR(grid.back(), 49.73, 0.005);               // "up to ~50 Hz"
  for (size_t n = 1; n < grid.size(); ++n) EXPECT_REL_NEAR(grid[n] / grid[n - 1], 1.02, 1e-14);
  EXPECT_EQ(InputErrorField([] { PaperFrequencyGridHz(0); }), "count");
}

}  // namespace
}  // namespace strokelab
