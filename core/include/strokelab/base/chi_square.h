// Chi-square tail and quantile, for the tests on residuals that the fit and the diagnosis make.
#pragma once

namespace strokelab {

// Upper tail P(X > x) of chi-square with k degrees of freedom, and its inverse: the x with
// ChiSquareUpperTail(x, k) = p. By the Wilson-Hilferty approximation (chi_square.cc).
double ChiSquareUpperTail(double x, double k);
double ChiSquareQuantile(double p, double k);

}  // namespace strokelab
