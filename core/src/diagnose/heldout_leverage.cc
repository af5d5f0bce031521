// The held-out chi-square with the diagnosed model's own parameter error counted (open_world.h,
// HeldOutLeverage).
#include <algorithm>
#include <cmath>
#include <complex>
#include <exception>
#include <limits>

#include "diagnose_internal.h"
#include "strokelab/base/parallel_for.h"
#include "strokelab/identify/fit_orbit.h"
#include "strokelab/identify/sparse_covariance.h"

namespace strokelab::internal {
namespace {

// b^T (I + U^T U)^-1 b: what the parameters' error explains of a residual r with b = U^T r.
double ExplainedByParameters(const Eigen::MatrixXd& utu, const Eigen::VectorXd& b) {
  const Eigen::MatrixXd g = Eigen::MatrixXd::Identity(utu.rows(), utu.cols()) + utu;
  return b.dot(g.llt().solve(b));
}

// A record's whitened residuals (Re, Im of each usable harmonic, `weight` = 1 / their standard
// deviation) and, where the model's periodic orbit gives them, the slopes of its model harmonics in
// the fields, whitened alike.
RecordLinearisation Linearise(const ActuatorModel& model, const std::vector<double ActuatorModel::*>& fields,
                              const RecordMatch& m, const RecordAnalysis& a, double weight, ResponseKind kind,
                              int orders) {
  std::vector<int> harmonics;  // usable, 0-based
  for (int h = 0; h < orders && h < static_cast<int>(m.measured.size()) && h < static_cast<int>(m.model.size()); ++h)
    if (a.usable.empty() || a.usable[h]) harmonics.push_back(h);
  const auto rows = static_cast<Eigen::Index>(2 * harmonics.size());
  RecordLinearisation l{Eigen::VectorXd(rows), Eigen::MatrixXd(rows, 0), m.heldout};
  for (size_t k = 0; k < harmonics.size(); ++k) {
    const std::complex<double> r = weight * (m.measured[harmonics[k]] - m.model[harmonics[k]]);
    const auto row = static_cast<Eigen::Index>(2 * k);
    l.residuals[row] = r.real(), l.residuals[row + 1] = r.imag();
  }
  if (m.model_period <= 0) return l;  // an aperiodic orbit has no slopes
  try {
    const OrbitSlopes s = OrbitHarmonicSlopes(model, a, m.model_start, m.model_period, kind, orders, fields);
    Eigen::MatrixXd slopes(rows, static_cast<Eigen::Index>(fields.size()));
    for (size_t k = 0; k < harmonics.size(); ++k)
      for (size_t j = 0; j < fields.size(); ++j) {
        const std::complex<double> d = weight * s.d_harmonics[j][harmonics[k]];
        const auto row = static_cast<Eigen::Index>(2 * k), column = static_cast<Eigen::Index>(j);
        slopes(row, column) = d.real(), slopes(row + 1, column) = d.imag();
      }
    if (slopes.allFinite()) l.slopes = std::move(slopes);
  } catch (const std::exception&) {
    // no slopes: the record's residuals are judged against noise alone
  }
  return l;
}

}  // namespace

HeldOutLeverage LeverageOf(std::span<const RecordLinearisation> records) {
  Eigen::Index p = 0, fit_rows = 0;
  for (const RecordLinearisation& r : records) p = std::max(p, r.slopes.cols());
  for (const RecordLinearisation& r : records)
    if (!r.heldout && r.slopes.cols() == p) fit_rows += r.slopes.rows();
  // C = (J_f^T J_f)^-1 over the parameters the fit records identify, by the fits' own rule
  // (sparse_covariance.h ErrorsFromJacobian), and L its Cholesky factor.
  Eigen::MatrixXd jf(fit_rows, p);
  for (Eigen::Index row = 0; const RecordLinearisation& r : records)
    if (!r.heldout && r.slopes.cols() == p) jf.middleRows(row, r.slopes.rows()) = r.slopes, row += r.slopes.rows();
  std::vector<Eigen::Index> identified;
  Eigen::MatrixXd root(0, 0);  // L, over `identified`
  if (p > 0 && fit_rows > 0) {
    const ParameterErrors errors = ErrorsFromJacobian(jf, 1.0);
    for (Eigen::Index j = 0; j < p; ++j)
      if (errors.identifiable[j]) identified.push_back(j);
    const auto n = static_cast<Eigen::Index>(identified.size());
    Eigen::MatrixXd c(n, n);
    for (Eigen::Index a = 0; a < n; ++a)
      for (Eigen::Index b = 0; b < n; ++b) c(a, b) = errors.covariance(identified[a], identified[b]);
    const Eigen::LLT<Eigen::MatrixXd> llt(c);
    if (n > 0 && llt.info() == Eigen::Success) root = llt.matrixL();
    else identified.clear();
  }
  const Eigen::Index q = root.cols();

  HeldOutLeverage out;
  out.record_chi2.assign(records.size(), std::numeric_limits<double>::quiet_NaN());
  Eigen::MatrixXd utu_all = Eigen::MatrixXd::Zero(q, q);
  Eigen::VectorXd b_all = Eigen::VectorXd::Zero(q);
  for (size_t i = 0; i < records.size(); ++i) {
    const RecordLinearisation& r = records[i];
    if (!r.heldout) continue;
    const double chi2 = r.residuals.squaredNorm();
    out.chi2 += chi2;
    out.expected_chi2 += static_cast<double>(r.residuals.size());
    out.record_chi2[i] = chi2;
    if (r.slopes.cols() != p || q == 0) continue;
    const Eigen::MatrixXd u = r.slopes(Eigen::all, identified) * root;
    const Eigen::MatrixXd utu = u.transpose() * u;
    const Eigen::VectorXd b = u.transpose() * r.residuals;
    out.record_chi2[i] -= ExplainedByParameters(utu, b);
    out.expected_chi2 += utu.trace();
    utu_all += utu;
    b_all += b;
  }
  if (q > 0) out.chi2 -= ExplainedByParameters(utu_all, b_all);
  return out;
}

std::optional<HeldOutLeverage> MeasureHeldOutLeverage(const ActuatorModel& model,
                                                      const std::vector<double ActuatorModel::*>& fields,
                                                      const std::vector<RecordMatch>& matches,
                                                      std::span<const RecordAnalysis> analyses, ResponseKind kind,
                                                      int orders) {
  if (fields.empty() || matches.size() != analyses.size()) return std::nullopt;
  if (std::none_of(matches.begin(), matches.end(), [](const RecordMatch& m) { return m.heldout; })) return std::nullopt;
  std::vector<RecordLinearisation> records(matches.size());
  ParallelFor(matches.size(), [&](size_t i) {
    const RecordMatch& m = matches[i];
    records[i].heldout = m.heldout;
    if (!std::isfinite(m.chi2) || m.model.empty()) return;  // no orbit: FindUnexplained counts it apart
    // Fits weigh by the noise alone; the held-out test judges by the noise and the sampling's jitter.
    const double weight = m.heldout ? 1.0 / std::sqrt(m.variance) : 1.0 / analyses[i].harmonic_se;
    records[i] = Linearise(model, fields, m, analyses[i], weight, kind, orders);
  });
  HeldOutLeverage out = LeverageOf(records);
  // A record without an orbit has no residuals here: FindUnexplained's own figures count it.
  for (size_t i = 0; i < matches.size(); ++i)
    if (!std::isfinite(matches[i].chi2)) out.record_chi2[i] = std::numeric_limits<double>::quiet_NaN();
  return out;
}

}  // namespace strokelab::internal
