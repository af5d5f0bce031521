// sin and cos of one argument in one call, without libm's rounding-mode save and restore.
//
// The closed-form engine spent a third of a sweep in glibc's sincos (perf, 200 x 200 sweep), a good
// part of it in the rounding-mode guard glibc wraps around every call. Here: Cody-Waite reduction
// by pi/2 in three parts (33 + 33 + 53 bits, so n * part is exact for |n| < 2^20), then the
// minimax kernels of fdlibm (Sun Microsystems, 1993; FreeBSD msun k_sin.c and k_cos.c, error below
// one ulp on [-pi/4, pi/4]). The tail of the reduced argument is dropped, which costs at most about
// one more ulp (tests/core/sincos_test.cc measures the error against libm). Arguments beyond the
// reduction's range, and non-finite ones, go to libm.
#pragma once

#include <cmath>

namespace strokelab {

struct SinCos {
  double sin, cos;
};

namespace sincos_detail {

inline double KernelSin(double x) {  // |x| <= pi/4 (fdlibm __kernel_sin, tail y = 0)
  constexpr double S1 = -1.66666666666666324348e-01, S2 = 8.33333333332248946124e-03,
                   S3 = -1.98412698298579493134e-04, S4 = 2.75573137070700676789e-06,
                   S5 = -2.50507602534068634195e-08, S6 = 1.58969099521155010221e-10;
  const double z = x * x, w = z * z;
  const double r = S2 + z * (S3 + z * S4) + z * w * (S5 + z * S6);
  return x + z * x * (S1 + z * r);
}

inline double KernelCos(double x) {  // |x| <= pi/4 (fdlibm __kernel_cos, tail y = 0)
  constexpr double C1 = 4.16666666666666019037e-02, C2 = -1.38888888888741095749e-03,
                   C3 = 2.48015872894767294178e-05, C4 = -2.75573143513906633035e-07,
                   C5 = 2.08757232129817482790e-09, C6 = -1.13596475577881948265e-11;
  const double z = x * x, w = z * z;
  const double r = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
  const double hz = 0.5 * z, one_minus_hz = 1.0 - hz;
  return one_minus_hz + (((1.0 - one_minus_hz) - hz) + z * r);
}

}  // namespace sincos_detail

inline SinCos SinCosOf(double x) {
  constexpr double kTwoOverPi = 6.36619772367581382433e-01;
  constexpr double kPio2Part1 = 1.57079632673412561417e+00;  // first 33 bits of pi/2
  constexpr double kPio2Part2 = 6.07710050630396597660e-11;  // next 33 bits
  constexpr double kPio2Part3 = 2.02226624879595063154e-21;  // pi/2 - part1 - part2, rounded
  constexpr double kMaxArgument = 1.5e6;                      // |n| < 2^20 below this
  if (!(std::abs(x) < kMaxArgument)) return {std::sin(x), std::cos(x)};
  // Nearest integer to x 2/pi by the 1.5 * 2^52 shift (round-to-nearest, the default mode).
  constexpr double kShift = 6755399441055744.0;
  const double n = (x * kTwoOverPi + kShift) - kShift;
  const double r = ((x - n * kPio2Part1) - n * kPio2Part2) - n * kPio2Part3;
  const double s = sincos_detail::KernelSin(r), c = sincos_detail::KernelCos(r);
  switch (static_cast<long long>(n) & 3) {
    case 0: return {s, c};
    case 1: return {c, -s};
    case 2: return {-s, -c};
    default: return {-c, s};
  }
}

}  // namespace strokelab
