// The standard errors of a least-squares problem's parameters, from a dense Jacobian or as the leading unknowns
// of a sparse one (identify/sparse_covariance.h).
#include "strokelab/identify/sparse_covariance.h"

#include <Eigen/OrderingMethods>
#include <Eigen/SVD>
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

ParameterErrors ErrorsFromJacobian(const Eigen::MatrixXd& j, double residual_variance) {
  const int p = static_cast<int>(j.cols());
  ParameterErrors out{Eigen::MatrixXd::Constant(p, p, std::numeric_limits<double>::quiet_NaN()),
                      std::vector<bool>(p, true)};
  const Eigen::VectorXd norms = j.colwise().norm();
  for (int i = 0; i < p; ++i)
    if (!(norms(i) > 0.0)) out.identifiable[i] = false;
  std::vector<int> kept;
  for (int i = 0; i < p; ++i)
    if (out.identifiable[i]) kept.push_back(i);
  Eigen::MatrixXd scaled(j.rows(), kept.size());
  for (size_t k = 0; k < kept.size(); ++k) scaled.col(k) = j.col(kept[k]) / norms(kept[k]);
  if (kept.empty()) return out;
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(scaled, Eigen::ComputeThinV);
  const Eigen::VectorXd& sigma = svd.singularValues();
  for (int k = 0; k < sigma.size(); ++k) {
    if (sigma(k) >= 1e-8 * sigma(0)) continue;
    for (size_t i = 0; i < kept.size(); ++i)
      if (std::abs(svd.matrixV()(i, k)) > 0.1) out.identifiable[kept[i]] = false;
  }
  std::vector<int> identified;
  for (int i : kept)
    if (out.identifiable[i]) identified.push_back(i);
  if (identified.empty()) return out;
  Eigen::MatrixXd a(j.rows(), identified.size());
  for (size_t k = 0; k < identified.size(); ++k) a.col(k) = j.col(identified[k]) / norms(identified[k]);
  const Eigen::MatrixXd inverse = (a.transpose() * a).inverse();
  for (size_t r = 0; r < identified.size(); ++r)
    for (size_t c = 0; c < identified.size(); ++c)
      out.covariance(identified[r], identified[c]) =
          residual_variance * inverse(r, c) / (norms(identified[r]) * norms(identified[c]));
  return out;
}

std::optional<ParameterErrors> LeadingErrors(const Rows& j, int p, double residual_variance) {
  const Eigen::Index n = j.cols();
  if (p < 1 || p > n || j.rows() < n) return std::nullopt;
  // Columns scaled to unit norm (J D): the rank decision then does not depend on each unknown's units.
  Eigen::VectorXd column_norm = Eigen::VectorXd::Zero(n);
  for (Eigen::Index r = 0; r < j.rows(); ++r)
    for (Rows::InnerIterator it(j, r); it; ++it)
      column_norm(it.col()) += it.value() * it.value();
  Eigen::VectorXd column_scale(n);
  for (Eigen::Index c = 0; c < n; ++c) column_scale(c) = column_norm(c) > 0 ? 1.0 / std::sqrt(column_norm(c)) : 1.0;
  // The other unknowns' columns first, in their order (their blocks stay banded: little fill without a
  // fill-reducing ordering), the first p last.
  const Eigen::SparseMatrix<double> reduced = ReducedRows(j, column_scale);
  if (reduced.rows() < n) return std::nullopt;
  std::vector<Eigen::Triplet<double>> entries;
  for (Eigen::Index c = 0; c < n; ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(reduced, c); it; ++it)
      entries.emplace_back(it.row(), c < p ? n - p + c : c - p, it.value());
  Eigen::SparseMatrix<double> ordered(reduced.rows(), n);
  ordered.setFromTriplets(entries.begin(), entries.end());
  ordered.makeCompressed();
  Eigen::SparseQR<Eigen::SparseMatrix<double>, Eigen::NaturalOrdering<int>> qr;
  qr.setPivotThreshold(0.0);  // no column is set aside: R keeps the order given
  qr.compute(ordered);
  if (qr.info() != Eigen::Success) return std::nullopt;
  const Eigen::MatrixXd r = Eigen::MatrixXd(qr.matrixR().topLeftCorner(n, n));
  const double tiny = 20.0 * static_cast<double>(j.rows() + n) * std::numeric_limits<double>::epsilon();
  for (Eigen::Index i = 0; i < n - p; ++i)
    if (!(std::abs(r(i, i)) > tiny)) return std::nullopt;
  Eigen::MatrixXd leading = r.bottomRightCorner(p, p);
  for (int c = 0; c < p; ++c) leading.col(c) /= column_scale(c);  // back to the unknowns' own units
  return ErrorsFromJacobian(leading, residual_variance);
}

}  // namespace strokelab::internal
