// The fit's parameters (fit_internal.h): the refinement's parameter vector theta <-> the model, and
// the parameters reported from theta and its covariance, with what is identifiable.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "fit_internal.h"
#include "strokelab/identify/fit.h"
#include "strokelab/model/model.h"

namespace strokelab::fit_internal {
namespace {

FitParameter Parameter(std::string name, std::string unit, double value, double se, std::string note = {}) {
  FitParameter p;
  p.name = std::move(name);
  p.unit = std::move(unit);
  p.value = value;
  p.standard_error = se;
  p.note = std::move(note);
  return p;
}

FitParameter Fixed(std::string name, std::string unit, double value, std::string note) {
  FitParameter p = Parameter(std::move(name), std::move(unit), value, 0.0, std::move(note));
  p.fixed = true;
  return p;
}

FitParameter NotIdentifiable(FitParameter p, std::string note) {
  p.identifiable = false;
  p.note = std::move(note);
  return p;
}

}  // namespace

ParameterLayout MakeLayout(const ActuatorModel& start, bool fit_contact_damping) {
  ParameterLayout layout;
  layout.base = start;
  layout.stop = start.HasLowerStop() || start.HasUpperStop();
  layout.lower = start.HasLowerStop();
  layout.p0[kStiffness] = start.stiffness_n_per_m;
  layout.p0[kDamping] = start.damping_n_s_per_m;
  layout.p0[kGain] = std::abs(start.gain_n_per_v);
  if (layout.stop) {
    layout.p0[kStop] = std::abs(layout.lower ? start.lower_stop_m : start.upper_stop_m);
    layout.p0[kContactStiffness] = start.contact_stiffness;
    layout.contact_damping = fit_contact_damping;
    if (fit_contact_damping) {
      // From 2 % of the contact's critical damping when the start has none (ln 0 does not exist).
      const double critical = 2.0 * std::sqrt(start.contact_stiffness * start.mass_kg);
      layout.p0[kContactDamping] =
          start.contact_damping_n_s_per_m > 0 ? start.contact_damping_n_s_per_m : 0.02 * critical;
      layout.base.contact_damping_n_s_per_m = layout.p0[kContactDamping];
    }
  }
  return layout;
}

std::vector<FitParameter> ReportParameters(const ParameterLayout& layout, const std::vector<double>& theta,
                                           const Eigen::MatrixXd& covariance, FitModelKind kind, ResponseKind response,
                                           bool absolute_scale, const std::string& why_no_error) {
  const ActuatorModel m = layout.Decode(theta.data());
  const double mass = m.mass_kg;
  // NaN where the covariance has none (a parameter the records do not identify).
  auto log_se = [&](int i) { return std::isnan(covariance(i, i)) ? kNaN : std::sqrt(std::max(0.0, covariance(i, i))); };
  const double k = m.stiffness_n_per_m, c = m.damping_n_s_per_m, g = m.gain_n_per_v;
  const std::string given_mass = "given m_p = " + Format(mass) + " kg (data sheet)";
  const std::string scaled = "scaled by the response's unknown sensitivity (absolute_scale false)";
  std::vector<FitParameter> out;

  if (kind == FitModelKind::kLinear) {
    out.push_back(Parameter("k_p/m_p", "1/s^2", k / mass, k / mass * log_se(kStiffness), "w_p^2"));
    out.push_back(Parameter("c_p/m_p", "1/s", c / mass, c / mass * log_se(kDamping), "2 zeta_p w_p"));
    if (response == ResponseKind::kForce) {
      FitParameter gain = Parameter("g", "N/V", g, std::abs(g) * log_se(kGain));
      out.push_back(absolute_scale ? gain : NotIdentifiable(gain, scaled));
    } else {
      FitParameter gain = Parameter("g/m_p", "N/(V kg)", g / mass, std::abs(g / mass) * log_se(kGain));
      out.push_back(absolute_scale ? gain : NotIdentifiable(gain, scaled));
    }
    return out;
  }

  const double d = layout.stop ? (layout.lower ? m.lower_stop_m : m.upper_stop_m) : kNaN;
  if (absolute_scale) {
    out.push_back(Parameter("k_p", "N/m", k, k * log_se(kStiffness), given_mass));
    out.push_back(Parameter("c_p", "N s/m", c, c * log_se(kDamping), given_mass));
    out.push_back(Parameter("g", "N/V", g, std::abs(g) * log_se(kGain),
                            response == ResponseKind::kForce ? std::string() : given_mass));
    if (layout.stop) {
      out.push_back(Parameter("d", "m", d, std::abs(d) * log_se(kStop), layout.lower ? "lower stop" : "upper stop"));
      out.push_back(
          Parameter("k_s", "N/m", m.contact_stiffness, m.contact_stiffness * log_se(kContactStiffness), given_mass));
      if (layout.contact_damping) {
        out.push_back(Parameter("c_s", "N s/m", m.contact_damping_n_s_per_m,
                                m.contact_damping_n_s_per_m * log_se(kContactDamping), given_mass));
      } else {
        out.push_back(Fixed("c_s", "N s/m", 0.0, "held at 0 (paper Table 2)"));
      }
    }
  } else {
    out.push_back(Parameter("k_p/m_p", "1/s^2", k / mass, k / mass * log_se(kStiffness)));
    out.push_back(Parameter("c_p/m_p", "1/s", c / mass, c / mass * log_se(kDamping)));
    if (layout.stop) {
      const double ks = m.contact_stiffness;
      out.push_back(Parameter("k_s/m_p", "1/s^2", ks / mass, ks / mass * log_se(kContactStiffness)));
      if (layout.contact_damping) {
        const double cs = m.contact_damping_n_s_per_m;
        out.push_back(Parameter("c_s/m_p", "1/s", cs / mass, cs / mass * log_se(kContactDamping)));
      }
      // ln(|d| / |g|) = theta_d - theta_g + const.
      const double var = covariance(kStop, kStop) + covariance(kGain, kGain) - 2.0 * covariance(kStop, kGain);
      out.push_back(Parameter("d/g", "m V/N", d / g, std::abs(d / g) * std::sqrt(std::max(0.0, var)),
                              "stop position over gain: independent of the sensitivity"));
    }
    out.push_back(NotIdentifiable(Parameter("g", "N/V", g, std::abs(g) * log_se(kGain)), scaled));
    if (layout.stop) out.push_back(NotIdentifiable(Parameter("d", "m", d, std::abs(d) * log_se(kStop)), scaled));
  }
  out.push_back(Fixed("m_p", "kg", mass, "data sheet (paper section 4); not identifiable, held fixed"));
  for (FitParameter& p : out)
    if (!p.fixed && p.identifiable && std::isnan(p.standard_error))
      p = NotIdentifiable(p, why_no_error + (p.note.empty() ? "" : " (" + p.note + ")"));
  return out;
}

std::string Identifiability(FitModelKind kind, ResponseKind response, bool absolute_scale, bool stop) {
  const bool force = response == ResponseKind::kForce;
  std::string text = "m_p is not identifiable and is held at the data-sheet value; ";
  if (kind == FitModelKind::kLinear) {
    text += "the linear model is reported as the ratios k_p/m_p and c_p/m_p";
    if (!absolute_scale) return text + "; the gain carries the response's unknown sensitivity (absolute_scale false)";
    return text + (force ? " and the absolute gain g (force response)"
                         : " and g/m_p (a kinematic response fixes only the ratio)");
  }
  if (!absolute_scale) {
    return text +
           "the response's sensitivity is only nominal and multiplies g and d alike: identifiable are k_p/m_p, "
           "c_p/m_p" +
           (stop ? ", k_s/m_p (c_s/m_p) and d/g" : "") + "; g" + (stop ? " and d are" : " is") +
           " reported but not identifiable";
  }
  std::string given = stop ? "k_p, c_p, k_s" : "k_p, c_p";
  if (force) return text + given + " are given m_p; g" + (stop ? " and d are" : " is") + " absolute";
  return text + given + " and g are given m_p (a kinematic response fixes g/m_p)" + (stop ? "; d is absolute" : "");
}

}  // namespace strokelab::fit_internal
