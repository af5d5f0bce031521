// The fit pipeline of fit.h: the paper's procedure (section 4) made robust. Ceres stays in this file.
#include "strokelab/identify/fit.h"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <numeric>
#include <optional>
#include <sstream>
#include <utility>

#include "strokelab/identify/fit_orbit.h"
#include "strokelab/signal/harmonic_fit.h"
#include "step_callback.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/parallel_for.h"
#include "strokelab/model/model_json.h"
#include "strokelab/engines/pwl_system.h"
#include "strokelab/steady/steady_state.h"

namespace strokelab {
namespace {

using internal::AfterSuccessfulStep;
using internal::Anchor;
using internal::BestMatchingOrbit;
using internal::MismatchSquared;
using internal::ModelOrbit;
using internal::OrbitSearch;
using internal::PowerOf;
using internal::SamplingCorrection;
using internal::SolveOrbit;

using Complex = std::complex<double>;
constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kMadToSigma = 1.4826;  // sigma / MAD for normal noise

// EstimateDrive.
constexpr double kCoarseStepPerRecord = 0.25;  // grid spacing of the coarse search [1/T]
constexpr double kCoarseRangePerRecord = 2.0;  // half-width of the search, at least [1/T] ...
constexpr double kCoarseRangeRelative = 0.01;  // ... and at least this fraction of the nominal frequency
constexpr int kDriveSegments = 4;              // segments for the phase drift
constexpr int kMaxDriveNewtonSteps = 8;
constexpr double kDriveFrequencyTolerance = 1e-10;  // relative |df| / f that ends the Newton steps
// Half-width of the final parabola [1/T]: the residual is quadratic in the frequency error only for
// errors far below 1/T (at 0.01/T its cubic term moves the vertex by ~1e-5 Hz).
constexpr double kParabolaStepPerRecord = 1e-3;

// Mains hum.
constexpr int kHumOrders = 3;                    // 50, 100, 150 Hz
constexpr int kHumPasses = 3;                    // alternating drive-harmonic / hum fits
constexpr double kHumSeparationPerWindow = 0.5;  // hum within half a bin (1/T) of a drive harmonic: inseparable

constexpr double kLagRoundingSlack = 0.05;         // lags rounded this much worse than the best still count [samples]
constexpr double kImpactHeightFraction = 0.25;     // smaller spikes in a record are baseline artefacts
constexpr double kRelativeSeFloor = 1e-12;         // noise at least this fraction of |C_1| (rounding)
constexpr size_t kMinClearRecords = 3;             // paper Eq. 3 has 3 parameters
constexpr double kTable2ContactStiffness = 1.3e6;  // k_s [N/m], start when no spike gives a contact time
constexpr double kBracketMargin = 1.05;            // |d| start just above the largest clear amplitude
constexpr int kMaxCorrectionPasses = 4;            // refinement passes with refreshed sampling corrections
constexpr double kCorrectionTolerance = 1e-3;      // their change [standard errors] that ends the passes
// A record moves to another coexisting orbit between passes when that one's mismatch is below this
// fraction of its anchor orbit's (a clear win, not noise between two near-identical orbits).
constexpr double kBranchSwitchRatio = 0.5;
constexpr double kParameterRange = 3.0;            // refinement bounds: staged estimate times or over this (k_p, c_p, g, d)
constexpr double kContactRange = 30.0;             // ... and this for k_s, c_s
// Relative step of the central differences in theta = 1 + ln(p / p0): a relative change of about
// 1e-4 in each parameter, far above the steady state's accuracy (shooting to 1e-11 of |d|) and small
// against the curvature of the harmonics (1e-5 gives the same standard errors to 1 %).
constexpr double kNumericStep = 1e-4;

std::string Format(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

void RequirePositiveFinite(double value, const std::string& field) {
  if (!std::isfinite(value) || value <= 0.0)
    throw InputError(field, "must be a finite number > 0 (got " + Format(value) + ")");
}

double Median(std::vector<double> values) {
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

// 1.4826 MAD about the median: the standard deviation of normal noise, blind to a minority of spikes.
double RobustSigma(std::span<const double> residual) {
  std::vector<double> values(residual.begin(), residual.end());
  const double median = Median(values);
  for (double& v : values) v = std::abs(v - median);
  return kMadToSigma * Median(std::move(values));
}

double WrapPhase(double phase) { return std::remainder(phase, kTwoPi); }

Complex FirstHarmonicOver(std::span<const double> signal, double fs, double f, SampleWindow window) {
  return internal::FitHarmonics(signal, fs, f, window, 1).amplitudes[0];
}

// Re-throws an InputError with the record's name in front of its field.
[[noreturn]] void RethrowForRecord(const InputError& e, const std::string& record) {
  throw InputError(record + (e.field().empty() ? "" : "." + e.field()), e.bare_message());
}

// ---- Parameters of the refinement ----------------------------------------------------------------

enum ParameterIndex { kStiffness = 0, kDamping = 1, kGain = 2, kStop = 3, kContactStiffness = 4, kContactDamping = 5 };
constexpr int kMaxParameters = 6;

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

// One record of the refinement: its measured harmonics and the orbit the next evaluation starts from.
struct RecordTarget {
  const RecordAnalysis* record = nullptr;
  double weight = 1.0;  // 1 / harmonic standard error [1 / response units]
  Anchor anchor;
  std::vector<Complex> correction;  // SamplingCorrection at the last outer pass
  bool live_correction = false;     // recompute it at every evaluation (for the covariance's Jacobian)
};

// Residuals (Re, Im) of (C_h - C_h^model) / se, h = 1..N, for Ceres' central differences.
class HarmonicCost {
 public:
  HarmonicCost(const ParameterLayout* layout, RecordTarget* target, ResponseKind kind, int orders)
      : layout_(layout), target_(target), kind_(kind), orders_(orders) {}

  bool operator()(const double* theta, double* residual) const {
    try {
      const ActuatorModel model = layout_->Decode(theta);
      const std::optional<ModelOrbit> orbit =
          SolveOrbit(model, *target_->record, target_->anchor, kind_, orders_, OrbitSearch::kNearby);
      if (!orbit) return false;
      const std::vector<Complex> correction = target_->live_correction
                                                  ? SamplingCorrection(model, *target_->record, *orbit, kind_, orders_)
                                                  : target_->correction;
      for (int h = 0; h < orders_; ++h) {
        const double weight = target_->record->usable[h] ? target_->weight : 0.0;
        const Complex r = weight * (target_->record->harmonics[h] - orbit->harmonics[h] - correction[h]);
        residual[2 * h] = r.real();
        residual[2 * h + 1] = r.imag();
      }
      return true;
    } catch (const std::exception&) {
      return false;  // a model the engines refuse (Validate) or a solver failure: Ceres rejects the step
    }
  }

 private:
  const ParameterLayout* layout_;
  RecordTarget* target_;
  ResponseKind kind_;
  int orders_;
};

template <int kParameters>
ceres::CostFunction* MakeCost(const ParameterLayout* layout, RecordTarget* target, ResponseKind kind, int orders) {
  ceres::NumericDiffOptions diff;
  diff.relative_step_size = kNumericStep;
  return new ceres::NumericDiffCostFunction<HarmonicCost, ceres::CENTRAL, ceres::DYNAMIC, kParameters>(
      new HarmonicCost(layout, target, kind, orders), ceres::TAKE_OWNERSHIP, 2 * orders, diff);
}

ceres::CostFunction* MakeCost(int parameters, const ParameterLayout* layout, RecordTarget* target, ResponseKind kind,
                              int orders) {
  switch (parameters) {
    case 3:
      return MakeCost<3>(layout, target, kind, orders);
    case 5:
      return MakeCost<5>(layout, target, kind, orders);
    default:
      return MakeCost<6>(layout, target, kind, orders);
  }
}

// ---- Reporting -----------------------------------------------------------------------------------

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

// The reported parameters from theta and its covariance (delta method: se(p) = |p| se(ln p)).
std::vector<FitParameter> ReportParameters(const ParameterLayout& layout, const std::vector<double>& theta,
                                           const Eigen::MatrixXd& covariance, FitModelKind kind, ResponseKind response,
                                           bool absolute_scale) {
  const ActuatorModel m = layout.Decode(theta.data());
  const double mass = m.mass_kg;
  auto log_se = [&](int i) { return std::sqrt(std::max(0.0, covariance(i, i))); };
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

nlohmann::json Number(double value) { return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(nullptr); }

nlohmann::json ComplexJson(Complex c) { return {{"re", Number(c.real())}, {"im", Number(c.imag())}}; }

}  // namespace

// ---- Options ---------------------------------------------------------------------------------------

FitModelKind ParseFitModel(std::string_view text) {
  if (text == "paper") return FitModelKind::kPaper;
  if (text == "linear") return FitModelKind::kLinear;
  throw InputError("model", "unknown fit model '" + std::string(text) + "' (known: paper, linear)");
}

const char* ToString(FitModelKind kind) { return kind == FitModelKind::kPaper ? "paper" : "linear"; }

bool FitOptions::IsValid(std::string* error) const {
  std::string message;
  if (!std::isfinite(mass_kg) || mass_kg <= 0)
    message = "mass_kg: must be a finite number > 0, got " + Format(mass_kg);
  else if (harmonic_orders < 1)
    message = "harmonic_orders: must be >= 1, got " + std::to_string(harmonic_orders);
  else if (!std::isfinite(max_clear_distortion) || max_clear_distortion <= 0)
    message = "max_clear_distortion: must be a finite number > 0, got " + Format(max_clear_distortion);
  else if (!std::isfinite(mains_frequency_hz))
    message = "mains_frequency_hz: must be finite";
  else if (max_iterations < 1)
    message = "max_iterations: must be >= 1, got " + std::to_string(max_iterations);
  else if (!(max_refinement_seconds > 0))
    message = "max_refinement_seconds: must be > 0, got " + Format(max_refinement_seconds);
  else if (!std::isfinite(spikes.threshold_sigmas) || spikes.threshold_sigmas <= 0)
    message = "spikes.threshold_sigmas: must be a finite number > 0";
  else if (spikes.baseline_harmonics < 0)
    message = "spikes.baseline_harmonics: must be >= 0";
  if (!message.empty() && error != nullptr) *error = message;
  return message.empty();
}

namespace {
void ThrowIfInvalid(const FitOptions& options) {
  std::string error;
  if (options.IsValid(&error)) return;
  const size_t colon = error.find(": ");
  throw InputError(error.substr(0, colon), error.substr(colon + 2));
}
}  // namespace

// ---- Step 1 ----------------------------------------------------------------------------------------

DriveEstimate EstimateDrive(std::span<const double> voltage, double sample_rate_hz, double nominal_frequency_hz) {
  RequirePositiveFinite(sample_rate_hz, "sample_rate_hz");
  RequirePositiveFinite(nominal_frequency_hz, "nominal_frequency_hz");
  if (nominal_frequency_hz >= 0.5 * sample_rate_hz)
    throw InputError("nominal_frequency_hz", Format(nominal_frequency_hz) + " Hz is not below the Nyquist frequency " +
                                                 Format(0.5 * sample_rate_hz) + " Hz");
  const size_t n = voltage.size();
  const double record_s = static_cast<double>(n) / sample_rate_hz;
  if (nominal_frequency_hz * record_s < 2.0)
    throw InputError("voltage", "holds " + std::to_string(n) + " samples (" + Format(record_s) +
                                    " s), less than two periods of " + Format(nominal_frequency_hz) + " Hz");
  const SampleWindow all{0, n, nominal_frequency_hz * record_s};
  auto c1 = [&](double f, SampleWindow w) {
    try {
      return FirstHarmonicOver(voltage, sample_rate_hz, f, w);
    } catch (const InputError& e) {
      throw InputError("voltage", e.bare_message());
    }
  };

  // Coarse: the largest |C_1| on a grid around the nominal frequency.
  const double step = kCoarseStepPerRecord / record_s;
  const double range = std::max(kCoarseRangePerRecord / record_s, kCoarseRangeRelative * nominal_frequency_hz);
  const int half = static_cast<int>(std::ceil(range / step));
  double f = nominal_frequency_hz, best = -1.0;
  for (int k = -half; k <= half; ++k) {
    const double trial = nominal_frequency_hz + k * step;
    if (trial * record_s < 1.0 || trial >= 0.5 * sample_rate_hz) continue;
    const double amplitude = std::abs(c1(trial, all));
    if (amplitude > best) best = amplitude, f = trial;
  }
  if (!(best > 0.0))
    throw InputError("voltage", "has no sinusoidal component near the nominal " + Format(nominal_frequency_hz) + " Hz");

  // Newton on the phase drift over kDriveSegments segments.
  DriveEstimate drive;
  for (int iteration = 0; iteration < kMaxDriveNewtonSteps; ++iteration) {
    std::array<double, kDriveSegments> t{}, phase{};
    for (int k = 0; k < kDriveSegments; ++k) {
      const SampleWindow w{n * k / kDriveSegments, n * (k + 1) / kDriveSegments, 0.0};
      t[k] = 0.5 * static_cast<double>(w.begin + w.end - 1) / sample_rate_hz;
      const double raw = std::arg(c1(f, w));
      phase[k] = k == 0 ? raw : phase[k - 1] + WrapPhase(raw - phase[k - 1]);
    }
    const double t_mean = std::accumulate(t.begin(), t.end(), 0.0) / kDriveSegments;
    const double p_mean = std::accumulate(phase.begin(), phase.end(), 0.0) / kDriveSegments;
    double num = 0.0, den = 0.0;
    for (int k = 0; k < kDriveSegments; ++k)
      num += (t[k] - t_mean) * (phase[k] - p_mean), den += (t[k] - t_mean) * (t[k] - t_mean);
    const double df = num / den / kTwoPi;
    if (!std::isfinite(df)) throw InputError("voltage", "holds non-finite samples or no drive");
    f += df;
    ++drive.newton_steps;
    if (std::abs(df) < kDriveFrequencyTolerance * f) break;
  }

  // Last, the least-squares (for white noise the maximum-likelihood) frequency: the minimum over the
  // whole record of the residual sum of squares of the sine-plus-offset fit, by a parabola through f
  // and f +- 0.001 / T. The phase drift of four segments leaves a few times its Cramer-Rao bound.
  {
    std::vector<double> fitted(n);
    auto residual_sum = [&](double trial) {
      const internal::HarmonicFit fit = internal::FitHarmonics(voltage, sample_rate_hz, trial, all, 1);
      internal::EvaluateHarmonics(fit, sample_rate_hz, trial, all, fitted);
      double sum = 0.0;
      for (size_t i = 0; i < n; ++i) sum += (voltage[i] - fitted[i]) * (voltage[i] - fitted[i]);
      return sum;
    };
    const double h = kParabolaStepPerRecord / record_s;
    const double below = residual_sum(f - h), centre = residual_sum(f), above = residual_sum(f + h);
    const double curvature = below - 2.0 * centre + above;
    if (curvature > 0.0) f += 0.5 * h * (below - above) / curvature;
  }

  internal::HarmonicFit fit;
  try {
    fit = internal::FitHarmonics(voltage, sample_rate_hz, f, all, 1);
  } catch (const InputError& e) {
    throw InputError("voltage", e.bare_message());
  }
  std::vector<double> model(n);
  internal::EvaluateHarmonics(fit, sample_rate_hz, f, all, model);
  double sum_squares = 0.0;
  for (size_t i = 0; i < n; ++i) sum_squares += (voltage[i] - model[i]) * (voltage[i] - model[i]);
  drive.frequency_hz = f;
  drive.amplitude_v = std::abs(fit.amplitudes[0]);
  // C_1 of V sin(wt + phi) is V e^{j (phi - pi/2)}.
  drive.phase_rad = WrapPhase(std::arg(fit.amplitudes[0]) + 0.5 * std::numbers::pi);
  drive.offset_v = fit.offset;
  drive.noise_rms_v = std::sqrt(sum_squares / static_cast<double>(n));
  return drive;
}

namespace {

// The mains hum frequencies to remove from a response: the candidates (50 and 60 Hz, or the one the
// options name) that no drive harmonic masks (closer than half a frequency bin 1/T: inseparable).
// Removing a family that is not there costs 2 kHumOrders of the window's n >> 1 degrees of freedom.
std::vector<double> HumCandidates(double fs, const RecordAnalysis& a, const FitOptions& options) {
  std::vector<double> candidates, kept;
  if (options.mains_frequency_hz > 0)
    candidates = {options.mains_frequency_hz};
  else if (options.mains_frequency_hz == 0)
    candidates = {50.0, 60.0};
  const double window_s = static_cast<double>(a.window.size()) / fs;
  for (double hum : candidates) {
    if (hum * window_s < 2.0 || hum >= 0.5 * fs) continue;
    bool masked = false;
    for (int k = 1; k <= kHumOrders && !masked; ++k)
      for (int h = 1; h <= options.harmonic_orders && !masked; ++h)
        masked = std::abs(k * hum - h * a.drive.frequency_hz) * window_s < kHumSeparationPerWindow;
    if (!masked) kept.push_back(hum);
  }
  return kept;
}

// Harmonics not masked by a mains hum overtone (RecordAnalysis::usable). Harmonic 1 always counts:
// the drive's response dwarfs the hum there, and without it there is no record.
std::vector<bool> UsableHarmonics(double fs, const RecordAnalysis& a, const FitOptions& options) {
  std::vector<bool> usable(options.harmonic_orders, true);
  std::vector<double> mains;
  if (options.mains_frequency_hz > 0)
    mains = {options.mains_frequency_hz};
  else if (options.mains_frequency_hz == 0)
    mains = {50.0, 60.0};
  const double window_s = static_cast<double>(a.window.size()) / fs;
  for (double hum : mains)
    for (int k = 1; k <= kHumOrders; ++k)
      for (int h = 2; h <= options.harmonic_orders; ++h)
        if (std::abs(k * hum - h * a.drive.frequency_hz) * window_s < kHumSeparationPerWindow) usable[h - 1] = false;
  return usable;
}

// The white-noise level of a periodic signal with spikes: sigma = 1.4826 MAD(y[n + L] - y[n]) / sqrt(2)
// for a lag L = k fs / f rounded, k <= P/2 whole periods. The periodic part cancels (to y' times the
// rounding, far below the noise for the smooth part); the impacts spoil only the few samples near
// them, which the median ignores. The smallest sigma over the lags with the least rounding (within
// kLagRoundingSlack samples of the best) is taken, so that a period-2 response (cancelled by even k
// only) is not mistaken for noise. (A harmonic fit's residual would count the impacts' harmonics
// above N as noise; the scatter of per-period harmonic fits is spoiled by their leakage, one period
// not being a whole number of samples.) NaN when the window holds less than two periods.
double PeriodicNoiseSigma(std::span<const double> signal, double fs, double f, SampleWindow w) {
  const int max_k = static_cast<int>(w.periods) / 2;
  std::vector<double> rounding(max_k + 1, 1.0);
  double best_rounding = 1.0;
  for (int k = 1; k <= max_k; ++k) {
    const double lag = k * fs / f;
    rounding[k] = std::abs(lag - std::round(lag));
    best_rounding = std::min(best_rounding, rounding[k]);
  }
  double sigma = kNaN;
  for (int k = 1; k <= max_k; ++k) {
    if (rounding[k] > best_rounding + kLagRoundingSlack) continue;
    const size_t lag = static_cast<size_t>(std::llround(k * fs / f));
    if (lag >= w.size()) continue;
    std::vector<double> differences(w.size() - lag);
    for (size_t i = 0; i < differences.size(); ++i) differences[i] = signal[w.begin + i + lag] - signal[w.begin + i];
    const double candidate = RobustSigma(differences) / std::sqrt(2.0);
    if (!(candidate >= sigma)) sigma = candidate;
  }
  return sigma;
}

// The response's harmonic fit with mains hum taken out by alternating least squares (block
// Gauss-Seidel: the bases are nearly orthogonal over the window, so a few passes suffice): each hum
// family fitted to the response less the drive harmonics and the other families, the drive harmonics
// to the response less the hum. Fills harmonics, offset, hum, noise; returns the response with the
// hum removed (full length; the window's samples changed).
std::vector<double> FitResponse(const Recording& record, const FitOptions& options, RecordAnalysis* a) {
  const double fs = record.sample_rate_hz, f = a->drive.frequency_hz;
  const int orders = options.harmonic_orders;
  const SampleWindow w = a->window;
  std::vector<double> cleaned = record.response;
  std::vector<double> evaluated(w.size()), target(record.response.size(), 0.0);
  const std::vector<double> hums = HumCandidates(fs, *a, options);
  // While the hum is estimated the drive's harmonics are fitted up to above its highest overtone:
  // impacts put drive harmonics next to the hum's, which would otherwise leak into it.
  int hum_pass_orders = orders;
  for (double hum : hums) {
    const double highest_hz = kHumOrders * hum + kHumSeparationPerWindow * fs / static_cast<double>(w.size());
    hum_pass_orders = std::max(hum_pass_orders, static_cast<int>(std::ceil(highest_hz / f)) + 1);
  }
  hum_pass_orders = std::min(hum_pass_orders, static_cast<int>(std::ceil(0.5 * fs / f)) - 1);
  internal::HarmonicFit fit = internal::FitHarmonics(cleaned, fs, f, w, hum_pass_orders);
  internal::EvaluateHarmonics(fit, fs, f, w, evaluated);

  std::vector<std::vector<double>> hum_values(hums.size(), std::vector<double>(w.size(), 0.0));
  std::vector<double> hum_amplitudes(hums.size(), 0.0);
  for (int pass = 0; pass < kHumPasses && !hums.empty(); ++pass) {
    for (size_t j = 0; j < hums.size(); ++j) {
      for (size_t i = 0; i < w.size(); ++i) {
        double others = 0.0;
        for (size_t k = 0; k < hums.size(); ++k) others += k == j ? 0.0 : hum_values[k][i];
        target[w.begin + i] = record.response[w.begin + i] - evaluated[i] - others;
      }
      const int hum_orders = std::max(1, std::min(kHumOrders, static_cast<int>(std::floor(0.5 * fs / hums[j] - 1e-9))));
      const internal::HarmonicFit hum_fit = internal::FitHarmonics(target, fs, hums[j], w, hum_orders);
      internal::EvaluateHarmonics(internal::HarmonicFit{0.0, hum_fit.amplitudes}, fs, hums[j], w, hum_values[j]);
      hum_amplitudes[j] = std::abs(hum_fit.amplitudes[0]);
    }
    for (size_t i = 0; i < w.size(); ++i) {
      double hum = 0.0;
      for (const std::vector<double>& values : hum_values) hum += values[i];
      cleaned[w.begin + i] = record.response[w.begin + i] - hum;
    }
    fit = internal::FitHarmonics(cleaned, fs, f, w, hum_pass_orders);
    internal::EvaluateHarmonics(fit, fs, f, w, evaluated);
  }
  if (hum_pass_orders != orders) {
    fit = internal::FitHarmonics(cleaned, fs, f, w, orders);
    internal::EvaluateHarmonics(fit, fs, f, w, evaluated);
  }
  for (size_t j = 0; j < hums.size(); ++j) {
    if (hum_amplitudes[j] > a->hum_amplitude) a->hum_amplitude = hum_amplitudes[j], a->hum_frequency_hz = hums[j];
  }
  a->response_offset = fit.offset;
  a->harmonics.resize(orders);
  for (int h = 1; h <= orders; ++h)
    a->harmonics[h - 1] = fit.amplitudes[h - 1] * std::polar(1.0, -h * a->drive.phase_rad);
  const double n = static_cast<double>(w.size());
  a->noise_rms = PeriodicNoiseSigma(cleaned, fs, f, w);
  if (!(a->noise_rms > 0.0)) {
    // Too short for the lag (or noise-free): the robust spread of the harmonic fit's residual.
    std::vector<double> residual(w.size());
    for (size_t i = 0; i < w.size(); ++i) residual[i] = cleaned[w.begin + i] - evaluated[i];
    a->noise_rms = RobustSigma(residual);
  }
  // A noise-free (simulated) record: a floor at rounding level keeps the weights finite.
  a->noise_rms = std::max(a->noise_rms, kRelativeSeFloor * std::abs(fit.amplitudes[0]));
  a->harmonic_se = a->noise_rms * std::sqrt(2.0 / n);
  return cleaned;
}

// Where impacts show as spikes: the force or acceleration itself, else its derivatives by central
// differences (velocity once, displacement twice) [acceleration units].
std::vector<double> SpikeSignal(std::vector<double> signal, ResponseKind kind, double fs) {
  const int derivatives = kind == ResponseKind::kVelocity ? 1 : kind == ResponseKind::kDisplacement ? 2 : 0;
  for (int d = 0; d < derivatives && signal.size() >= 3; ++d) {
    std::vector<double> out(signal.size());
    for (size_t i = 1; i + 1 < signal.size(); ++i) out[i] = 0.5 * fs * (signal[i + 1] - signal[i - 1]);
    out.front() = out[1];
    out.back() = out[out.size() - 2];
    signal = std::move(out);
  }
  return signal;
}

// The spikes of impacts: those at least kImpactHeightFraction of the record's largest. The rest are
// the baseline's: DetectSpikes' smooth baseline (a few harmonics) cannot follow the step that an
// impact leaves in the force (the damping force c_p x' flips with the velocity), and flags it.
std::vector<Spike> ImpactSpikes(std::vector<Spike> spikes) {
  double largest = 0.0;
  for (const Spike& s : spikes) largest = std::max(largest, std::abs(s.peak_height));
  std::erase_if(spikes, [&](const Spike& s) { return std::abs(s.peak_height) < kImpactHeightFraction * largest; });
  return spikes;
}

}  // namespace

RecordAnalysis AnalyseRecord(const Recording& record, ResponseKind kind, const FitOptions& options) {
  ThrowIfInvalid(options);
  const std::string name = record.name.empty() ? "record" : record.name;
  if (record.broadband) throw InputError(name, "is broadband: only stepped-sine records are fitted");
  if (record.voltage_v.size() != record.response.size())
    throw InputError(name, "has " + std::to_string(record.voltage_v.size()) + " voltage samples but " +
                               std::to_string(record.response.size()) + " response samples");
  RecordAnalysis a;
  a.name = record.name;
  a.nominal_frequency_hz = record.nominal_frequency_hz;
  a.nominal_amplitude_v = record.nominal_amplitude_v;
  a.sample_rate_hz = record.sample_rate_hz;
  try {
    RequirePositiveFinite(record.sample_rate_hz, "sample_rate_hz");
    a.drive = EstimateDrive(record.voltage_v, record.sample_rate_hz, record.nominal_frequency_hz);
    const double fs = record.sample_rate_hz, f = a.drive.frequency_hz;
    const size_t n = record.size();
    // Whole periods of the estimated drive at the record's end (half a sample of slack).
    const double periods = std::floor((static_cast<double>(n) + 0.5) * f / fs);
    if (periods < 2.0) throw InputError("voltage", "holds less than two periods of the drive at " + Format(f) + " Hz");
    const size_t count = std::min(n, static_cast<size_t>(std::llround(periods * fs / f)));
    a.window = SampleWindow{n - count, n, periods};
    if (options.harmonic_orders * f >= 0.5 * fs)
      throw InputError("harmonic_orders", "harmonic " + std::to_string(options.harmonic_orders) + " of " + Format(f) +
                                              " Hz is not below the Nyquist frequency " + Format(0.5 * fs) + " Hz");
    const std::vector<double> cleaned = FitResponse(record, options, &a);
    a.usable = UsableHarmonics(fs, a, options);
    a.frf = Complex(0.0, 1.0) * a.harmonics[0] / a.drive.amplitude_v;  // C_1(v) = V e^{j(phi - pi/2)}
    double higher = 0.0;
    for (size_t h = 1; h < a.harmonics.size(); ++h) higher += std::norm(a.harmonics[h]);
    const double noise_share = 2.0 * a.harmonic_se * a.harmonic_se * static_cast<double>(a.harmonics.size() - 1);
    a.distortion = std::sqrt(std::max(0.0, higher - noise_share)) / std::abs(a.harmonics[0]);
    a.spikes = ImpactSpikes(DetectSpikes(SpikeSignal(cleaned, kind, fs), fs, f, a.window, options.spikes));
    a.clear = a.spikes.empty() && a.distortion < options.max_clear_distortion;
  } catch (const InputError& e) {
    RethrowForRecord(e, name);
  }
  if (!(std::abs(a.harmonics[0]) > 0.0) || !std::isfinite(a.distortion))
    throw InputError(name, "has no response at the drive frequency");
  return a;
}

// ---- Step 2 ----------------------------------------------------------------------------------------

std::complex<double> EquivalentForceFrf(std::complex<double> frf, ResponseKind kind, double frequency_hz,
                                        double mass_kg) {
  const double w = kTwoPi * frequency_hz;
  switch (kind) {
    case ResponseKind::kForce:
      return frf;
    case ResponseKind::kAcceleration:
      return mass_kg * frf;
    case ResponseKind::kVelocity:
      return mass_kg * Complex(0.0, w) * frf;
    case ResponseKind::kDisplacement:
      return -mass_kg * w * w * frf;
  }
  return frf;
}

LinearStage FitClearRecords(std::span<const RecordAnalysis> analyses, ResponseKind kind, const FitOptions& options) {
  ThrowIfInvalid(options);
  LinearStage stage;
  std::vector<FrfSample> samples;
  size_t spiky = 0;
  for (size_t i = 0; i < analyses.size(); ++i) {
    const RecordAnalysis& a = analyses[i];
    if (!a.spikes.empty()) ++spiky;
    if (!a.clear) continue;
    stage.records.push_back(i);
    samples.push_back({a.drive.frequency_hz, EquivalentForceFrf(a.frf, kind, a.drive.frequency_hz, options.mass_kg)});
  }
  if (stage.records.size() < kMinClearRecords) {
    throw InputError("records", std::to_string(stage.records.size()) + " of " + std::to_string(analyses.size()) +
                                    " records stay clear of the stop (" + std::to_string(spiky) +
                                    " show impact spikes, the others harmonic distortion above " +
                                    Format(100 * options.max_clear_distortion) +
                                    " %): the linear fit (paper Eq. 3) needs at least 3 clear records");
  }
  FrfFitOptions frf_options;
  frf_options.mass_kg = options.mass_kg;
  stage.summary = FitLinearFrf(samples, frf_options);
  return stage;
}

// ---- Step 3 ----------------------------------------------------------------------------------------

ContactEstimate EstimateContact(std::span<const RecordAnalysis> analyses, ResponseKind kind,
                                const FrfFitSummary& linear, const FitOptions& options) {
  (void)kind;
  ContactEstimate e;
  const double m = options.mass_kg, k = linear.stiffness_n_per_m, c = linear.damping_n_s_per_m;
  const double g = linear.gain_n_per_v;
  std::vector<double> times, stiffness;
  double polarity = 0.0;
  // Which records bound |d|: those with impact spikes hit the stop, those without do not (a record
  // distorted but without spikes, e.g. by a hardening suspension, stays clear of the stop). When no
  // record shows spikes at all, clear against not clear.
  const bool any_spikes =
      std::any_of(analyses.begin(), analyses.end(), [](const RecordAnalysis& a) { return !a.spikes.empty(); });
  auto hits_stop = [&](const RecordAnalysis& a) { return any_spikes ? !a.spikes.empty() : !a.clear; };
  double largest_clear = kNaN, smallest_contacting = kNaN;
  std::vector<double> contacting_amplitudes;
  for (size_t i = 0; i < analyses.size(); ++i) {
    const RecordAnalysis& a = analyses[i];
    const double w = kTwoPi * a.drive.frequency_hz;
    const double amplitude = std::abs(g) * a.drive.amplitude_v / std::abs(Complex(k - m * w * w, c * w));
    if (hits_stop(a)) {
      contacting_amplitudes.push_back(amplitude);
    } else if (!(amplitude <= largest_clear)) {
      largest_clear = amplitude;
    }
    if (a.clear) continue;
    e.records.push_back(i);
    for (const Spike& s : a.spikes) {
      try {
        stiffness.push_back(ContactStiffnessDamped(m, s.ContactTimeS(), k, c));
        times.push_back(s.ContactTimeS());
        polarity += s.peak_height > 0 ? 1.0 : -1.0;
      } catch (const InputError&) {
        // a spike too wide for any stop stiffness: not an impact of this model
      }
    }
  }
  // The smallest contacting amplitude above the clear ones: below it the record may sit on the
  // contacting branch of a bistable response, which bounds nothing.
  for (double amplitude : contacting_amplitudes)
    if ((std::isnan(largest_clear) || amplitude > largest_clear) && !(amplitude >= smallest_contacting))
      smallest_contacting = amplitude;
  e.largest_clear_amplitude_m = largest_clear;
  e.smallest_contacting_amplitude_m = smallest_contacting;
  e.spikes = stiffness.size();
  const ContactTimeStatistics stats = ContactTimeStats(times);
  e.contact_time_s = stats.mean_s;
  e.contact_time_rsd = stats.rsd;
  if (stiffness.empty()) {
    e.stiffness_n_per_m = e.stiffness_spread_n_per_m = kNaN;
  } else {
    e.stiffness_n_per_m =
        std::accumulate(stiffness.begin(), stiffness.end(), 0.0) / static_cast<double>(stiffness.size());
    double ss = 0.0;
    for (double s : stiffness) ss += (s - e.stiffness_n_per_m) * (s - e.stiffness_n_per_m);
    e.stiffness_spread_n_per_m =
        stiffness.size() > 1 ? std::sqrt(ss / static_cast<double>(stiffness.size() - 1)) : kNaN;
  }
  // A lower stop pushes the mass up: positive spikes of m_p x'' (negative when the gain, i.e. the
  // sensor's polarity, is negative).
  e.lower_stop = polarity * (g < 0 ? -1.0 : 1.0) >= 0.0;
  if (e.records.empty()) {
    e.stop_distance_m = kNaN;
  } else if (std::isnan(largest_clear)) {
    e.stop_distance_m = smallest_contacting;
  } else if (std::isnan(smallest_contacting)) {
    e.stop_distance_m = kBracketMargin * largest_clear;
  } else {
    e.stop_distance_m = std::sqrt(largest_clear * smallest_contacting);  // the bracket's geometric middle
  }
  return e;
}

// ---- Step 4 ----------------------------------------------------------------------------------------

void RefineParameters(std::span<const RecordAnalysis> analyses, ResponseKind kind, const ActuatorModel& start,
                      const std::vector<size_t>& used, const FitOptions& options, FitResult* result) {
  ThrowIfInvalid(options);
  const auto clock_start = std::chrono::steady_clock::now();
  const int orders = options.harmonic_orders;
  const ParameterLayout layout = MakeLayout(start, options.fit_contact_damping);
  const int p = layout.size();
  std::vector<double> theta(p, 1.0);

  // Anchors at the start: the stable orbit matching each record best.
  std::vector<RecordTarget> all(analyses.size());
  std::vector<RecordFit>& fits = result->records;
  fits.assign(analyses.size(), RecordFit{});
  const ActuatorModel start_model = layout.Decode(theta.data());
  for (size_t i = 0; i < analyses.size(); ++i) {
    const RecordAnalysis& a = analyses[i];
    all[i].record = &a;
    all[i].weight = 1.0 / a.harmonic_se;
    const std::optional<ModelOrbit> orbit = BestMatchingOrbit(start_model, a, kind, orders);
    if (!orbit) throw NumericalError("no steady state of the starting model at record " + a.name);
    all[i].anchor = orbit->anchor;
    fits[i].nrmse_initial = std::sqrt(MismatchSquared(a, orbit->harmonics) / PowerOf(a));
  }
  std::vector<RecordTarget> targets;
  for (size_t i : used) targets.push_back(all[i]);

  ceres::Problem problem;
  for (RecordTarget& t : targets)
    problem.AddResidualBlock(MakeCost(p, &layout, &t, kind, orders), nullptr, theta.data());
  // Bounds: a factor kParameterRange around the staged estimates (kContactRange for the contact's
  // parameters, which the staged estimate knows least). They keep a model that cannot fit the data
  // from wandering to values where an evaluation costs minutes (a stiff contact takes ever shorter
  // steps); an estimate on its bound is reported.
  for (int i = 0; i < p; ++i) {
    const double range = i >= kContactStiffness ? kContactRange : kParameterRange;
    problem.SetParameterLowerBound(theta.data(), i, 1.0 - std::log(range));
    problem.SetParameterUpperBound(theta.data(), i, 1.0 + std::log(range));
  }

  RefinementSummary& summary = result->refinement;
  summary.parameters = static_cast<size_t>(p);
  summary.residuals = 2 * static_cast<size_t>(orders) * targets.size();
  if (summary.residuals <= summary.parameters) throw InputError("records", "too few records to fit the parameters");

  // The sampling corrections at the current iterate; returns their largest change in standard errors.
  auto update_corrections = [&] {
    const ActuatorModel model = layout.Decode(theta.data());
    double change = 0.0;
    for (RecordTarget& t : targets) {
      std::vector<Complex> correction(orders, 0.0);
      try {
        if (const std::optional<ModelOrbit> orbit =
                SolveOrbit(model, *t.record, t.anchor, kind, orders, OrbitSearch::kAttractor)) {
          t.anchor = orbit->anchor;
          correction = SamplingCorrection(model, *t.record, *orbit, kind, orders);
        }
      } catch (const std::exception&) {
        // keep zero: the evaluation itself will fail and say so
      }
      for (int h = 0; h < orders; ++h)
        change = std::max(change,
                          t.weight * std::abs(correction[h] - (t.correction.empty() ? Complex(0.0) : t.correction[h])));
      t.correction = std::move(correction);
    }
    return change;
  };

  // Records whose best-matching stable orbit at the current iterate is another one than their anchor's
  // (a bistable record the start model put on the other branch: the contacting branch may not exist
  // at the start model) move to it; returns how many moved.
  auto reselect_branches = [&] {
    const ActuatorModel model = layout.Decode(theta.data());
    size_t moved = 0;
    for (RecordTarget& t : targets) {
      try {
        const std::optional<ModelOrbit> best = BestMatchingOrbit(model, *t.record, kind, orders);
        if (!best) continue;
        const std::optional<ModelOrbit> current =
            SolveOrbit(model, *t.record, t.anchor, kind, orders, OrbitSearch::kNearby);
        const double now = current ? MismatchSquared(*t.record, current->harmonics) : kInf;
        if (MismatchSquared(*t.record, best->harmonics) < kBranchSwitchRatio * now) {
          t.anchor = best->anchor;
          ++moved;
        }
      } catch (const std::exception&) {
        // keep the anchor
      }
    }
    return moved;
  };

  bool solved = true;
  update_corrections();
  if (options.refine) {
    // After each successful step every record's anchor moves to its orbit at the new iterate.
    AfterSuccessfulStep callback([&] {
      const ActuatorModel model = layout.Decode(theta.data());
      for (RecordTarget& t : targets) internal::MoveAnchor(model, *t.record, kind, orders, &t.anchor);
    });
    ceres::Solver::Options solver = internal::RefinementSolverOptions(options.max_iterations, &callback);
    const auto deadline = clock_start + std::chrono::duration<double>(options.max_refinement_seconds);
    // Outer passes: solve with the corrections frozen, recompute them at the solution, and solve
    // again while they moved by more than kCorrectionTolerance standard errors.
    summary.ran = true;
    for (int pass = 0; pass < kMaxCorrectionPasses; ++pass) {
      solver.max_solver_time_in_seconds =
          std::max(1.0, std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count());
      ceres::Solver::Summary ceres_summary;
      ceres::Solve(solver, &problem, &ceres_summary);
      if (pass == 0) summary.initial_cost = ceres_summary.initial_cost;
      summary.iterations += static_cast<int>(ceres_summary.iterations.size()) - 1;
      summary.final_cost = ceres_summary.final_cost;
      summary.report = ceres_summary.BriefReport();
      solved = ceres_summary.termination_type == ceres::CONVERGENCE;
      summary.correction_passes = pass + 1;
      const size_t switched = reselect_branches();
      summary.branch_switches += switched;
      const double change = update_corrections();
      if (!solved || (change < kCorrectionTolerance && switched == 0)) break;
    }
    if (!solved) {
      summary.report += "\nNOT CONVERGED: Ceres stopped without convergence";
      if (std::chrono::steady_clock::now() >= deadline)
        summary.report += " (time limit of " + Format(options.max_refinement_seconds) + " s)";
    }
    double cost = 0.0;  // at the final corrections
    problem.Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, nullptr);
    summary.final_cost = cost;
  } else {
    double cost = 0.0;
    problem.Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, nullptr);
    summary.initial_cost = summary.final_cost = cost;
    summary.report = "refinement not run: staged estimates, standard errors at them";
  }
  summary.residual_variance = 2.0 * summary.final_cost / static_cast<double>(summary.residuals - summary.parameters);

  // Covariance of theta: (J^T J)^-1 s^2, J with the corrections' own dependence on theta (it matters
  // for k_s, which the impacts' high harmonics carry: frozen corrections leave its standard error
  // about 30 % too small).
  for (RecordTarget& t : targets) t.live_correction = true;
  Eigen::MatrixXd covariance = Eigen::MatrixXd::Constant(p, p, kNaN);
  {
    ceres::Covariance::Options covariance_options;
    covariance_options.algorithm_type = ceres::DENSE_SVD;
    covariance_options.num_threads = 1;
    ceres::Covariance cov(covariance_options);
    const double* block = theta.data();
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> c(p, p);
    if (cov.Compute(std::vector<const double*>{block}, &problem) && cov.GetCovarianceBlock(block, block, c.data())) {
      covariance = summary.residual_variance * Eigen::MatrixXd(c);
    } else {
      solved = false;
      summary.report += "\nNOT CONVERGED: the Jacobian is rank deficient (parameters not all identifiable)";
    }
  }
  summary.converged = solved && covariance.allFinite();

  result->model = layout.Decode(theta.data());
  constexpr std::array<const char*, kMaxParameters> kNames = {"k_p", "c_p", "g", "d", "k_s", "c_s"};
  for (int i = 0; i < p; ++i) {
    const double range = std::log(i >= kContactStiffness ? kContactRange : kParameterRange);
    if (std::abs(theta[i] - 1.0) > 0.999 * range)
      result->warnings.push_back(std::string(kNames[i]) + " ended on its bound (a factor " + Format(std::exp(range)) +
                                 " from the staged estimate): the model does not fit these records");
  }
  result->parameters = ReportParameters(layout, theta, covariance, result->model_kind, kind, result->absolute_scale);

  // Every record at the fitted model, from its (updated) anchor, as its sampling sees it.
  for (size_t k = 0; k < used.size(); ++k) all[used[k]].anchor = targets[k].anchor;
  double mismatch_initial = 0.0, mismatch = 0.0, power = 0.0;
  for (size_t i = 0; i < analyses.size(); ++i) {
    const RecordAnalysis& a = analyses[i];
    RecordFit& f = fits[i];
    f.name = a.name;
    f.frequency_hz = a.drive.frequency_hz;
    f.amplitude_v = a.drive.amplitude_v;
    f.phase_rad = a.drive.phase_rad;
    f.nominal_frequency_hz = a.nominal_frequency_hz;
    f.nominal_amplitude_v = a.nominal_amplitude_v;
    f.clear = a.clear;
    f.spikes = a.spikes.size();
    double total = 0.0;
    for (const Spike& s : a.spikes) total += s.ContactTimeS();
    f.contact_time_s = a.spikes.empty() ? kNaN : total / static_cast<double>(a.spikes.size());
    f.distortion = a.distortion;
    f.noise_rms = a.noise_rms;
    f.hum_frequency_hz = a.hum_frequency_hz;
    f.hum_amplitude = a.hum_amplitude;
    f.frf = a.frf;
    f.used_refinement = std::find(used.begin(), used.end(), i) != used.end();
    std::optional<ModelOrbit> orbit;
    try {
      orbit = SolveOrbit(result->model, a, all[i].anchor, kind, orders, OrbitSearch::kAttractor);
    } catch (const NumericalError&) {
    }
    if (!orbit) {
      f.nrmse = f.chi2 = kNaN;
      result->warnings.push_back("record " + a.name + ": no steady state of the fitted model");
      continue;
    }
    std::vector<Complex> model_harmonics = orbit->harmonics;
    try {
      const std::vector<Complex> correction = SamplingCorrection(result->model, a, *orbit, kind, orders);
      for (int h = 0; h < orders; ++h) model_harmonics[h] += correction[h];
    } catch (const std::exception&) {
    }
    const double power_i = PowerOf(a), mismatch_i = MismatchSquared(a, model_harmonics);
    f.nrmse = std::sqrt(mismatch_i / power_i);
    f.chi2 = mismatch_i / (a.harmonic_se * a.harmonic_se) / (2.0 * orders);
    f.model_period = orbit->anchor.period;
    f.model_contacts_per_period = orbit->contacts_per_period;
    f.model_harmonics = std::move(model_harmonics);
    mismatch += mismatch_i;
    mismatch_initial += f.nrmse_initial * f.nrmse_initial * power_i;
    power += power_i;
  }
  result->nrmse = std::sqrt(mismatch / power);
  result->nrmse_initial = std::sqrt(mismatch_initial / power);
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
}

// ---- The pipeline ----------------------------------------------------------------------------------

std::vector<RecordAnalysis> AnalyseCampaign(const Campaign& campaign, const FitOptions& options,
                                            std::vector<std::string>* warnings) {
  ThrowIfInvalid(options);
  if (campaign.records.empty()) throw InputError("records", "the campaign holds no records");
  std::vector<const Recording*> stepped;
  for (const Recording& record : campaign.records) {
    if (!record.broadband) {
      stepped.push_back(&record);
    } else if (warnings != nullptr) {
      warnings->push_back("record " + record.name + " is broadband: not used (stepped-sine records only)");
    }
  }
  if (stepped.empty())
    throw InputError("records", "the campaign holds no stepped-sine record (broadband records are not fitted)");
  // Records are independent: analysed side by side, the first error (in campaign order) re-thrown.
  std::vector<RecordAnalysis> analyses(stepped.size());
  ParallelFor(stepped.size(), [&](size_t i) { analyses[i] = AnalyseRecord(*stepped[i], campaign.response, options); });
  for (const RecordAnalysis& a : analyses) {
    const double drift = a.drive.frequency_hz / a.nominal_frequency_hz - 1.0;
    if (std::abs(drift) > 1e-3 && warnings != nullptr)
      warnings->push_back("record " + a.name + ": the drive is at " + Format(a.drive.frequency_hz) +
                          " Hz, the manifest says " + Format(a.nominal_frequency_hz) + " Hz");
  }
  return analyses;
}

FitResult FitCampaign(const Campaign& campaign, const FitOptions& options) {
  const auto clock_start = std::chrono::steady_clock::now();
  std::vector<std::string> warnings;
  const std::vector<RecordAnalysis> analyses = AnalyseCampaign(campaign, options, &warnings);
  FitResult result = FitAnalysed(analyses, campaign.response, campaign.absolute_scale, options);
  result.warnings.insert(result.warnings.begin(), warnings.begin(), warnings.end());
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return result;
}

FitResult FitAnalysed(std::span<const RecordAnalysis> analyses, ResponseKind response, bool absolute_scale,
                      const FitOptions& options) {
  ThrowIfInvalid(options);
  const auto clock_start = std::chrono::steady_clock::now();
  if (analyses.empty()) throw InputError("records", "no stepped-sine record to fit");
  FitResult result;
  result.model_kind = options.model;
  result.response = response;
  result.absolute_scale = absolute_scale;
  result.mass_kg = options.mass_kg;
  // Step 2.
  result.linear = FitClearRecords(analyses, response, options);
  const FrfFitSummary& linear = result.linear.summary;
  if (!linear.converged) {
    if (!(linear.stiffness_n_per_m > 0) || !(linear.damping_n_s_per_m > 0) || linear.gain_n_per_v == 0)
      throw NumericalError("the linear fit (paper Eq. 3) of the clear records failed: " + linear.report);
    result.warnings.push_back("the linear fit (paper Eq. 3) did not converge: " + linear.report);
  }

  ActuatorModel start = PaperModel();
  start.mass_kg = options.mass_kg;
  start.stiffness_n_per_m = linear.stiffness_n_per_m;
  start.damping_n_s_per_m = linear.damping_n_s_per_m;
  start.gain_n_per_v = linear.gain_n_per_v;
  start.lower_stop_m = ActuatorModel::kNoLowerStop;
  start.contact_damping_n_s_per_m = 0.0;

  // Step 3.
  result.contact = EstimateContact(analyses, response, linear, options);
  const ContactEstimate& contact = result.contact;
  std::vector<size_t> used;
  if (options.model == FitModelKind::kLinear) {
    used = result.linear.records;
    if (!contact.records.empty())
      result.warnings.push_back(std::to_string(contact.records.size()) +
                                " records are not clear of the stop: the linear model leaves them out of the fit");
  } else if (contact.records.empty()) {
    used = result.linear.records;
    result.warnings.push_back("no record reaches the stop: d and k_s are not identifiable (|d| > " +
                              Format(contact.largest_clear_amplitude_m) + " m, the largest displacement amplitude)");
  } else {
    for (size_t i = 0; i < analyses.size(); ++i) used.push_back(i);
    if (contact.lower_stop)
      start.lower_stop_m = -contact.stop_distance_m;
    else
      start.upper_stop_m = contact.stop_distance_m;
    if (contact.spikes > 0) {
      start.contact_stiffness = contact.stiffness_n_per_m;
    } else {
      start.contact_stiffness = kTable2ContactStiffness;
      result.warnings.push_back("no impact spike gave a contact time: k_s starts from paper Table 2 (" +
                                Format(kTable2ContactStiffness) + " N/m)");
    }
    if (!contact.lower_stop) result.warnings.push_back("impact spikes are negative: the stop is on the upper side");
  }
  // Step 4.
  RefineParameters(analyses, response, start, used, options, &result);
  for (size_t i : result.linear.records) result.records[i].used_linear = true;
  for (size_t i : contact.records) result.records[i].used_contact = result.records[i].spikes > 0;
  const bool stop = result.model.HasLowerStop() || result.model.HasUpperStop();
  result.identifiability = Identifiability(options.model, response, absolute_scale, stop);
  if (!result.refinement.converged)
    result.warnings.push_back("the refinement did not converge: " + result.refinement.report);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - clock_start).count();
  return result;
}

const FitParameter* FitResult::Find(std::string_view name) const {
  for (const FitParameter& p : parameters)
    if (p.name == name) return &p;
  return nullptr;
}

nlohmann::json FitResultToJson(const FitResult& r) {
  using nlohmann::json;
  json parameters = json::object();
  for (const FitParameter& p : r.parameters) {
    parameters[p.name] = {{"value", Number(p.value)},
                          {"standard_error", Number(p.standard_error)},
                          {"unit", p.unit},
                          {"fixed", p.fixed},
                          {"identifiable", p.identifiable},
                          {"note", p.note}};
  }
  const FrfFitSummary& l = r.linear.summary;
  json linear = {{"records", r.linear.records.size()},
                 {"natural_frequency_rad_s", Number(l.natural_frequency_rad_s)},
                 {"natural_frequency_se", Number(l.natural_frequency_se)},
                 {"damping_ratio", Number(l.damping_ratio)},
                 {"damping_ratio_se", Number(l.damping_ratio_se)},
                 {"gain_n_per_v", Number(l.gain_n_per_v)},
                 {"gain_se", Number(l.gain_se)},
                 {"stiffness_n_per_m", Number(l.stiffness_n_per_m)},
                 {"stiffness_se", Number(l.stiffness_se)},
                 {"damping_n_s_per_m", Number(l.damping_n_s_per_m)},
                 {"damping_se", Number(l.damping_se)},
                 {"rms_residual", Number(l.rms_residual)},
                 {"converged", l.converged}};
  const ContactEstimate& c = r.contact;
  json contact = {{"records", c.records.size()},
                  {"spikes", c.spikes},
                  {"contact_time_s", Number(c.contact_time_s)},
                  {"contact_time_rsd", Number(c.contact_time_rsd)},
                  {"stiffness_n_per_m", Number(c.stiffness_n_per_m)},
                  {"stiffness_spread_n_per_m", Number(c.stiffness_spread_n_per_m)},
                  {"stop", c.lower_stop ? "lower" : "upper"},
                  {"largest_clear_amplitude_m", Number(c.largest_clear_amplitude_m)},
                  {"smallest_contacting_amplitude_m", Number(c.smallest_contacting_amplitude_m)},
                  {"stop_distance_m", Number(c.stop_distance_m)}};
  const RefinementSummary& f = r.refinement;
  json refinement = {{"ran", f.ran},
                     {"converged", f.converged},
                     {"iterations", f.iterations},
                     {"correction_passes", f.correction_passes},
                     {"branch_switches", f.branch_switches},
                     {"initial_cost", Number(f.initial_cost)},
                     {"final_cost", Number(f.final_cost)},
                     {"residuals", f.residuals},
                     {"parameters", f.parameters},
                     {"residual_variance", Number(f.residual_variance)},
                     {"seconds", Number(f.seconds)},
                     {"report", f.report}};
  json records = json::array();
  for (const RecordFit& x : r.records) {
    json used = json::array();
    if (x.used_linear) used.push_back("linear");
    if (x.used_contact) used.push_back("contact_time");
    if (x.used_refinement) used.push_back("refinement");
    records.push_back({{"name", x.name},
                       {"frequency_hz", Number(x.frequency_hz)},
                       {"amplitude_v", Number(x.amplitude_v)},
                       {"phase_rad", Number(x.phase_rad)},
                       {"nominal_frequency_hz", Number(x.nominal_frequency_hz)},
                       {"nominal_amplitude_v", Number(x.nominal_amplitude_v)},
                       {"clear", x.clear},
                       {"spikes", x.spikes},
                       {"contact_time_s", Number(x.contact_time_s)},
                       {"distortion", Number(x.distortion)},
                       {"noise_rms", Number(x.noise_rms)},
                       {"hum_frequency_hz", Number(x.hum_frequency_hz)},
                       {"hum_amplitude", Number(x.hum_amplitude)},
                       {"frf", ComplexJson(x.frf)},
                       {"used_for", used},
                       {"nrmse_initial", Number(x.nrmse_initial)},
                       {"nrmse", Number(x.nrmse)},
                       {"chi2", Number(x.chi2)},
                       {"model_period", x.model_period},
                       {"model_contacts_per_period", Number(x.model_contacts_per_period)}});
  }
  return {{"model", ToString(r.model_kind)},
          {"response", ToString(r.response)},
          {"absolute_scale", r.absolute_scale},
          {"mass_kg", Number(r.mass_kg)},
          {"identifiability", r.identifiability},
          {"parameters", parameters},
          {"fitted_model", ModelToJson(r.model)},
          {"stages", {{"linear", linear}, {"contact", contact}, {"refinement", refinement}}},
          {"records", records},
          {"nrmse_initial", Number(r.nrmse_initial)},
          {"nrmse", Number(r.nrmse)},
          {"warnings", r.warnings},
          {"seconds", Number(r.seconds)}};
}

}  // namespace strokelab
