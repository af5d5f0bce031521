// The leading unknowns' errors of a sparse least-squares problem (identify/sparse_covariance.h)
// against a dense column-pivoted QR of the whole Jacobian, on Jacobians shaped as the broadband fit's:
// a few shared columns, segment columns in blocks, and continuity rows weighted 1e6 times the rest.
#include "strokelab/identify/sparse_covariance.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace strokelab {
namespace {

using RowMajor = Eigen::SparseMatrix<double, Eigen::RowMajor>;

// `rows` sample rows, each on the p shared columns and the two columns of its segment (segments of
// `segment_rows`), then per segment boundary two continuity rows of weight 1e6 on both segments'
// columns. Entries uniform in [-1, 1] (the shared columns scaled by 1e-3, as parameters in other units).
RowMajor SegmentedJacobian(int rows, int segment_rows, int p, unsigned seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int segments = (rows + segment_rows - 1) / segment_rows;
  const int columns = p + 2 * segments;
  std::vector<Eigen::Triplet<double>> entries;
  int row = 0;
  for (int s = 0; s < segments; ++s) {
    for (int i = 0; i < segment_rows && s * segment_rows + i < rows; ++i, ++row) {
      for (int c = 0; c < p; ++c) entries.emplace_back(row, c, 1e-3 * u(random));
      for (int c = 0; c < 2; ++c) entries.emplace_back(row, p + 2 * s + c, u(random));
    }
    if (s + 1 == segments) continue;
    for (int k = 0; k < 2; ++k, ++row) {
      for (int c = 0; c < 2; ++c) entries.emplace_back(row, p + 2 * s + c, 1e6 * u(random));
      entries.emplace_back(row, p + 2 * (s + 1) + k, -1e6);
    }
  }
  RowMajor j(row, columns);
  j.setFromTriplets(entries.begin(), entries.end());
  j.makeCompressed();
  return j;
}

// The same leading block by a dense column-pivoted Householder QR of J D (D scaling columns to unit norm).
Eigen::MatrixXd DenseLeadingCovariance(const RowMajor& sparse, int p) {
  Eigen::MatrixXd j = Eigen::MatrixXd(sparse);
  const Eigen::VectorXd scale = j.colwise().norm().cwiseInverse().transpose();
  j = j * scale.asDiagonal();
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(j);
  const Eigen::Index n = j.cols();
  const Eigen::MatrixXd r = qr.matrixR().topLeftCorner(n, n).triangularView<Eigen::Upper>();
  const Eigen::MatrixXd r_inverse = r.triangularView<Eigen::Upper>().solve(Eigen::MatrixXd::Identity(n, n));
  const Eigen::MatrixXd inverse = qr.colsPermutation() * r_inverse * r_inverse.transpose() * qr.colsPermutation().transpose();
  return scale.head(p).asDiagonal() * inverse.topLeftCorner(p, p) * scale.head(p).asDiagonal();
}

TEST(LeadingErrorsTest, EqualADenseQrOfTheWholeJacobian) {
  // Rows that fill several of the reduction's blocks and end in a part of one, segments that straddle them.
  for (const auto& [rows, segment_rows, seed] : {std::tuple{5000, 700, 1u}, {3000, 1500, 2u}, {200, 50, 3u}}) {
    const int p = 3;
    const RowMajor j = SegmentedJacobian(rows, segment_rows, p, seed);
    const std::optional<internal::ParameterErrors> sparse = internal::LeadingErrors(j, p, 2.0);
    ASSERT_TRUE(sparse.has_value()) << rows;
    const Eigen::MatrixXd dense = DenseLeadingCovariance(j, p);
    // Both are backward stable on J D, whose condition number here is about 1e3: agreement to ~1e-12.
    for (int a = 0; a < p; ++a) {
      EXPECT_TRUE(sparse->identifiable[a]);
      for (int b = 0; b < p; ++b)
        EXPECT_NEAR(sparse->covariance(a, b), 2.0 * dense(a, b), 1e-9 * 2.0 * std::sqrt(dense(a, a) * dense(b, b)))
            << rows << " " << a << b;
    }
  }
}

// Leading columns the rows cannot tell apart, or that no row sees, are not identifiable; the others' errors
// are those of the problem without them.
TEST(LeadingErrorsTest, NameTheLeadingColumnsTheRowsCannotTellApart) {
  const RowMajor j = SegmentedJacobian(3000, 700, 3, 4);
  Eigen::MatrixXd dense = Eigen::MatrixXd(j);
  dense.col(1) = 2.0 * dense.col(0);
  std::optional<internal::ParameterErrors> errors = internal::LeadingErrors(dense.sparseView(), 3, 1.0);
  ASSERT_TRUE(errors.has_value());
  EXPECT_EQ(errors->identifiable, (std::vector<bool>{false, false, true}));
  EXPECT_TRUE(std::isnan(errors->covariance(0, 0)));
  Eigen::MatrixXd without(dense.rows(), dense.cols() - 2);  // column 2 and the others
  without << dense.col(2), dense.rightCols(dense.cols() - 3);
  const Eigen::MatrixXd alone = DenseLeadingCovariance(without.sparseView(), 1);
  EXPECT_NEAR(errors->covariance(2, 2), alone(0, 0), 1e-9 * alone(0, 0));
  dense.col(1).setZero();
  errors = internal::LeadingErrors(dense.sparseView(), 3, 1.0);
  ASSERT_TRUE(errors.has_value());
  EXPECT_EQ(errors->identifiable, (std::vector<bool>{true, false, true}));
}

// Where the other unknowns cannot be told apart there are no errors at all.
TEST(LeadingErrorsTest, AreEmptyWhenTheOtherUnknownsAreNotIdentifiable) {
  const RowMajor j = SegmentedJacobian(3000, 700, 3, 6);
  Eigen::MatrixXd dense = Eigen::MatrixXd(j);
  dense.col(5) = -dense.col(4);
  EXPECT_FALSE(internal::LeadingErrors(dense.sparseView(), 3, 1.0).has_value());
}

TEST(LeadingErrorsTest, RefuseFewerRowsThanColumnsAndBadCounts) {
  const RowMajor j = SegmentedJacobian(3000, 700, 3, 5);
  EXPECT_FALSE(internal::LeadingErrors(j.topRows(4), 3, 1.0).has_value());
  EXPECT_FALSE(internal::LeadingErrors(j, 0, 1.0).has_value());
  EXPECT_FALSE(internal::LeadingErrors(j, static_cast<int>(j.cols()) + 1, 1.0).has_value());
}

}  // namespace
}  // namespace strokelab
