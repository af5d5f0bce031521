// The covariance of a sparse least-squares problem's leading unknowns (identify/sparse_covariance.h).
#include "strokelab/identify/sparse_covariance.h"

#include <Eigen/SparseQR>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace strokelab::internal {
namespace {

using Rows = Eigen::Ref<const Eigen::SparseMatrix<double, Eigen::RowMajor>>;

// J's rows are reduced in blocks of this many.
constexpr Eigen::Index kBlockRows = 1024;

// A matrix with the R factor of J D and its column norms, of far fewer rows: each block of kBlockRows
// consecutive rows replaced by the R of its dense Householder QR over the columns it uses. With Q_b
// orthogonal, J D = diag(Q_b) [R_b], so a QR of [R_b] is one of J D (Golub and Van Loan, "Matrix
// Computations", 4th ed., 2013, Sec. 5.2: QR by row blocks). A block of the broadband fit's samples uses
// only the model's parameters, one or two segments' starts and one record's offset and hum.
Eigen::SparseMatrix<double> ReducedRows(const Rows& j, const Eigen::VectorXd& column_scale) {
  std::vector<Eigen::Triplet<double>> entries;
  Eigen::Index reduced_rows = 0;
  for (Eigen::Index first = 0; first < j.rows(); first += kBlockRows) {
    const Eigen::Index end = std::min(j.rows(), first + kBlockRows);
    std::vector<Eigen::Index> columns;
    for (Eigen::Index r = first; r < end; ++r)
      for (Rows::InnerIterator it(j, r); it; ++it) columns.push_back(it.col());
    std::sort(columns.begin(), columns.end());
    columns.erase(std::unique(columns.begin(), columns.end()), columns.end());
    Eigen::MatrixXd block = Eigen::MatrixXd::Zero(end - first, static_cast<Eigen::Index>(columns.size()));
    for (Eigen::Index r = first; r < end; ++r)
      for (Rows::InnerIterator it(j, r); it; ++it) {
        const auto at = std::lower_bound(columns.begin(), columns.end(), it.col()) - columns.begin();
        block(r - first, at) = it.value() * column_scale(it.col());
      }
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(block);
    const Eigen::Index kept = std::min(block.rows(), block.cols());
    for (Eigen::Index i = 0; i < kept; ++i)
      for (Eigen::Index c = i; c < block.cols(); ++c)
        if (qr.matrixQR()(i, c) != 0.0) entries.emplace_back(reduced_rows + i, columns[c], qr.matrixQR()(i, c));
    reduced_rows += kept;
  }
  Eigen::SparseMatrix<double> reduced(reduced_rows, j.cols());
  reduced.setFromTriplets(entries.begin(), entries.end());
  reduced.makeCompressed();
  return reduced;
}

}  // namespace

std::optional<Eigen::MatrixXd> LeadingCovariance(const Rows& j, int p) {
  const Eigen::Index n = j.cols();
  if (p < 1 || p > n || j.rows() < n) return std::nullopt;
  // Columns scaled to unit norm (J D): the rank decision then does not depend on each unknown's units.
  Eigen::VectorXd column_norm = Eigen::VectorXd::Zero(n);
  for (Eigen::Index r = 0; r < j.rows(); ++r)
    for (Rows::InnerIterator it(j, r); it; ++it)
      column_norm(it.col()) += it.value() * it.value();
  Eigen::VectorXd column_scale(n);
  for (Eigen::Index c = 0; c < n; ++c) column_scale(c) = column_norm(c) > 0 ? 1.0 / std::sqrt(column_norm(c)) : 1.0;
  Eigen::SparseQR<Eigen::SparseMatrix<double>, Eigen::COLAMDOrdering<int>> qr;
  qr.setPivotThreshold(20.0 * static_cast<double>(j.rows() + n) * std::numeric_limits<double>::epsilon());
  qr.compute(ReducedRows(j, column_scale));
  if (qr.info() != Eigen::Success || qr.rank() < n) return std::nullopt;
  const Eigen::SparseMatrix<double> r = qr.matrixR().topLeftCorner(n, n);
  Eigen::MatrixXd unit = Eigen::MatrixXd::Zero(n, p);
  for (int i = 0; i < p; ++i) unit(i, i) = 1.0;
  const Eigen::MatrixXd permuted = qr.colsPermutation().transpose() * unit;
  const Eigen::MatrixXd z = r.transpose().triangularView<Eigen::Lower>().solve(permuted);
  const Eigen::MatrixXd w = r.triangularView<Eigen::Upper>().solve(z);
  const Eigen::MatrixXd x = qr.colsPermutation() * w;
  const Eigen::MatrixXd block = column_scale.head(p).asDiagonal() * x.topRows(p) * column_scale.head(p).asDiagonal();
  if (!block.allFinite()) return std::nullopt;
  for (int i = 0; i < p; ++i)
    if (!(block(i, i) > 0.0)) return std::nullopt;
  return block;
}

}  // namespace strokelab::internal
