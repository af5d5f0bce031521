// Chi-square and normal tails and quantiles, for the tests on residuals that the fit and the diagnosis make.
#pragma once

namespace strokelab {

// Upper tail P(X > x) of chi-square with k degrees of freedom, and its inverse: the x with
// ChiSquareUpperTail(x, k) = p. By the Wilson-Hilferty approximation (chi_square.cc).
double ChiSquareUpperTail(double x, double k);
double ChiSquareQuantile(double p, double k);

// The standard normal's upper tail P(Z > z), and its inverse: the z with NormalUpperTail(z) = p.
double NormalUpperTail(double z);
double NormalUpperQuantile(double p);

}  // namespace strokelab
