// The covariance's principal directions probed by secants (secant_covariance.h).
#include "strokelab/identify/secant_covariance.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace strokelab::internal {

SecantCovariance CheckCovarianceBySecants(
    const Eigen::MatrixXd& covariance, double residual_variance, const std::vector<double>& theta,
    const std::function<std::optional<double>(const std::vector<double>&)>& chi2_at) {
  SecantCovariance result{covariance, {}};
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(covariance);
  const std::optional<double> centre = chi2_at(theta);
  if (eigen.info() != Eigen::Success || !centre) return result;
  Eigen::VectorXd variances = eigen.eigenvalues();
  // A quadratic chi-square with (J^T J) = s^2 C^-1 rises by k^2 s^2 at k standard deviations along
  // any principal direction of C.
  const double expected_rise = kSecantSteps * kSecantSteps * residual_variance;
  // The chi-square's rise over the expected at +-kSecantSteps standard deviations of variance v along
  // direction i (nullopt: a probe has no chi-square).
  auto rise_ratio = [&](Eigen::Index i, double v) -> std::optional<double> {
    const Eigen::VectorXd step = kSecantSteps * std::sqrt(v) * eigen.eigenvectors().col(i);
    std::vector<double> up = theta, down = theta;
    for (size_t j = 0; j < theta.size(); ++j) up[j] += step(j), down[j] -= step(j);
    const std::optional<double> chi2_up = chi2_at(up), chi2_down = chi2_at(down);
    if (!chi2_up || !chi2_down) return std::nullopt;
    return (0.5 * (*chi2_up + *chi2_down) - *centre) / expected_rise;
  };
  for (Eigen::Index i = variances.size() - 1; i >= 0; --i) {
    const double jacobians = variances(i);
    if (!(jacobians > 0.0)) {
      result.ratios.push_back(1.0);
      continue;
    }
    // Where the rise falls short, the variance grows by the ratio and the probes move out with it,
    // until they find the expected rise: the likelihood-ratio interval along this direction.
    double v = jacobians;
    for (int probe = 0; probe < kMaxSecantProbes; ++probe) {
      const std::optional<double> ratio = rise_ratio(i, v);
      if (!ratio || *ratio >= kSecantTolerance) break;
      v = std::min(v / std::max(*ratio, kMinSecantRatio), jacobians / kMinSecantRatio);
      if (v == jacobians / kMinSecantRatio) break;
    }
    variances(i) = v;
    result.ratios.push_back(jacobians / v);
  }
  result.covariance = eigen.eigenvectors() * variances.asDiagonal() * eigen.eigenvectors().transpose();
  return result;
}

}  // namespace strokelab::internal
