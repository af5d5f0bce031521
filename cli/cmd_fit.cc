// strokelab fit: a model fitted to a campaign directory (core/include/strokelab/fit.h).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "commands.h"
#include "format.h"
#include "option_flags.h"
#include "strokelab/base/errors.h"
#include "strokelab/identify/broadband_campaign.h"
#include "strokelab/identify/mixed_campaign.h"
#include "strokelab/identify/fit.h"
#include "strokelab/data/recordings.h"

namespace strokelab::cli {
namespace {

constexpr const char* kFitHelp = R"(usage: strokelab fit --data DIR [--model paper|linear] [--json] [options]

Fits a model to a stepped-sine campaign (manifest.json + one CSV per record, or mapping.json + UFF 58
or WAV files; data/README.md): the paper's procedure made robust. Per record the true drive from the
voltage channel, offsets and mains hum removed, the response's harmonics; paper Eq. 3 on the records
clear of the stop (no impact spike, distortion below --max-distortion; with fewer than 3, the 3 least
distorted without spikes), m_p held at the data sheet's; k_s from contact times and d from where
contact begins; then all parameters refined together against every record's harmonics, with standard
errors. With a nominal sensitivity only ratios are reported.

A campaign of broadband records (noise, multisine, sweep) is fitted by its time series instead: the
model driven by the measured voltage, in segments whose start states are unknowns (multiple shooting),
from paper Eq. 3 fitted to the quietest record's FRF, then to the time series of the records without
impacts; the stop's d and k_s are fitted where a record shows impacts, d from where the impacts set in.
Where none does, the stop is fitted only if the records reject the fit without it, and kept only if it
lowers the chi-square by more than Akaike's penalty for its two parameters. A fit that still ends away
from the optimum (records with hard impacts) is reported as rejected by the records. A campaign of both
kinds is fitted jointly: its stepped sines alone first, then every parameter refined on all records at
once (the stepped records' harmonics and the broadband records' time series in one least-squares
problem).

  --data DIR               campaign directory (manifest.json or mapping.json)         (required)
  --model NAME             paper (linear suspension, one linear end stop) | linear (no stop) [paper]
  --json                   one JSON object on stdout instead of the text report
  --harmonics N            response harmonics analysed and fitted                      [10]
  --mass-kg M              proof mass m_p, data sheet, held fixed [kg]                 [0.032]
  --fit-contact-damping    fit the contact damping c_s as well (else held at 0)
  --mains-hz F             mains hum removed: 0 both 50 and 60 Hz, F that one, < 0 none [0]
  --max-distortion X       harmonic distortion below which a spike-free record is clear [0.05]
  --max-iterations N       iterations of the joint refinement                          [50]
  --no-refine              stop at the staged estimates (standard errors at them); a mixed campaign
                           then takes its stepped sines alone, a broadband one is refused

Exit codes: 0 fitted (a refinement that did not converge is a warning in the report), 2 bad input
(the message names the file and line or the flag), 3 numerical failure.
)";

std::string Fixed(double value, int precision) {
  if (!std::isfinite(value)) return "-";
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*f", precision, value);
  return buffer;
}

// The parameter table: value, standard error ("-" for a fixed one or one without), unit, and the note, marked where
// the parameter is fixed or not identifiable.
void PrintParameters(const std::vector<FitParameter>& parameters, std::ostream& out) {
  char line[256];
  std::snprintf(line, sizeof line, "%-10s %14s %12s %9s  %s\n", "parameter", "value", "std. error", "unit", "note");
  out << line;
  for (const FitParameter& p : parameters) {
    std::string note = p.note;
    if (p.fixed) note = "fixed: " + note;
    if (!p.identifiable) note = "NOT IDENTIFIABLE: " + note;
    std::snprintf(line, sizeof line, "%-10s %14s %12s %9s  %s\n", p.name.c_str(), General(p.value, 8).c_str(),
                  p.fixed || std::isnan(p.standard_error) ? "-" : General(p.standard_error, 3).c_str(), p.unit.c_str(),
                  note.c_str());
    out << line;
  }
}

void PrintReport(const FitResult& r, std::ostream& out) {
  out << "model " << ToString(r.model_kind) << ", " << ToString(r.response) << " response"
      << (r.absolute_scale ? "" : " (sensitivity nominal: only ratios identifiable)") << ", " << r.records.size()
      << " records, " << General(r.seconds, 3) << " s\n";
  out << r.identifiability << "\n\n";

  PrintParameters(r.parameters, out);
  char line[256];

  const FrfFitSummary& l = r.linear.summary;
  out << "\nstage 2, paper Eq. 3 on " << r.linear.records.size() << " records with distortion up to "
      << General(100 * r.linear.distortion_limit, 3) << " % and no spike: k_p "
      << General(l.stiffness_n_per_m, 6) << " N/m, c_p " << General(l.damping_n_s_per_m, 6) << " N s/m, g "
      << General(l.gain_n_per_v, 6) << " N/V" << (l.converged ? "" : " (NOT CONVERGED)") << "\n";
  const ContactEstimate& c = r.contact;
  if (!c.records.empty()) {
    const ContactCounts n = CountContacts(r);  // as FitResultToJson's stages.contact
    out << "stage 3, contact: " << n.records_not_clear << " records not clear of the stop, " << n.records_with_spikes
        << " of them with impact spikes (" << n.spikes << " spikes, " << c.spikes << " with a contact time), contact time "
        << General(c.contact_time_s * 1e3, 4) << " ms (RSD " << General(c.contact_time_rsd, 2) << "), k_s "
        << General(c.stiffness_n_per_m, 6) << " +- " << General(c.stiffness_spread_n_per_m, 3)
        << " N/m (spread), |d| between " << General(c.largest_clear_amplitude_m, 4) << " and "
        << General(c.smallest_contacting_amplitude_m, 4) << " m (" << (c.lower_stop ? "lower" : "upper") << " stop)\n";
  }
  const RefinementSummary& f = r.refinement;
  out << "stage 4, joint refinement: " << (f.ran ? "" : "not run, ") << f.iterations << " iterations, " << f.residuals
      << " residuals, residual variance " << General(f.residual_variance, 3) << " (1: noise only), "
      << (f.converged ? "converged" : "NOT CONVERGED") << ", " << General(f.seconds, 3) << " s\n";
  out << "normalised RMS of the response residual (harmonics 1..N): " << General(r.nrmse_initial, 3) << " staged, "
      << General(r.nrmse, 3) << " fitted\n\n";

  std::snprintf(line, sizeof line, "%-16s %9s %7s %6s %7s %8s %10s %10s %8s  %s\n", "record", "f [Hz]", "V [V]",
                "clear", "spikes", "dT [ms]", "nrmse", "chi2", "period", "used for");
  out << line;
  for (const RecordFit& x : r.records) {
    std::string used;
    if (x.used_linear) used += "linear ";
    if (x.used_contact) used += "contact-time ";
    if (x.used_refinement) used += "refinement";
    const std::string period = std::to_string(x.model_period) + "/" + std::to_string(x.response_periods);
    std::snprintf(line, sizeof line, "%-16s %9s %7s %6s %7zu %8s %10s %10s %8s  %s\n", x.name.c_str(),
                  Fixed(x.frequency_hz, 4).c_str(), Fixed(x.amplitude_v, 4).c_str(), x.clear ? "yes" : "no", x.spikes,
                  Fixed(x.contact_time_s * 1e3, 3).c_str(), General(x.nrmse, 3).c_str(), General(x.chi2, 3).c_str(),
                  period.c_str(), used.c_str());
    out << line;
  }
  out << "(period: of the fitted model's steady state / of the record's response, in drive periods; 0 aperiodic)\n";
  if (!r.warnings.empty()) {
    out << "\nwarnings:\n";
    for (const std::string& w : r.warnings) out << "  " << w << "\n";
  }
}

// Each broadband record's noise level, offset, misfit before and after, and segments.
void PrintBroadbandRecords(const std::vector<internal::BroadbandRecordFit>& records, std::ostream& out) {
  char line[256];
  std::snprintf(line, sizeof line, "%-16s %12s %12s %10s %10s %10s %9s\n", "record", "noise rms", "offset", "nrmse0",
                "nrmse", "chi2/n", "segments");
  out << line;
  for (const internal::BroadbandRecordFit& x : records) {
    std::snprintf(line, sizeof line, "%-16s %12s %12s %10s %10s %10s %9zu\n", x.name.c_str(),
                  General(x.noise_rms, 3).c_str(), General(x.offset, 3).c_str(), General(x.nrmse_initial, 3).c_str(),
                  General(x.nrmse, 3).c_str(), General(x.chi2_per_sample, 3).c_str(), x.segments);
    out << line;
  }
}

void PrintBroadbandReport(const BroadbandCampaignFit& fit, std::ostream& out) {
  const internal::ExtendedFitResult& r = fit.result.fit;
  out << "model " << ToString(fit.model_kind) << ", " << ToString(fit.response) << " response"
      << (fit.absolute_scale ? "" : " (sensitivity nominal: only ratios identifiable)") << ", "
      << fit.result.records.size() << " broadband records fitted by their time series, " << General(fit.seconds, 3)
      << " s" << (fit.starts_tried > 1 ? " (" + std::to_string(fit.starts_tried) + " stop positions tried)" : "")
      << "\n";
  out << (r.converged ? "converged" : "NOT CONVERGED") << (fit.result.rejected ? ", REJECTED by the records" : "")
      << ": chi-square " << General(r.chi2, 6) << " over " << r.residuals << " samples, residual variance "
      << General(r.residual_variance, 3) << " (1: noise only), " << r.iterations << " iterations\n\n";
  PrintParameters(ReportedBroadbandParameters(r, fit.absolute_scale), out);
  const FrfFitSummary& l = fit.linear_start;
  out << "\nstart: paper Eq. 3 on " << fit.start_record << "'s FRF: k_p " << General(l.stiffness_n_per_m, 6)
      << " N/m, c_p " << General(l.damping_n_s_per_m, 6) << " N s/m, g " << General(l.gain_n_per_v, 6) << " N/V"
      << (l.converged ? "" : " (NOT CONVERGED)");
  if (fit.linear_records > 0)
    out << "; refined on " << fit.linear_records << " record" << (fit.linear_records > 1 ? "s" : "")
        << " without impacts";
  if (fit.stop_free)
    out << "\nstop start: d " << General(fit.stop_start_m, 6) << " m, "
        << (fit.impact_onsets > 0 ? "the median of " + std::to_string(fit.impact_onsets) + " impact onsets"
                                  : std::string("the data sheet's"));
  out << "\n\n";
  PrintBroadbandRecords(fit.result.records, out);
  if (!fit.warnings.empty() || !r.converged || fit.result.rejected) out << "\n" << r.report << "\n";
  for (const std::string& w : fit.warnings) out << "warning: " << w << "\n";
}

void PrintMixedReport(const MixedCampaignFit& fit, std::ostream& out) {
  const internal::ExtendedFitResult& r = fit.result.fit;
  out << "model " << ToString(fit.model_kind) << ", " << ToString(fit.response) << " response"
      << (fit.absolute_scale ? "" : " (sensitivity nominal: only ratios identifiable)") << ", " << fit.stepped_used
      << " stepped-sine records (their harmonics) and " << fit.result.records.size()
      << " broadband records (their time series) fitted jointly, " << General(fit.seconds, 3) << " s\n";
  out << (r.converged ? "converged" : "NOT CONVERGED") << (fit.result.rejected ? ", REJECTED by the records" : "")
      << ": chi-square " << General(r.chi2, 6) << " over " << r.residuals
      << " residuals (harmonics and samples), residual variance " << General(r.residual_variance, 3)
      << " (1: noise only), " << r.iterations << " iterations\n\n";
  PrintParameters(ReportedBroadbandParameters(r, fit.absolute_scale), out);
  out << "\nstart: the stepped-sine records alone (" << (fit.stepped.refinement.converged ? "converged" : "NOT CONVERGED")
      << ", " << General(fit.stepped.seconds, 3) << " s):\n";
  PrintParameters(fit.stepped.parameters, out);
  char line[128];
  std::snprintf(line, sizeof line, "\n%-16s %10s %10s\n", "stepped record", "chi2/n", "n");
  out << line;
  for (const internal::SteppedRecordFit& x : fit.result.stepped) {
    std::snprintf(line, sizeof line, "%-16s %10s %10zu\n", x.name.c_str(),
                  General(x.chi2 / static_cast<double>(x.residuals), 3).c_str(), x.residuals);
    out << line;
  }
  out << "\n";
  PrintBroadbandRecords(fit.result.records, out);
  if (!fit.warnings.empty() || !r.converged || fit.result.rejected) out << "\n" << r.report << "\n";
  for (const std::string& w : fit.warnings) out << "warning: " << w << "\n";
}

}  // namespace

void AddFitFlags(std::vector<std::string>* valued, std::vector<std::string>* switches) {
  valued->push_back("--model");
  AddOptionFlags(FitOptionFields(), valued, switches);
}

FitOptions FitOptionsFromArgs(const Args& args) {
  FitOptions options;
  try {
    options.model = ParseFitModel(args.GetOr("--model", "paper"));
  } catch (const InputError& e) {
    throw InputError("--model", e.bare_message());
  }
  ReadOptionFlags(args, FitOptionFields(), &options);
  if (const std::optional<FieldError> error = options.IsValid())
    throw InputError(FlagOf(FitOptionFields(), error->field), error->message);
  return options;
}

int RunFit(const std::vector<std::string>& argv) {
  std::vector<std::string> values = {"--data"}, switches = {"--json", "--help"};
  AddFitFlags(&values, &switches);
  const Args args(argv, {values.begin(), values.end()}, {switches.begin(), switches.end()});
  if (args.Has("--help")) {
    std::cout << kFitHelp;
    return 0;
  }
  if (!args.Positional().empty())
    throw InputError(args.Positional().front(), "unexpected argument (see strokelab fit --help)");
  const auto data = args.Get("--data");
  if (!data) throw InputError("--data", "is required (the campaign directory)");

  const FitOptions options = FitOptionsFromArgs(args);
  const Campaign campaign = ReadCampaign(*data);
  CampaignFitKind kind;
  try {
    kind = FitKindOf(campaign, options);
  } catch (const InputError& e) {
    throw InputError("--no-refine", e.bare_message());
  }
  if (kind == CampaignFitKind::kMixed) {
    const MixedCampaignFit fit = FitMixedCampaign(campaign, options);
    if (args.Has("--json")) std::cout << MixedCampaignFitToJson(fit).dump(2) << "\n";
    else PrintMixedReport(fit, std::cout);
    return 0;
  }
  if (kind == CampaignFitKind::kBroadband) {
    const BroadbandCampaignFit fit = FitBroadbandCampaign(campaign, options);
    if (args.Has("--json")) std::cout << BroadbandCampaignFitToJson(fit).dump(2) << "\n";
    else PrintBroadbandReport(fit, std::cout);
    return 0;
  }
  const FitResult result = FitCampaign(campaign, options);
  if (args.Has("--json")) {
    std::cout << FitResultToJson(result).dump(2) << "\n";
  } else {
    PrintReport(result, std::cout);
  }
  return 0;
}

}  // namespace strokelab::cli
