// The paper fit's covariance checked by secants (identify/secant_covariance.h), on chi-squares whose
// shape is known: quadratic as the covariance says, flatter or steeper along one principal direction,
// falling, or not evaluable.
#include "strokelab/identify/secant_covariance.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <optional>
#include <vector>

namespace strokelab {
namespace {

using internal::CheckCovarianceBySecants;
using internal::kMinSecantRatio;

constexpr double kResidualVariance = 1.1;  // s^2
constexpr double kChi2AtMinimum = 460.0;

// A covariance with correlated parameters of different scales: principal variances `variances`
// (largest first) along the columns of a fixed rotation.
struct Principal {
  Eigen::Matrix3d directions;
  Eigen::Vector3d variances{4e-4, 1e-5, 2.5e-7};
  Eigen::Matrix3d Covariance() const { return directions * variances.asDiagonal() * directions.transpose(); }
};
Principal MakePrincipal() {
  Principal p;
  p.directions = (Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()) *
                  Eigen::AngleAxisd(-0.4, Eigen::Vector3d(0, 1, 1).normalized()))
                     .toRotationMatrix();
  return p;
}

const std::vector<double> kTheta = {1.0, 0.9, 1.2};

Eigen::Vector3d Offset(const std::vector<double>& theta) {
  return {theta[0] - kTheta[0], theta[1] - kTheta[1], theta[2] - kTheta[2]};
}

// chi2 = chi2_min + s^2 delta^T C^-1 delta, with the rise along principal direction `scaled` times
// `factor`: the quadratic the covariance describes, except there.
auto Chi2(const Principal& p, int scaled, double factor) {
  Eigen::Vector3d curvatures = p.variances.cwiseInverse();
  curvatures(scaled) *= factor;
  const Eigen::Matrix3d form = kResidualVariance * p.directions * curvatures.asDiagonal() * p.directions.transpose();
  return [form](const std::vector<double>& theta) -> std::optional<double> {
    const Eigen::Vector3d delta = Offset(theta);
    return kChi2AtMinimum + delta.dot(form * delta);
  };
}

void ExpectMatrixNear(const Eigen::MatrixXd& actual, const Eigen::MatrixXd& expected) {
  EXPECT_LT((actual - expected).norm(), 1e-10 * expected.norm()) << "actual\n" << actual << "\nexpected\n" << expected;
}

TEST(SecantCovariance, AQuadraticAsTheCovarianceSaysKeepsIt) {
  const Principal p = MakePrincipal();
  const auto checked = CheckCovarianceBySecants(p.Covariance(), kResidualVariance, kTheta, Chi2(p, 0, 1.0));
  ExpectMatrixNear(checked.covariance, p.Covariance());
  ASSERT_EQ(checked.ratios.size(), 3u);
  for (double r : checked.ratios) EXPECT_NEAR(r, 1.0, 1e-9);
}

// Flatter by 4 along the middle direction: its variance grows 4 times, the others' not.
TEST(SecantCovariance, AFlatterDirectionGrowsByTheRatio) {
  const Principal p = MakePrincipal();
  const auto checked = CheckCovarianceBySecants(p.Covariance(), kResidualVariance, kTheta, Chi2(p, 1, 0.25));
  Principal expected = p;
  expected.variances(1) *= 4.0;
  ExpectMatrixNear(checked.covariance, expected.Covariance());
  ASSERT_EQ(checked.ratios.size(), 3u);
  EXPECT_NEAR(checked.ratios[0], 1.0, 1e-9);
  EXPECT_NEAR(checked.ratios[1], 0.25, 1e-9);
  EXPECT_NEAR(checked.ratios[2], 1.0, 1e-9);
}

// As the covariance says within one standard deviation of the largest direction, 4 times flatter
// beyond (a rise of s^2 (1 + (u^2 - 1) / 4) at u standard deviations): the probes move out until
// the rise at 2 of the grown standard deviations is near 4 s^2, which is at a variance 3.25 times the
// Jacobian's, and stop within kSecantTolerance of it.
TEST(SecantCovariance, AChiSquareThatFlattensFarOutGrowsToItsInterval) {
  const Principal p = MakePrincipal();
  const Eigen::Vector3d largest = p.directions.col(0);
  const auto quadratic = Chi2(p, 0, 1.0);
  const auto chi2 = [&](const std::vector<double>& theta) -> std::optional<double> {
    const double u2 = std::pow(Offset(theta).dot(largest), 2) / p.variances(0);
    const double excess = u2 > 1.0 ? kResidualVariance * 0.75 * (u2 - 1.0) : 0.0;
    return *quadratic(theta) - excess;
  };
  const auto checked = CheckCovarianceBySecants(p.Covariance(), kResidualVariance, kTheta, chi2);
  EXPECT_GT(checked.ratios[0], 1.0 / 3.25);
  EXPECT_LT(checked.ratios[0], 1.0 / (internal::kSecantTolerance * 3.25));
  EXPECT_NEAR(checked.ratios[1], 1.0, 1e-9);
  EXPECT_NEAR(checked.ratios[2], 1.0, 1e-9);
}

// Steeper than the covariance says: the Jacobian's variances are kept (never made smaller).
TEST(SecantCovariance, ASteeperDirectionKeepsItsVariance) {
  const Principal p = MakePrincipal();
  const auto checked = CheckCovarianceBySecants(p.Covariance(), kResidualVariance, kTheta, Chi2(p, 2, 9.0));
  ExpectMatrixNear(checked.covariance, p.Covariance());
}

// A chi-square that falls along the largest direction (the estimate is no minimum there): that
// direction's variance grows by the largest factor allowed.
TEST(SecantCovariance, AFallingDirectionGrowsByTheLargestFactor) {
  const Principal p = MakePrincipal();
  const auto checked = CheckCovarianceBySecants(p.Covariance(), kResidualVariance, kTheta, Chi2(p, 0, -1.0));
  Principal expected = p;
  expected.variances(0) /= kMinSecantRatio;
  ExpectMatrixNear(checked.covariance, expected.Covariance());
  EXPECT_EQ(checked.ratios[0], kMinSecantRatio);
}

// No steady state at a probe: that direction is left as the Jacobian says.
TEST(SecantCovariance, AProbeWithoutAChiSquareLeavesItsDirection) {
  const Principal p = MakePrincipal();
  const auto flatter = Chi2(p, 0, 0.25);
  const Eigen::Vector3d largest = p.directions.col(0);
  const auto chi2 = [&](const std::vector<double>& theta) -> std::optional<double> {
    const Eigen::Vector3d delta = Offset(theta);
    if (std::abs(delta.dot(largest)) > 1e-3) return std::nullopt;  // the largest direction's probes only
    return flatter(theta);
  };
  const auto checked = CheckCovarianceBySecants(p.Covariance(), kResidualVariance, kTheta, chi2);
  ExpectMatrixNear(checked.covariance, p.Covariance());
  EXPECT_EQ(checked.ratios[0], 1.0);
}

}  // namespace
}  // namespace strokelab
