// The standard errors of a least-squares problem's parameters, and which of them the data identify:
// from a dense Jacobian, or from a few leading unknowns of a large, sparse one (the broadband fit's).
#pragma once

#include <Eigen/Dense>
#include <Eigen/SparseCore>
#include <optional>
#include <vector>

namespace strokelab::internal {

// Cov(theta) = s^2 (J^T J)^{-1} of a least-squares problem's parameters from its Jacobian J (dense, one
// column per parameter) at the solution, over the parameters the rows constrain. A parameter is not
// identifiable when its column is zero or it takes part (component above 0.1) in a right singular vector
// of the column-scaled J whose singular value is below 1e-8 of the largest: the sensitivities are exact
// to ~1e-8, so such a direction is zero within their error (e.g. an amplifier limit above every record's
// drive, a stop no record reaches). The others' covariance is that of the problem with those held.
struct ParameterErrors {
  Eigen::MatrixXd covariance;  // NaN rows and columns for parameters not identifiable
  std::vector<bool> identifiable;
};
ParameterErrors ErrorsFromJacobian(const Eigen::MatrixXd& j, double residual_variance);

// The same for the first p columns of a large, sparse J (the broadband fit's model parameters among
// its segments' start states and records' offsets and hum), the other unknowns eliminated: with J's
// columns scaled to unit norm and ordered the others first, [J_o J_p] = Q [R_oo R_op; 0 R_pp], and
// J^T J's Schur complement on the first p, J_p^T J_p - J_p^T J_o (J_o^T J_o)^-1 J_o^T J_p, is R_pp^T R_pp
// (substitute J = Q R): R_pp is a Jacobian of the first p alone, the others at their best. Not
// the normal equations, which square J's condition number (the broadband fit's continuity rows weigh 1e6
// times its samples'). Empty when the other unknowns are not all identifiable: a diagonal of R in their
// columns within 20 (m + n) eps of the unit column norm, Eigen's default pivot threshold, for J of m rows
// and n columns. The QR is of far fewer rows than J's (each block of consecutive rows replaced by the R of
// its dense QR over the columns it uses), exact up to rounding.
std::optional<ParameterErrors> LeadingErrors(const Eigen::Ref<const Eigen::SparseMatrix<double, Eigen::RowMajor>>& j,
                                             int p, double residual_variance);

}  // namespace strokelab::internal
