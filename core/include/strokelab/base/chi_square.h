// Chi-square and normal tails and quantiles, for the tests on residuals that the fit and the diagnosis
// make, and Akaike's penalty for added parameters.
#pragma once

namespace strokelab {

// Upper tail P(X > x) of chi-square with k degrees of freedom, and its inverse: the x with
// ChiSquareUpperTail(x, k) = p. By the Wilson-Hilferty approximation (chi_square.cc).
double ChiSquareUpperTail(double x, double k);
double ChiSquareQuantile(double p, double k);

// The standard normal's upper tail P(Z > z), and its inverse: the z with NormalUpperTail(z) = p.
double NormalUpperTail(double z);
double NormalUpperQuantile(double p);

// Akaike's information criterion charges a model 2 per fitted parameter: a parameter added to a
// least-squares fit must lower the chi-square by more than that (H. Akaike, "A new look at the
// statistical model identification", IEEE Trans. Autom. Control 19 (1974) 716-723).
inline constexpr double kAkaikePenaltyPerParameter = 2.0;

}  // namespace strokelab
