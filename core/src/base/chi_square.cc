#include "strokelab/base/chi_square.h"

#include <cmath>
#include <numbers>

namespace strokelab {

// The Wilson-Hilferty cube-root normal approximation (E. B. Wilson and M. M. Hilferty, "The
// distribution of chi-square", Proc. Natl. Acad. Sci. 17 (1931) 684-688): (x/k)^(1/3) is near-normal
// with mean 1 - 2/(9k), variance 2/(9k). Relative error of a few per cent at p ~ 1e-3 for k >= 10.
double ChiSquareUpperTail(double x, double k) {
  if (!(x > 0)) return 1.0;
  const double v = 2.0 / (9.0 * k);
  const double z = (std::cbrt(x / k) - (1.0 - v)) / std::sqrt(v);
  return NormalUpperTail(z);
}

// By bisection: the tail falls monotonically in x.
double ChiSquareQuantile(double p, double k) {
  if (!(k > 0)) return 0.0;  // chi-square(0) is 0 (and the bracket below would never grow from 0)
  double lo = 0.0, hi = k;
  while (ChiSquareUpperTail(hi, k) > p) hi *= 2.0;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (ChiSquareUpperTail(mid, k) > p ? lo : hi) = mid;
  }
  return hi;
}

double NormalUpperTail(double z) { return 0.5 * std::erfc(z / std::numbers::sqrt2); }

// By bisection: the tail falls monotonically in z (40 standard deviations: a tail of 4e-350, below any p).
double NormalUpperQuantile(double p) {
  double lo = -40.0, hi = 40.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (NormalUpperTail(mid) > p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace strokelab
