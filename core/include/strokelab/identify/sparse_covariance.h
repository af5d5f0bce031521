// The covariance of a few leading unknowns of a large, sparse least-squares problem (the broadband
// fit's model parameters among its segments' start states and records' offsets and hum).
#pragma once

#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <optional>

namespace strokelab::internal {

// (J^T J)^-1 restricted to J's first p columns (the other unknowns eliminated), by a sparse QR of J with
// its columns scaled to unit norm, J D P = Q R: (J^T J)^-1 = D P R^-1 R^-T P^T D, applied to the p unit
// vectors. Not the normal equations, which square J's condition number (the broadband fit's continuity
// rows weigh 1e6 times its samples'). Empty when J is rank deficient, by the rank a QR of J takes:
// Eigen's default pivot threshold, 20 (m + n) eps times the largest column norm (1 after scaling), for J
// of m rows and n columns. The QR is of far fewer rows than J's (each block of consecutive rows replaced
// by the R of its dense QR over the columns it uses), exact up to rounding.
std::optional<Eigen::MatrixXd> LeadingCovariance(const Eigen::Ref<const Eigen::SparseMatrix<double, Eigen::RowMajor>>& j,
                                                 int p);

}  // namespace strokelab::internal
