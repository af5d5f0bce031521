// The fit of a broadband campaign with start values from its records (identify/broadband_campaign.h).
#include "strokelab/identify/broadband_campaign.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <nlohmann/json.hpp>
#include <numbers>
#include <numeric>
#include <utility>
#include <unsupported/Eigen/FFT>

#include "strokelab/base/chi_square.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/json_number.h"
#include "strokelab/base/nan.h"
#include "strokelab/model/model_json.h"
#include "strokelab/signal/signal.h"

namespace strokelab {

using internal::LogParameter;

std::vector<FrfSample> BroadbandFrf(const Recording& record) {
  const size_t n = record.size();
  if (n < 256) throw InputError(record.name, "is too short for a spectral estimate (fewer than 256 samples)");
  const double u_mean = std::accumulate(record.voltage_v.begin(), record.voltage_v.end(), 0.0) / static_cast<double>(n);
  const double y_mean = std::accumulate(record.response.begin(), record.response.end(), 0.0) / static_cast<double>(n);
  std::vector<double> u(n), y(n);
  for (size_t k = 0; k < n; ++k) {
    const double window = 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * k / n);
    u[k] = (record.voltage_v[k] - u_mean) * window;
    y[k] = (record.response[k] - y_mean) * window;
  }
  Eigen::FFT<double> fft;
  std::vector<std::complex<double>> u_bins, y_bins;
  fft.fwd(u_bins, u);
  fft.fwd(y_bins, y);
  std::vector<std::complex<double>> suu(n / 2 + 1), syu(n / 2 + 1);
  for (size_t k = 0; k < suu.size(); ++k) {
    suu[k] = std::norm(u_bins[k]);
    syu[k] = y_bins[k] * std::conj(u_bins[k]);
  }
  double peak = 0.0;
  for (size_t k = 1; k < suu.size(); ++k) peak = std::max(peak, suu[k].real());
  std::vector<size_t> bins;
  for (size_t k = 1; k < suu.size(); ++k)
    if (suu[k].real() >= 0.01 * peak) bins.push_back(k);
  const size_t stride = std::max<size_t>(1, bins.size() / 200);
  std::vector<FrfSample> samples;
  for (size_t i = 0; i < bins.size(); i += stride) {
    const size_t k = bins[i];
    samples.push_back({static_cast<double>(k) * record.sample_rate_hz / static_cast<double>(n), syu[k] / suu[k]});
  }
  return samples;
}

std::vector<bool> RecordImpacts(const Recording& record, ResponseKind kind) {
  std::vector<double> y = record.response;
  const int differences = kind == ResponseKind::kDisplacement ? 2 : kind == ResponseKind::kVelocity ? 1 : 0;
  for (int k = 0; k < differences; ++k) {
    for (size_t n = 0; n + 1 < y.size(); ++n) y[n] = y[n + 1] - y[n];
    y.pop_back();
  }
  std::vector<bool> impact = internal::ImpactSamples(y, internal::FourthDifferenceNoiseRms(y));
  impact.resize(record.size(), false);  // the differences' last samples: none
  return impact;
}

BroadbandCampaignFit FitBroadbandCampaign(const Campaign& campaign, const FitOptions& options) {
  const auto clock_start = std::chrono::steady_clock::now();
  Validate(options);
  BroadbandCampaignFit out;
  out.model_kind = options.model;
  out.response = campaign.response;
  out.absolute_scale = campaign.absolute_scale;
  std::vector<const Recording*> records;
  for (const Recording& r : campaign.records) {
    if (r.broadband) records.push_back(&r);
    else out.warnings.push_back("record " + r.name + " is a stepped sine: not used (broadband records only)");
  }
  if (records.empty()) throw InputError("records", "the campaign holds no broadband record");

  // 1. The linear start from the record with the smallest drive.
  const Recording* quiet = *std::min_element(records.begin(), records.end(), [](const Recording* a, const Recording* b) {
    return RmsAboutMean(a->voltage_v) < RmsAboutMean(b->voltage_v);
  });
  out.start_record = quiet->name;
  std::vector<FrfSample> frf = BroadbandFrf(*quiet);
  for (FrfSample& s : frf) s.h = EquivalentForceFrf(s.h, campaign.response, s.frequency_hz, options.mass_kg);
  FrfFitOptions frf_options;
  frf_options.mass_kg = options.mass_kg;
  out.linear_start = FitLinearFrf(frf, frf_options);
  if (!out.linear_start.converged)
    out.warnings.push_back("the linear start (paper Eq. 3 on " + quiet->name + "'s FRF) did not converge: " +
                           out.linear_start.report);

  const FrfFitSummary& l = out.linear_start;
  const bool linear_ok = l.converged && l.stiffness_n_per_m > 0 && l.damping_n_s_per_m > 0 && l.gain_n_per_v != 0;
  if (!linear_ok) out.warnings.push_back("the linear part starts at the data sheet's values (paper Table 2)");
  ActuatorModel linear = PaperModel();
  linear.mass_kg = options.mass_kg;
  linear.lower_stop_m = ActuatorModel::kNoLowerStop;
  if (linear_ok) {
    linear.stiffness_n_per_m = l.stiffness_n_per_m;
    linear.damping_n_s_per_m = l.damping_n_s_per_m;
    linear.gain_n_per_v = l.gain_n_per_v;
  }
  internal::BroadbandFitOptions fit_options;
  fit_options.max_iterations = options.max_iterations;
  fit_options.max_seconds = options.max_refinement_seconds;
  // k_p, c_p and g, free within a factor 3 of `m`'s.
  auto linear_parameters = [](const ActuatorModel& m) {
    return std::vector<internal::FreeParameter>{
        LogParameter("k_p", "N/m", &ActuatorModel::stiffness_n_per_m, m.stiffness_n_per_m, 3.0),
        LogParameter("c_p", "N s/m", &ActuatorModel::damping_n_s_per_m, m.damping_n_s_per_m, 3.0),
        LogParameter("g", "N/V", &ActuatorModel::gain_n_per_v, m.gain_n_per_v, 3.0)};
  };
  // The linear part refined by the time series of records that show no impact, with the stop taken
  // away (a linear model's fit has one valley): of every such record where the model has a stop and
  // some other record shows impacts, since the stop's start is then read off the linear model (step 2)
  // and a few per cent in k_p put it outside the narrow valley hard impacts leave in d (on 11 records,
  // 1.6 % off in k_p from the quietest alone, 0.01 % from the nine without impacts); else of the
  // quietest alone, whose start the full fit then refines anyway. A joint refinement the records reject
  // (an impact too soft to see, say) falls back to the quietest alone.
  auto shows_impacts = [&](const Recording& r) {
    const std::vector<bool> impact = RecordImpacts(r, campaign.response);
    return std::find(impact.begin(), impact.end(), true) != impact.end();
  };
  std::vector<const Recording*> impact_free;
  for (const Recording* r : records)
    if (!shows_impacts(*r)) impact_free.push_back(r);
  const bool quiet_is_free = std::find(impact_free.begin(), impact_free.end(), quiet) != impact_free.end();
  std::vector<std::vector<const Recording*>> refinements;
  if (options.model == FitModelKind::kPaper && impact_free.size() > 1 && impact_free.size() < records.size())
    refinements.push_back(impact_free);
  if (quiet_is_free) refinements.push_back({quiet});
  for (const std::vector<const Recording*>& refined_on : refinements) {
    internal::ExtendedProblem linear_problem;
    linear_problem.base = linear;
    linear_problem.parameters = linear_parameters(linear);
    const internal::BroadbandFitResult refined =
        internal::FitBroadband(refined_on, campaign.response, linear_problem, fit_options);
    if (!refined.fit.converged || refined.rejected) continue;
    linear = refined.fit.model;
    out.linear_records = refined_on.size();
    break;
  }

  out.linear_model = linear;
  // 2. The stop, where a record shows impacts, from where the impacts set in as the linear model sees
  // them (ImpactOnsetsM; the median of those below the rest position), else the data sheet's.
  out.stop_free = options.model == FitModelKind::kPaper && impact_free.size() < records.size();
  internal::ExtendedProblem problem;
  problem.base = PaperModel();
  problem.base.mass_kg = options.mass_kg;
  if (out.stop_free) {
    std::vector<double> lower;
    for (double x : internal::ImpactOnsetsM(records, campaign.response, linear))
      if (x < 0) lower.push_back(x);
    if (!lower.empty()) {
      std::nth_element(lower.begin(), lower.begin() + static_cast<long>(lower.size() / 2), lower.end());
      problem.base.lower_stop_m = lower[lower.size() / 2];
      out.impact_onsets = lower.size();
    }
  }
  out.stop_start_m = problem.base.lower_stop_m;

  // 3. The problem and the fit.
  auto problem_from = [&](double stop_factor, double contact_stiffness_n_per_m) {
    internal::ExtendedProblem p = problem;
    if (!out.stop_free) p.base.lower_stop_m = ActuatorModel::kNoLowerStop;
    p.parameters = linear_parameters(linear);
    if (options.model == FitModelKind::kPaper && out.stop_free) {
      p.parameters.push_back(
          LogParameter("d", "m", &ActuatorModel::lower_stop_m, stop_factor * problem.base.lower_stop_m, 3.0));
      p.parameters.push_back(
          LogParameter("k_s", "N/m", &ActuatorModel::contact_stiffness, contact_stiffness_n_per_m, 30.0));
    }
    return p;
  };
  // The impacts make the misfit rugged in d (broadband_fit.h): a fit the records reject is tried again
  // from the next of a few stop positions around the start's, and the first the records accept,
  // or else the one with the least chi-square, is the result. Without impacts seen, the stop is freed
  // when the records reject the fit without it: a displacement record that grazes the stop by a few
  // micrometres shows no impact in its differences, yet no stop-free model fits it. A stop no record
  // shows an impact of may also be soft, and from the data sheet's stiff one a fit runs the stop out of
  // the motion (a Hertzian stop beside a hardening suspension, broadband study 8410: d and k_s ran to
  // their bounds, and the stop-free fit stayed the base at 3.2 times the noise's chi-square, where a
  // linear stop of 7e4 N/m fits at 1.005).
  // Such a stop is also tried from a soft start at each position: halfway (in log) between the
  // suspension's stiffness, below which a stop hardly stops, and the data sheet's.
  constexpr double kStopFactors[] = {1.0, 0.97, 1.03, 0.94, 1.06};
  const double sheet_ks = problem.base.contact_stiffness;
  std::vector<std::pair<double, double>> starts;  // d's factor, k_s [N/m]
  auto plan_starts = [&](bool soft_too) {
    starts.clear();
    const double soft_ks = std::sqrt(linear.stiffness_n_per_m * sheet_ks);
    for (double factor : kStopFactors) {
      starts.emplace_back(factor, sheet_ks);
      if (soft_too) starts.emplace_back(factor, soft_ks);
    }
  };
  // A stop no record shows an impact of must earn its two parameters: it replaces the fit without it only
  // where it lowers the chi-square by more than Akaike's penalty for them (chi_square.h), as an effect must
  // in the diagnosis. A stop the motion does not reach lowers it by nothing, and which start such a
  // fit kept was down to the last bits (clipping, broadband study 8414: d kept at -0.94 mm, 6 % shallow,
  // which the motion of the held-out parts then hit).
  constexpr double kStopAkaikePenalty = 2 * kAkaikePenaltyPerParameter;  // d and k_s
  const bool impacts_seen = out.stop_free;
  bool without_stop = !impacts_seen;  // the kept fit has no stop (the first, where no impact is seen)
  plan_starts(false);
  for (size_t next = 0; next < starts.size(); ++next) {
    const auto [factor, contact_stiffness] = starts[next];
    // The starts share the fit's wall-time budget (options.max_refinement_seconds).
    const double spent = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
    if (out.starts_tried > 0 && spent >= options.max_refinement_seconds) break;
    fit_options.max_seconds = std::max(1.0, options.max_refinement_seconds - spent);
    internal::BroadbandFitResult trial =
        internal::FitBroadband(records, campaign.response, problem_from(factor, contact_stiffness), fit_options);
    ++out.starts_tried;
    const double margin = out.stop_free && without_stop ? kStopAkaikePenalty : 0.0;
    const bool better = out.starts_tried == 1 || !(trial.fit.chi2 >= out.result.fit.chi2 - margin);
    if (better) {
      out.result = std::move(trial);
      without_stop = !out.stop_free;
    }
    const bool accepted = out.result.fit.converged && !out.result.rejected;
    if (accepted) break;
    if (!out.stop_free) {
      if (options.model != FitModelKind::kPaper) break;
      out.stop_free = true;
      plan_starts(true);
      next = static_cast<size_t>(-1);  // from the data sheet's d again
    }
  }
  if (options.model == FitModelKind::kPaper && !impacts_seen) {
    if (!out.stop_free) {
      out.warnings.push_back("no record shows an impact: the stop's position and stiffness cannot be fitted");
    } else if (without_stop) {
      out.stop_free = false;
      const int stop_starts = out.starts_tried - 1;
      out.warnings.push_back(
          "no record shows an impact, and the records reject the fit without the stop, but " +
          (stop_starts == 0 ? std::string("the fit's time ran out before a stop was fitted")
                            : "no stop fitted from " + std::to_string(stop_starts) +
                                  " starts lowers its chi-square by more than Akaike's penalty (" +
                                  std::to_string(static_cast<int>(kStopAkaikePenalty)) + ")") +
          ": it is left out");
    } else {
      out.warnings.push_back("no record shows an impact, but the records reject the fit without the stop: it is fitted");
    }
  }
  if (!campaign.absolute_scale)
    out.warnings.push_back("the sensitivity is nominal: g and d carry its unknown factor (only ratios are identifiable)");
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return out;
}

std::vector<FitParameter> ReportedBroadbandParameters(const internal::ExtendedFitResult& fit, bool absolute_scale) {
  if (absolute_scale) return fit.parameters;
  const std::string scaled = "scaled by the response's unknown sensitivity (absolute_scale false)";
  const double mass = fit.model.mass_kg;
  const size_t n = fit.parameters.size();
  std::vector<FitParameter> out;
  size_t g = n, d = n;
  for (size_t i = 0; i < n; ++i) {
    FitParameter p = fit.parameters[i];
    if (p.name == "g" || p.name == "d") {
      (p.name == "g" ? g : d) = i;
      p.identifiable = false;
      p.note = scaled;
    } else if (p.name == "k_p" || p.name == "c_p" || p.name == "k_s" || p.name == "c_s") {
      p.name += "/m_p";
      p.unit = p.name[0] == 'c' ? "1/s" : "1/s^2";
      p.value /= mass;
      p.standard_error /= mass;
      p.note = "independent of the sensitivity";
    }
    out.push_back(p);
  }
  if (g < n && d < n) {
    // Var(d / g) = (d / g)^2 (C_dd / d^2 + C_gg / g^2 - 2 C_dg / (d g)), the delta method.
    const FitParameter& pg = fit.parameters[g];
    const FitParameter& pd = fit.parameters[d];
    const auto c = [&](size_t i, size_t j) { return fit.covariance.size() == n * n ? fit.covariance[i * n + j] : kNaN; };
    const double ratio = pd.value / pg.value;
    const double relative = c(d, d) / (pd.value * pd.value) + c(g, g) / (pg.value * pg.value) -
                            2.0 * c(d, g) / (pd.value * pg.value);
    FitParameter r;
    r.name = "d/g";
    r.unit = "m V/N";
    r.value = ratio;
    r.standard_error = std::abs(ratio) * std::sqrt(std::max(0.0, relative));
    r.identifiable = std::isfinite(r.standard_error);
    r.note = "stop position over gain: independent of the sensitivity";
    out.push_back(r);
  }
  return out;
}

nlohmann::json BroadbandFitJson(const internal::BroadbandFitResult& fit, bool absolute_scale) {
  using nlohmann::json;
  const internal::ExtendedFitResult& r = fit.fit;
  json parameters = json::object();
  for (const FitParameter& p : ReportedBroadbandParameters(r, absolute_scale)) parameters[p.name] = FitParameterJson(p);
  json records = json::array();
  for (const internal::BroadbandRecordFit& x : fit.records)
    records.push_back({{"name", x.name},
                       {"noise_rms", JsonNumber(x.noise_rms)},
                       {"offset", JsonNumber(x.offset)},
                       {"hum_amplitude", JsonNumber(x.hum_amplitude)},
                       {"nrmse_initial", JsonNumber(x.nrmse_initial)},
                       {"nrmse", JsonNumber(x.nrmse)},
                       {"chi2_per_sample", JsonNumber(x.chi2_per_sample)},
                       {"segments", x.segments}});
  return {{"parameters", parameters},
          {"fitted_model", ModelToJson(r.model)},
          {"converged", r.converged},
          {"rejected", fit.rejected},
          {"report", r.report},
          {"chi2", JsonNumber(r.chi2)},
          {"residuals", r.residuals},
          {"residual_variance", JsonNumber(r.residual_variance)},
          {"iterations", r.iterations},
          {"records", records}};
}

nlohmann::json BroadbandCampaignFitToJson(const BroadbandCampaignFit& fit) {
  using nlohmann::json;
  const FrfFitSummary& l = fit.linear_start;
  json out = BroadbandFitJson(fit.result, fit.absolute_scale);
  out.update(json{{"kind", "broadband"},
                  {"model", ToString(fit.model_kind)},
                  {"response", ToString(fit.response)},
                  {"absolute_scale", fit.absolute_scale},
                  {"linear_start",
                   {{"record", fit.start_record},
                    {"k_p", JsonNumber(l.stiffness_n_per_m)},
                    {"c_p", JsonNumber(l.damping_n_s_per_m)},
                    {"g", JsonNumber(l.gain_n_per_v)},
                    {"converged", l.converged}}},
                  {"linear_records", fit.linear_records},
                  {"stop_fitted", fit.stop_free},
                  {"stop_start_m", JsonNumber(fit.stop_start_m)},
                  {"impact_onsets", fit.impact_onsets},
                  {"starts_tried", fit.starts_tried},
                  {"warnings", fit.warnings},
                  {"seconds", JsonNumber(fit.seconds)}});
  return out;
}

}  // namespace strokelab
