// SinCosOf (sincos.h) against libm: the error in ulps of the result, over the arguments the engines
// use (drive phases up to thousands of radians, propagator angles near zero) and at the quadrant
// boundaries where the reduction cancels.
#include "strokelab/base/sincos.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>

namespace strokelab {
namespace {

// |a - b| in units of the spacing of doubles at b (at least the smallest normal's spacing scale of 1).
double UlpError(double a, double b) {
  const double spacing = std::nextafter(std::abs(b), INFINITY) - std::abs(b);
  return std::abs(a - b) / std::max(spacing, std::numeric_limits<double>::denorm_min());
}

struct WorstError {
  double ulps = 0, at = 0;
  void Add(double error, double x) {
    if (error > ulps) ulps = error, at = x;
  }
};

void ExpectWithinUlps(double x, WorstError* sin_error, WorstError* cos_error) {
  const SinCos sc = SinCosOf(x);
  sin_error->Add(UlpError(sc.sin, std::sin(x)), x);
  cos_error->Add(UlpError(sc.cos, std::cos(x)), x);
}

TEST(SinCos, WithinTwoUlpsOfLibmOverTheEnginesRange) {
  std::mt19937_64 random(7);
  WorstError sin_error, cos_error;
  for (double range : {1.0, 10.0, 1e3, 1e5, 1.4e6}) {
    std::uniform_real_distribution<double> uniform(-range, range);
    for (int i = 0; i < 200000; ++i) ExpectWithinUlps(uniform(random), &sin_error, &cos_error);
  }
  // Next to multiples of pi/2 the reduced argument is small and the result is where cancellation
  // in the reduction would show.
  for (int k = -2000; k <= 2000; ++k)
    for (double offset : {-1e-3, -1e-7, -1e-12, 0.0, 1e-12, 1e-7, 1e-3})
      ExpectWithinUlps(k * std::numbers::pi / 2 + offset, &sin_error, &cos_error);
  std::printf("worst error: sin %.2f ulp at %.17g, cos %.2f ulp at %.17g\n", sin_error.ulps, sin_error.at,
              cos_error.ulps, cos_error.at);
  EXPECT_LE(sin_error.ulps, 2.0) << "at x = " << sin_error.at;
  EXPECT_LE(cos_error.ulps, 2.0) << "at x = " << cos_error.at;
}

TEST(SinCos, ExactAtZeroAndLibmBeyondTheReduction) {
  EXPECT_EQ(SinCosOf(0.0).sin, 0.0);
  EXPECT_EQ(SinCosOf(0.0).cos, 1.0);
  EXPECT_EQ(SinCosOf(1e-300).sin, 1e-300);
  for (double x : {2e6, -3e9, 1e300}) {
    EXPECT_EQ(SinCosOf(x).sin, std::sin(x)) << x;
    EXPECT_EQ(SinCosOf(x).cos, std::cos(x)) << x;
  }
  EXPECT_TRUE(std::isnan(SinCosOf(INFINITY).sin));
  EXPECT_TRUE(std::isnan(SinCosOf(std::nan("")).cos));
}

}  // namespace
}  // namespace strokelab
