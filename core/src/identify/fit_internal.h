// What the files of the campaign fit (fit.h) share: fit.cc (the pipeline), fit_options.cc,
// fit_drive.cc and fit_record.cc (step 1), fit_stages.cc (steps 2-3), fit_refine.cc (step 4, the
// only one with Ceres), fit_parameters.cc (parameter vector <-> model, the reported parameters) and
// fit_json.cc. Everything of theirs that is not public lives in strokelab::fit_internal, so that
// their names never meet those of the library's other files in a unity source; the public functions
// name what they use from here with using-declarations at block scope.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <complex>
#include <limits>
#include <numbers>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include "strokelab/base/nan.h"
#include "strokelab/identify/fit.h"
#include "strokelab/model/model.h"

namespace strokelab::fit_internal {

using Complex = std::complex<double>;
inline constexpr double kTwoPi = 2.0 * std::numbers::pi;
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A number in a message, as operator<< writes it (6 significant digits).
inline std::string Format(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

// Throws InputError(field) unless value is finite and > 0 (fit_drive.cc).
void RequirePositiveFinite(double value, const std::string& field);

// Step 3's |d| bracket (largest clear, smallest contacting linear amplitude) can be wide when few
// records fall between (a held-out split, a coarse amplitude grid), and its geometric middle then
// starts the refinement in another minimum. The start instead: the |d| of a geometric grid over the
// bracket whose model `start` (k_s, stop side as staged) matches the contacting records best by
// chi-square (fit_stop_start.cc); contact.stop_distance_m when the bracket is one-sided.
double StopDistanceStart(std::span<const RecordAnalysis> analyses, ResponseKind kind, const ActuatorModel& start,
                         const ContactEstimate& contact, int orders);

// ---- Parameters of the refinement (fit_parameters.cc) ---------------------------------------------

enum ParameterIndex { kStiffness = 0, kDamping = 1, kGain = 2, kStop = 3, kContactStiffness = 4, kContactDamping = 5 };
inline constexpr int kMaxParameters = 6;
// Their names where the model is absolute (the refinement's reports and RefinementSummary::unidentified).
inline constexpr std::array<const char*, kMaxParameters> kParameterNames = {"k_p", "c_p", "g", "d", "k_s", "c_s"};

// theta_i = 1 + ln(p_i / p0_i) for the positive magnitudes p = (k_p, c_p, |g|, |d|, k_s, c_s), p0 the
// staged estimates: theta starts at 1 (so that Ceres' relative difference step is kNumericStep).
struct ParameterLayout {
  ActuatorModel base;  // m_p, stop side, contact law; the staged values p0
  bool stop = false;   // |d| and k_s are fitted
  bool contact_damping = false;
  bool lower = true;  // the stop is the lower one (x < d)
  std::array<double, kMaxParameters> p0{};

  int size() const { return stop ? (contact_damping ? 6 : 5) : 3; }

  double Magnitude(const double* theta, int i) const { return p0[i] * std::exp(theta[i] - 1.0); }

  ActuatorModel Decode(const double* theta) const {
    ActuatorModel m = base;
    m.stiffness_n_per_m = Magnitude(theta, kStiffness);
    m.damping_n_s_per_m = Magnitude(theta, kDamping);
    m.gain_n_per_v = std::copysign(Magnitude(theta, kGain), base.gain_n_per_v);
    if (stop) {
      const double d = Magnitude(theta, kStop);
      if (lower)
        m.lower_stop_m = -d;
      else
        m.upper_stop_m = d;
      m.contact_stiffness = Magnitude(theta, kContactStiffness);
      if (contact_damping) m.contact_damping_n_s_per_m = Magnitude(theta, kContactDamping);
    }
    return m;
  }
};

// The layout around the staged model `start` (its stop side; c_s fitted when asked).
ParameterLayout MakeLayout(const ActuatorModel& start, bool fit_contact_damping);

// The reported parameters from theta and its covariance (delta method: se(p) = |p| se(ln p)). Those
// the covariance gives no error (NaN) are reported not identifiable, with `why_no_error` as their note.
std::vector<FitParameter> ReportParameters(const ParameterLayout& layout, const std::vector<double>& theta,
                                           const Eigen::MatrixXd& covariance, FitModelKind kind, ResponseKind response,
                                           bool absolute_scale, const std::string& why_no_error);

// FitResult::identifiability: what the model kind, response and scale let the fit identify, in words.
std::string Identifiability(FitModelKind kind, ResponseKind response, bool absolute_scale, bool stop);

}  // namespace strokelab::fit_internal
