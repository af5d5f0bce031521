// strokelab paper: regenerates the paper's simulated figures as data (CSV) and pictures (SVG), and a
// short text summary of what it found, from the Table 2 model (or any model given with --model/--set).
//
//   Fig. 2/9   time histories at 16 pi and 26 pi rad/s (8 and 13 Hz) for 0.3, 0.4, 0.5 V
//   Fig. 3     Hann spectra of (8 Hz, 0.3 V) and (13 Hz, 0.5 V)
//   Fig. 6     restoring force against displacement (paper Eq. 2, continuous form)
//   Fig. 7     k_s against contact time (paper Eq. 5 and the damped relation)
//   Fig. 10/5  first-order FRFs H and H_p for 0.1 .. 0.6 V on the Eq. 1 grid, stepped-sine up-sweep
//   onset      saturation onset per frequency: closed-form grazing V_sat and, from rest, by bisection
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <numbers>
#include <sstream>

#include "commands.h"
#include "strokelab/report/csv_table.h"
#include "strokelab/engines/engine.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/parallel_for.h"
#include "strokelab/model/linear_response.h"
#include "strokelab/engines/record_summary.h"
#include "strokelab/signal/signal.h"
#include "strokelab/plot/svg_plot.h"

namespace strokelab::cli {

using report::CsvTable;
namespace {

constexpr const char* kPaperHelp = R"(usage: strokelab paper --out DIR [options]

  --out DIR              folder for the figures (SVG), tables (CSV) and summary.txt   (required)
  --model NAME|FILE      preset or JSON model file                                    [paper]
  --set KEY=VALUE        override a model parameter (repeatable)
  --method M             auto | exact | cvode | ode3 for the time histories           [auto]
  --step-duration-s T    length of each stepped-sine step [s]                          [10]
  --threads N            threads for the FRF sweeps                                    [2]
)";

constexpr double kSampleRateHz = 51200.0;  // paper section 3
const std::vector<double> kFigure2AmplitudesV = {0.3, 0.4, 0.5};
const std::vector<double> kFigure2FrequenciesHz = {8.0, 13.0};  // 16 pi and 26 pi rad/s
const std::vector<double> kFrfAmplitudesV = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6};

struct Study {
  ActuatorModel model;
  MethodChoice method;  // of the time histories and spectra
  double step_duration_s = 10.0;
  int threads = 2;
  std::filesystem::path out;
  std::ostringstream summary;
};

void WriteFile(const std::filesystem::path& path, const std::string& text) {
  std::ofstream file(path);
  file << text;
  if (!file) throw std::runtime_error("cannot write " + path.string());
}

plot::Series Line(std::string label, std::vector<double> x, std::vector<double> y) {
  plot::Series series;
  series.label = std::move(label);
  series.x = std::move(x);
  series.y = std::move(y);
  return series;
}

std::string FormatHz(double f) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%g", f);
  return buffer;
}

// Fig. 2/9: the last 0.4 s of each 10 s record, from rest.
void TimeHistories(Study& study) {
  const auto engine = MakeEngine(study.method.method);
  SimulationOptions options;
  options.duration_s = study.step_duration_s;
  options.sample_rate_hz = kSampleRateHz;
  study.summary << "Time histories (Fig. 2/9), " << study.method.Describe() << ", 10 s from rest, last second:\n";
  for (double f_hz : kFigure2FrequenciesHz) {
    CsvTable table({"time_s"});
    std::vector<plot::Series> series;
    for (double amplitude_v : kFigure2AmplitudesV) {
      const SineDrive drive{amplitude_v, f_hz, 0.0};
      const Record record = engine->Simulate(study.model, drive, options);
      const RecordSummary s = Summarize(record, drive);
      char line[256];
      std::snprintf(line, sizeof line,
                    "  %5.2f Hz %.1f V: %3zu contacts, min x %.4f mm, peak force %.3f N, |F1| %.5f N, "
                    "contact time %s ms\n",
                    f_hz, amplitude_v, s.contacts, s.min_displacement_m * 1e3, s.peak_force_n,
                    s.first_harmonic_force_n,
                    std::isnan(s.mean_contact_ms) ? "-" : std::to_string(s.mean_contact_ms).substr(0, 6).c_str());
      study.summary << line;
      const size_t shown = static_cast<size_t>(0.4 * kSampleRateHz);
      const size_t begin = record.size() - shown;
      plot::Series line_series = Line(FormatHz(amplitude_v) + " V", {}, {});
      std::vector<double> column;
      for (size_t n = begin; n < record.size(); ++n) {
        line_series.x.push_back(record.TimeS(n));
        line_series.y.push_back(record.force_n[n]);
      }
      if (table.rows() == 0) table.SetColumn("time_s", line_series.x);
      table.AddColumn("force_n_" + FormatHz(amplitude_v) + "V", line_series.y);
      series.push_back(std::move(line_series));
    }
    const std::string stem = "fig2_time_history_" + FormatHz(f_hz) + "hz";
    table.Write(study.out / (stem + ".csv"));
    plot::Axes axes;
    axes.title = "Blocked force at " + FormatHz(f_hz) + " Hz (" + FormatHz(2 * f_hz) + " pi rad/s), simulated";
    axes.x_label = "time [s]";
    axes.y_label = "force f = m_p x'' [N]";
    WriteFile(study.out / (stem + ".svg"), plot::LinePlot(series, axes));
  }
}

// Fig. 3: Hann spectra of the last second, (8 Hz, 0.3 V) and (13 Hz, 0.5 V).
void Spectra(Study& study) {
  const auto engine = MakeEngine(study.method.method);
  SimulationOptions options;
  options.duration_s = study.step_duration_s;
  options.sample_rate_hz = kSampleRateHz;
  const std::vector<std::pair<double, double>> cases = {{8.0, 0.3}, {13.0, 0.5}};
  const char* labels[] = {"a", "b"};
  for (size_t i = 0; i < cases.size(); ++i) {
    const SineDrive drive{cases[i].second, cases[i].first, 0.0};
    const Record record = engine->Simulate(study.model, drive, options);
    const size_t n_last = static_cast<size_t>(kSampleRateHz);
    const std::span<const double> last(record.force_n.data() + record.size() - n_last, n_last);
    const Spectrum spectrum = HannSpectrum(last, kSampleRateHz);
    plot::Series s = Line("", {}, {});
    CsvTable table({"frequency_hz", "amplitude_n"});
    for (size_t k = 1; k < spectrum.frequency_hz.size() && spectrum.frequency_hz[k] <= 1000.0; ++k) {
      s.x.push_back(spectrum.frequency_hz[k]);
      s.y.push_back(spectrum.amplitude[k]);
    }
    table.SetColumn("frequency_hz", s.x);
    table.SetColumn("amplitude_n", s.y);
    const std::string stem = std::string("fig3") + labels[i] + "_spectrum";
    table.Write(study.out / (stem + ".csv"));
    plot::Axes axes;
    axes.title = "Force spectrum (Hann), " + FormatHz(drive.frequency_hz) + " Hz, " + FormatHz(drive.amplitude_v) + " V";
    axes.x_label = "frequency [Hz]";
    axes.y_label = "amplitude [N]";
    axes.log_y = true;
    axes.y_min = 1e-7;
    WriteFile(study.out / (stem + ".svg"), plot::LinePlot({s}, axes));
  }
}

// Fig. 6: the restoring force k_p x + k_s (x - d) below d (continuous form of Eq. 2, model.h).
void RestoringForce(Study& study) {
  const ActuatorModel& m = study.model;
  plot::Series s = Line("restoring force", {}, {});
  const double span_m = 2e-3;
  for (int i = 0; i <= 400; ++i) {
    const double x = -span_m + 2 * span_m * i / 400.0;
    // Static restoring force at zero velocity: minus the blocked force with no drive.
    const ContactMode mode = ModeFromState(m, x, 0.0);
    s.x.push_back(x * 1e3);
    s.y.push_back(-BlockedForce(m, 0.0, State{x, 0.0}, mode));
  }
  CsvTable table({"displacement_mm", "restoring_force_n"});
  table.SetColumn("displacement_mm", s.x);
  table.SetColumn("restoring_force_n", s.y);
  table.Write(study.out / "fig6_restoring_force.csv");
  plot::Axes axes;
  axes.title = "Restoring force (suspension + end stop)";
  axes.x_label = "displacement x [mm]";
  axes.y_label = "force [N]";
  WriteFile(study.out / "fig6_restoring_force.svg", plot::LinePlot({s}, axes));
}

// Fig. 7: k_s against contact time, paper Eq. 5 and the exact damped relation.
void ContactStiffness(Study& study) {
  const ActuatorModel& m = study.model;
  plot::Series eq5 = Line("paper Eq. 5: m_p (pi/dT)^2", {}, {});
  plot::Series damped = Line("damped contact, exact", {}, {});
  damped.dashed = true;
  for (int i = 0; i <= 200; ++i) {
    const double dt_s = (0.2 + 0.8 * i / 200.0) * 1e-3;
    eq5.x.push_back(dt_s * 1e3);
    eq5.y.push_back(ContactStiffnessEq5(m.mass_kg, dt_s));
    damped.x.push_back(dt_s * 1e3);
    damped.y.push_back(ContactStiffnessDamped(m.mass_kg, dt_s, m.stiffness_n_per_m,
                                              m.damping_n_s_per_m + m.contact_damping_n_s_per_m));
  }
  CsvTable table({"contact_time_ms", "k_s_eq5_n_per_m", "k_s_damped_n_per_m"});
  table.SetColumn("contact_time_ms", eq5.x);
  table.SetColumn("k_s_eq5_n_per_m", eq5.y);
  table.SetColumn("k_s_damped_n_per_m", damped.y);
  table.Write(study.out / "fig7_contact_stiffness.csv");
  plot::Axes axes;
  axes.title = "End-stop stiffness from contact time";
  axes.x_label = "contact time dT [ms]";
  axes.y_label = "k_s [N/m]";
  axes.log_y = true;
  WriteFile(study.out / "fig7_contact_stiffness.svg", plot::LinePlot({eq5, damped}, axes));
}

struct SweepPoint {
  std::complex<double> h;  // first-order FRF [N/V]
  size_t contacts = 0;     // in the last second
  double mean_contact_ms = NAN;
};

// A stepped-sine up-sweep at one amplitude, the state carried from step to step as on the rig.
std::vector<SweepPoint> UpSweep(const Study& study, double amplitude_v, const std::vector<double>& grid_hz) {
  const auto engine = MakeEngine(ChooseMethod("auto", study.model).method);
  SimulationOptions options;
  options.duration_s = study.step_duration_s;
  options.sample_rate_hz = kSampleRateHz;
  options.record_velocity = false;
  std::vector<SweepPoint> points;
  Record record;
  for (double f_hz : grid_hz) {
    const SineDrive drive{amplitude_v, f_hz, 0.0};
    engine->Simulate(study.model, drive, options, &record);
    options.initial = record.final_state;
    const RecordSummary s = Summarize(record, drive);
    // |H| = |C1(f)| / V and arg H is the summary's phase (relative to the drive).
    points.push_back({std::polar(s.first_harmonic_force_n / amplitude_v, s.first_harmonic_phase_rad), s.contacts,
                      s.mean_contact_ms});
  }
  return points;
}

// Fig. 10 (H) and Fig. 5 (H_p = -H / (m_p w^2)) for 0.1 .. 0.6 V on the Eq. 1 grid.
void FrequencyResponses(Study& study) {
  const std::vector<double> grid_hz = PaperFrequencyGridHz();
  std::vector<std::vector<SweepPoint>> results(kFrfAmplitudesV.size());
  // Amplitudes are independent sweeps.
  ParallelFor(kFrfAmplitudesV.size(), [&](size_t i) { results[i] = UpSweep(study, kFrfAmplitudesV[i], grid_hz); },
              static_cast<size_t>(study.threads));

  CsvTable table({"frequency_hz"});
  table.SetColumn("frequency_hz", grid_hz);
  std::vector<plot::Series> magnitude, displacement, phase;
  for (size_t a = 0; a < kFrfAmplitudesV.size(); ++a) {
    const std::string label = FormatHz(kFrfAmplitudesV[a]) + " V";
    plot::Series mag = Line(label, grid_hz, {}), disp = Line(label, grid_hz, {}), ph = Line(label, grid_hz, {});
    std::vector<double> re, im, contacts;
    for (size_t i = 0; i < grid_hz.size(); ++i) {
      const std::complex<double> h = results[a][i].h;
      const double w = 2 * std::numbers::pi * grid_hz[i];
      mag.y.push_back(std::abs(h));
      ph.y.push_back(std::arg(h));  // rad, as every phase strokelab writes
      disp.y.push_back(std::abs(h) / (study.model.mass_kg * w * w) * 1e3);
      re.push_back(h.real());
      im.push_back(h.imag());
      contacts.push_back(static_cast<double>(results[a][i].contacts));
    }
    const std::string suffix = "_" + FormatHz(kFrfAmplitudesV[a]) + "V";
    table.AddColumn("h_re_n_per_v" + suffix, re);
    table.AddColumn("h_im_n_per_v" + suffix, im);
    table.AddColumn("contacts_last_second" + suffix, contacts);
    magnitude.push_back(mag);
    displacement.push_back(disp);
    phase.push_back(ph);
  }
  table.Write(study.out / "fig10_frf.csv");
  plot::Axes axes;
  axes.x_label = "frequency [Hz]";
  axes.log_x = true;
  axes.title = "First-order force-voltage FRF |H| (Fig. 10), stepped-sine up-sweep";
  axes.y_label = "|H| [N/V]";
  WriteFile(study.out / "fig10_frf_magnitude.svg", plot::LinePlot(magnitude, axes));
  axes.title = "First-order FRF phase (Fig. 4b), stepped-sine up-sweep";
  axes.y_label = "arg H [rad]";
  WriteFile(study.out / "fig4b_frf_phase.svg", plot::LinePlot(phase, axes));
  axes.title = "First-order displacement-voltage FRF |H_p| (Fig. 5)";
  axes.y_label = "|H_p| [mm/V]";
  WriteFile(study.out / "fig5_displacement_frf.svg", plot::LinePlot(displacement, axes));

  study.summary << "\nStepped-sine up-sweep FRFs (Fig. 10) on the Eq. 1 grid, 117 steps of "
                << study.step_duration_s << " s:\n";
  for (size_t a = 0; a < kFrfAmplitudesV.size(); ++a) {
    size_t peak = 0, first_contact = grid_hz.size();
    for (size_t i = 0; i < grid_hz.size(); ++i) {
      if (std::abs(results[a][i].h) > std::abs(results[a][peak].h)) peak = i;
      if (results[a][i].contacts > 0 && first_contact == grid_hz.size()) first_contact = i;
    }
    char line[256];
    std::snprintf(line, sizeof line, "  %.1f V: |H| peaks at %.2f Hz (%.4f N/V); %s\n", kFrfAmplitudesV[a],
                  grid_hz[peak], std::abs(results[a][peak].h),
                  first_contact == grid_hz.size()
                      ? "never reaches the stop"
                      : ("reaches the stop from " + FormatHz(std::round(grid_hz[first_contact] * 100) / 100) + " Hz")
                            .c_str());
    study.summary << line;
  }
}

// Whether a record started from rest touches the stop in its last second.
bool ContactsFromRest(const Engine& engine, const ActuatorModel& model, double f_hz, double amplitude_v,
                      double duration_s) {
  SimulationOptions options;
  options.duration_s = duration_s;
  options.sample_rate_hz = kSampleRateHz;
  options.record_velocity = false;
  const SineDrive drive{amplitude_v, f_hz, 0.0};
  return Summarize(engine.Simulate(model, drive, options), drive).contacts > 0;
}

// Saturation onset per frequency: the closed-form grazing amplitude V_sat (linear_response.h) and
// the lowest amplitude at which a record from rest touches the stop, by bisection to 1e-4 V.
void SaturationOnset(Study& study) {
  if (!study.model.HasLowerStop()) return;
  const auto engine = MakeEngine(ChooseMethod("auto", study.model).method);
  const std::vector<double> grid_hz = PaperFrequencyGridHz();
  std::vector<double> closed_form, from_rest(grid_hz.size(), NAN);
  for (double f : grid_hz) closed_form.push_back(LinearSaturationThresholdV(study.model, 2 * std::numbers::pi * f));
  auto bisect = [&](size_t i) -> double {
    // The record from rest touches at V_sat (the steady state grazes there); search below it.
    double lo = 0.5 * closed_form[i], hi = closed_form[i] * 1.0001;
    if (!ContactsFromRest(*engine, study.model, grid_hz[i], hi, study.step_duration_s)) return NAN;
    if (ContactsFromRest(*engine, study.model, grid_hz[i], lo, study.step_duration_s)) return lo;
    while (hi - lo > 1e-4) {
      const double mid = 0.5 * (lo + hi);
      (ContactsFromRest(*engine, study.model, grid_hz[i], mid, study.step_duration_s) ? hi : lo) = mid;
    }
    return hi;
  };
  ParallelFor(grid_hz.size(), [&](size_t i) { from_rest[i] = bisect(i); }, static_cast<size_t>(study.threads));

  CsvTable table({"frequency_hz", "grazing_amplitude_v", "from_rest_contact_amplitude_v"});
  table.SetColumn("frequency_hz", grid_hz);
  table.SetColumn("grazing_amplitude_v", closed_form);
  table.SetColumn("from_rest_contact_amplitude_v", from_rest);
  table.Write(study.out / "saturation_onset.csv");
  plot::Series graze = Line("steady state grazes the stop (closed form)", grid_hz, closed_form);
  plot::Series rest = Line("record from rest reaches the stop (bisection)", grid_hz, from_rest);
  rest.markers = true;
  rest.line = false;
  plot::Axes axes;
  axes.title = "Stroke saturation onset, Table 2 model";
  axes.x_label = "frequency [Hz]";
  axes.y_label = "drive amplitude [V]";
  axes.log_x = true;
  // From the data, on a log axis: the thresholds run from a few tenths of a volt at the resonance to
  // 10 V and more far from it (a fixed 0 .. 1 V cut them off).
  axes.log_y = true;
  WriteFile(study.out / "saturation_onset.svg", plot::LinePlot({graze, rest}, axes));

  study.summary << "\nSaturation onset (drive amplitude at which the stop is reached):\n";
  study.summary << "  frequency   grazing V_sat   from rest (10 s record)\n";
  for (size_t i = 0; i < grid_hz.size(); i += 4) {
    char line[128];
    std::snprintf(line, sizeof line, "  %6.2f Hz   %8.4f V      %8.4f V\n", grid_hz[i], closed_form[i], from_rest[i]);
    study.summary << line;
  }
  const auto lowest = std::min_element(closed_form.begin(), closed_form.end()) - closed_form.begin();
  char line[160];
  std::snprintf(line, sizeof line, "  lowest grazing amplitude on the grid: %.4f V at %.2f Hz\n", closed_form[lowest],
                grid_hz[lowest]);
  study.summary << line;
}

}  // namespace

int RunPaper(const std::vector<std::string>& argv) {
  const Args args(argv, {"--out", "--model", "--set", "--method", "--step-duration-s", "--threads"}, {"--help"},
                  {"--set"});
  if (args.Has("--help")) {
    std::cout << kPaperHelp;
    return 0;
  }
  Study study;
  const auto out = args.Get("--out");
  if (!out) throw InputError("--out", "is required (a folder for the figures)");
  study.out = *out;
  study.model = LoadModel(args);
  try {
    study.method = ChooseMethod(args.GetOr("--method", "auto"), study.model);
  } catch (const InputError& e) {
    throw InputError("--method", e.bare_message());
  }
  study.step_duration_s = args.Number("--step-duration-s", 10.0);
  if (study.step_duration_s < 1.0) throw InputError("--step-duration-s", "must be at least 1 s (the summaries use the last second)");
  study.threads = args.Integer("--threads", 2);
  if (study.threads < 1 || study.threads > 64) throw InputError("--threads", "must be between 1 and 64");
  std::error_code ec;
  std::filesystem::create_directories(study.out, ec);
  if (ec) throw InputError("--out", "cannot create '" + study.out.string() + "': " + ec.message());

  const auto start = std::chrono::steady_clock::now();
  auto stage = [&](const char* name, void (*run)(Study&)) {
    const auto t0 = std::chrono::steady_clock::now();
    run(study);
    std::fprintf(stderr, "  %-28s %.2f s\n", name, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  };
  std::fprintf(stderr, "strokelab paper -> %s\n", study.out.string().c_str());
  stage("Fig. 2/9 time histories", TimeHistories);
  stage("Fig. 3 spectra", Spectra);
  stage("Fig. 6 restoring force", RestoringForce);
  stage("Fig. 7 contact stiffness", ContactStiffness);
  stage("Fig. 10/5/4b FRFs", FrequencyResponses);
  stage("saturation onset", SaturationOnset);
  study.summary << "\nwall time " << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()
                << " s\n";
  WriteFile(study.out / "summary.txt", study.summary.str());
  std::cout << study.summary.str();
  return 0;
}

}  // namespace strokelab::cli
