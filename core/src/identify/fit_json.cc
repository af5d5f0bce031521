// FitResultToJson (fit.h). Non-finite numbers are written as null (base's JsonNumber).
#include <complex>
#include <nlohmann/json.hpp>

#include "strokelab/base/json_number.h"
#include "strokelab/identify/fit.h"
#include "strokelab/model/model_json.h"

namespace strokelab {
namespace fit_internal {
namespace {

nlohmann::json ComplexJson(std::complex<double> c) {
  return {{"re", JsonNumber(c.real())}, {"im", JsonNumber(c.imag())}};
}

}  // namespace
}  // namespace fit_internal

ContactCounts CountContacts(const FitResult& r) {
  ContactCounts n;
  n.records_not_clear = r.contact.records.size();
  for (size_t i : r.contact.records) {
    if (r.records[i].spikes > 0) ++n.records_with_spikes;
    n.spikes += r.records[i].spikes;
  }
  return n;
}

nlohmann::json FitParameterJson(const FitParameter& p) {
  // A fixed parameter (m_p, c_s held at 0) was not estimated from the records: it has no standard
  // error (FitParameter holds 0 there) and is not identifiable from them (m_p's note says so).
  return {{"value", JsonNumber(p.value)},
          {"standard_error", p.fixed ? nlohmann::json(nullptr) : JsonNumber(p.standard_error)},
          {"unit", p.unit},
          {"fixed", p.fixed},
          {"identifiable", p.identifiable && !p.fixed},
          {"note", p.note}};
}

nlohmann::json FitResultToJson(const FitResult& r) {
  using fit_internal::ComplexJson;
  using nlohmann::json;
  json parameters = json::object();
  for (const FitParameter& p : r.parameters) parameters[p.name] = FitParameterJson(p);
  const FrfFitSummary& l = r.linear.summary;
  json linear = {{"records", r.linear.records.size()},
                 {"distortion_limit", JsonNumber(r.linear.distortion_limit)},
                 {"natural_frequency_rad_s", JsonNumber(l.natural_frequency_rad_s)},
                 {"natural_frequency_se", JsonNumber(l.natural_frequency_se)},
                 {"damping_ratio", JsonNumber(l.damping_ratio)},
                 {"damping_ratio_se", JsonNumber(l.damping_ratio_se)},
                 {"gain_n_per_v", JsonNumber(l.gain_n_per_v)},
                 {"gain_se", JsonNumber(l.gain_se)},
                 {"stiffness_n_per_m", JsonNumber(l.stiffness_n_per_m)},
                 {"stiffness_se", JsonNumber(l.stiffness_se)},
                 {"damping_n_s_per_m", JsonNumber(l.damping_n_s_per_m)},
                 {"damping_se", JsonNumber(l.damping_se)},
                 {"rms_residual", JsonNumber(l.rms_residual)},
                 {"converged", l.converged}};
  const ContactEstimate& c = r.contact;
  const ContactCounts counts = CountContacts(r);
  json contact = {{"records_not_clear", counts.records_not_clear},
                  {"records_with_spikes", counts.records_with_spikes},
                  {"spikes", counts.spikes},
                  {"spikes_with_contact_time", c.spikes},
                  {"contact_time_s", JsonNumber(c.contact_time_s)},
                  {"contact_time_rsd", JsonNumber(c.contact_time_rsd)},
                  {"stiffness_n_per_m", JsonNumber(c.stiffness_n_per_m)},
                  {"stiffness_spread_n_per_m", JsonNumber(c.stiffness_spread_n_per_m)},
                  {"stop", c.lower_stop ? "lower" : "upper"},
                  {"largest_clear_amplitude_m", JsonNumber(c.largest_clear_amplitude_m)},
                  {"smallest_contacting_amplitude_m", JsonNumber(c.smallest_contacting_amplitude_m)},
                  {"stop_distance_m", JsonNumber(c.stop_distance_m)}};
  const RefinementSummary& f = r.refinement;
  json refinement = {{"ran", f.ran},
                     {"converged", f.converged},
                     {"iterations", f.iterations},
                     {"correction_passes", f.correction_passes},
                     {"branch_switches", f.branch_switches},
                     {"initial_cost", JsonNumber(f.initial_cost)},
                     {"final_cost", JsonNumber(f.final_cost)},
                     {"residuals", f.residuals},
                     {"parameters", f.parameters},
                     {"residual_variance", JsonNumber(f.residual_variance)},
                     {"secant_ratios", f.secant_ratios},
                     {"largest_excursion_m", JsonNumber(f.largest_excursion_m)},
                     {"seconds", JsonNumber(f.seconds)},
                     {"report", f.report}};
  json records = json::array();
  for (const RecordFit& x : r.records) {
    json used = json::array();
    if (x.used_linear) used.push_back("linear");
    if (x.used_contact) used.push_back("contact_time");
    if (x.used_refinement) used.push_back("refinement");
    records.push_back({{"name", x.name},
                       {"frequency_hz", JsonNumber(x.frequency_hz)},
                       {"amplitude_v", JsonNumber(x.amplitude_v)},
                       {"phase_rad", JsonNumber(x.phase_rad)},
                       {"nominal_frequency_hz", JsonNumber(x.nominal_frequency_hz)},
                       {"nominal_amplitude_v", JsonNumber(x.nominal_amplitude_v)},
                       {"clear", x.clear},
                       {"spikes", x.spikes},
                       {"contact_time_s", JsonNumber(x.contact_time_s)},
                       {"distortion", JsonNumber(x.distortion)},
                       {"noise_rms", JsonNumber(x.noise_rms)},
                       {"hum_frequency_hz", JsonNumber(x.hum_frequency_hz)},
                       {"hum_amplitude", JsonNumber(x.hum_amplitude)},
                       {"response_periods", x.response_periods},
                       {"frf", ComplexJson(x.frf)},
                       {"used_for", used},
                       {"nrmse_initial", JsonNumber(x.nrmse_initial)},
                       {"nrmse", JsonNumber(x.nrmse)},
                       {"chi2", JsonNumber(x.chi2)},
                       {"model_period", x.model_period},
                       {"model_contacts_per_period", JsonNumber(x.model_contacts_per_period)}});
  }
  return {{"model", ToString(r.model_kind)},
          {"response", ToString(r.response)},
          {"absolute_scale", r.absolute_scale},
          {"mass_kg", JsonNumber(r.mass_kg)},
          {"identifiability", r.identifiability},
          {"parameters", parameters},
          {"fitted_model", ModelToJson(r.model)},
          {"stages", {{"linear", linear}, {"contact", contact}, {"refinement", refinement}}},
          {"records", records},
          {"nrmse_initial", JsonNumber(r.nrmse_initial)},
          {"nrmse", JsonNumber(r.nrmse)},
          {"warnings", r.warnings},
          {"seconds", JsonNumber(r.seconds)}};
}

}  // namespace strokelab
