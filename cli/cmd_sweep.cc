// strokelab sweep: steady states over a drive-frequency x drive-amplitude grid (RunSweep, sweep.h),
// printed as a summary, as one JSON object (--json) or written as tables and pictures (--out).
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>

#include "commands.h"
#include "strokelab/base/errors.h"
#include "strokelab/base/parse.h"
#include "strokelab/sweep/sweep.h"
#include "strokelab/report/sweep_report.h"

namespace strokelab::cli {

using report::SweepFolderFiles;
using report::SweepSummaryText;
using report::SweepToJson;
using report::WriteSweepFolder;
namespace {

constexpr const char* kSweepHelp = R"(usage: strokelab sweep [options]

Steady states over a grid of drive frequency x drive amplitude: periodic orbits by shooting,
continued in frequency through folds, on the up-sweep and down-sweep branches and the unstable
orbits between them; per frequency the saturation threshold (grazing amplitude and lowest
amplitude with a stable contacting response), per amplitude the jump (bistable) intervals.

  --model NAME|FILE      preset (paper, linear) or a JSON model file             [paper]
  --set KEY=VALUE        override a model parameter (repeatable), e.g. --set k3=4e7
  --frequency-hz A:B|F   drive frequency range [Hz], or one frequency F          [5:50]
  --frequency-points N   frequencies on the grid                  [117; 1 with one --frequency-hz]
  --grid G               frequency spacing: linear | geometric | eq1             [linear]
                         eq1: paper Eq. 1, f_n = 5 Hz * 1.02^(n-1) for n = 1..N with
                         N = --frequency-points (117: 5 .. 49.7 Hz). It fixes the range, so
                         --frequency-hz cannot be given with it.
  --amplitude-v A:B|V    drive amplitude range [V], linear spacing, or one V     [0.1:0.6]
  --amplitude-points N   amplitudes on the grid                   [6; 1 with one --amplitude-v]
  --threads N            worker threads; results do not depend on it             [hardware threads]
  --no-thresholds        skip the saturation thresholds (a root search per frequency); the jump
                         intervals come with the amplitude rows and are still given
  --json                 print the result as one JSON object on stdout
  --out DIR              write tables, pictures and summary.txt into DIR (created if missing)

Without --json or --out a short summary is printed. --json and --out exclude each other.

--json: {points: [{frequency_hz, amplitude_v, branch (up|down|unstable), stable, period (drive
periods, or "aperiodic"), first_harmonic_force_n, first_harmonic_phase_rad, h_re_n_per_v, h_im_n_per_v,
min_displacement_m, max_displacement_m, peak_force_n, contacts_per_period, max_multiplier}],
saturation_threshold: [{frequency_hz, grazing_amplitude_v, lowest_contact_amplitude_v}],
jump: [{amplitude_v, bistable_from_hz, bistable_to_hz, from_kind, to_kind}],
grid: {frequency_hz, amplitude_v}, model, wall_time_s, points_per_second}; non-finite numbers: null.

--out DIR writes:
  points.csv                one row per steady state, columns as in --json (period empty: aperiodic)
  saturation_threshold.csv  per frequency: grazing and lowest contacting amplitude [V]
  jump.csv                  per bistable interval: amplitude, frequency bounds, what bounds them
  saturation_map.svg        up-sweep branch over (frequency, amplitude), coloured by peak force /
                            first-harmonic force amplitude: 1 for a sinusoidal response at any
                            frequency and growing with the impact spikes, so the map shows where
                            and how hard the stop is hit rather than the resonance ridge that
                            dominates |H|. On top: the grazing and lowest-contact curves and the
                            jump intervals (horizontal segments at their amplitude)
  saturation_map_down.svg   the same for the down-sweep branch
  frf_up.svg, frf_down.svg  |H| against frequency, one line per amplitude coloured by amplitude
                            (colour bar; paper Fig. 10), dots: unstable orbits, the jumps marked
  frf_phase.svg             arg H [rad], up branch solid, down branch dashed
  model.json, summary.txt   the model swept and the text summary

While running, a progress line is shown on stderr if it is a terminal: grid points done (a row's
as its continuation passes them) and threshold columns, the time elapsed and an estimate of the
time left. Ctrl-C cancels: the sweep stops at its next unit of work, prints "cancelled" and exits
with code 130.
)";

// Set by SIGINT; RunSweep polls it. A second Ctrl-C ends the process at once.
std::atomic<bool> interrupted{false};
static_assert(std::atomic<bool>::is_always_lock_free, "used from a signal handler");

void OnInterrupt(int) {
  if (interrupted.exchange(true)) {
    std::signal(SIGINT, SIG_DFL);
    std::raise(SIGINT);
  }
}

// Installs OnInterrupt for its lifetime and restores the previous SIGINT action after.
class InterruptGuard {
 public:
  InterruptGuard() {
    interrupted = false;
    struct sigaction action = {};
    action.sa_handler = OnInterrupt;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, &previous_);
  }
  ~InterruptGuard() { sigaction(SIGINT, &previous_, nullptr); }
  InterruptGuard(const InterruptGuard&) = delete;
  InterruptGuard& operator=(const InterruptGuard&) = delete;

 private:
  struct sigaction previous_ = {};
};

// A one-line progress bar on stderr, redrawn in place at most every 0.1 s; only on a terminal. Its
// units are the sweep's grid points (a row's as its continuation passes them) and threshold columns
// (SweepProgress); the time left is an estimate from the rate so far.
class ProgressLine {
 public:
  explicit ProgressLine(std::string units)
      : enabled_(isatty(STDERR_FILENO) == 1), start_(std::chrono::steady_clock::now()), units_(std::move(units)) {}
  ~ProgressLine() { Clear(); }

  // Called from RunSweep's worker threads.
  void Update(const SweepProgress& progress) {
    if (!enabled_ || progress.total == 0) return;
    const std::lock_guard<std::mutex> lock(mutex_);
    const auto now = std::chrono::steady_clock::now();
    if (progress.done < progress.total && now - last_draw_ < std::chrono::milliseconds(100)) return;
    last_draw_ = now;
    constexpr int kWidth = 30;
    const double fraction = static_cast<double>(progress.done) / static_cast<double>(progress.total);
    const int filled = static_cast<int>(fraction * kWidth);
    std::string bar(static_cast<size_t>(filled), '#');
    bar.resize(kWidth, '.');
    const double elapsed_s = std::chrono::duration<double>(now - start_).count();
    std::fprintf(stderr, "\rsweep [%s] %zu/%zu %s %3.0f%% %.1f s", bar.c_str(), progress.done, progress.total,
                 units_.c_str(), 100.0 * fraction, elapsed_s);
    if (progress.done > 0 && progress.done < progress.total && elapsed_s >= 1.0)  // a rate over a second at least
      std::fprintf(stderr, ", about %.0f s left (estimate)", elapsed_s * (1.0 / fraction - 1.0));
    std::fputs("\033[K", stderr);
    std::fflush(stderr);
    drawn_ = true;
  }

  void Clear() {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (!drawn_) return;
    std::fputs("\r\033[K", stderr);
    std::fflush(stderr);
    drawn_ = false;
  }

 private:
  const bool enabled_;
  const std::chrono::steady_clock::time_point start_;
  const std::string units_;
  std::chrono::steady_clock::time_point last_draw_{};
  std::mutex mutex_;
  bool drawn_ = false;
};

// The points of an axis: `points_flag`, or 1 where `range_flag` gives one value (a FROM:TO range
// takes `fallback`); one value with more points is refused naming the points flag.
int AxisPoints(const Args& args, const std::string& range_flag, const std::string& points_flag, int fallback) {
  const auto range = args.Get(range_flag);
  const bool single = range && range->find(':') == std::string::npos;
  if (!single) return args.Integer(points_flag, fallback);
  const int points = args.Integer(points_flag, 1);
  if (points != 1)
    throw InputError(points_flag, "must be 1 with a single " + range_flag + " value ('" + *range +
                                      "'); give " + range_flag + " FROM:TO for more points");
  return points;
}

// SweepSpec::Validate names spec fields (frequency_hz.to, amplitude_v.points, threads, ...): the
// flag that set each one.
std::string FlagFor(const std::string& field, bool eq1_grid) {
  const auto starts = [&](const char* prefix) { return field.rfind(prefix, 0) == 0; };
  const bool points = field.find("points") != std::string::npos;
  if (starts("frequency_hz")) {
    if (points) return "--frequency-points";
    if (field.find("geometric") != std::string::npos || eq1_grid) return "--grid";
    return "--frequency-hz";
  }
  if (starts("amplitude_v")) return points ? "--amplitude-points" : "--amplitude-v";
  if (starts("threads")) return "--threads";
  if (starts("thresholds")) return "--no-thresholds";
  if (field == "grid") return "--frequency-points";  // the grid's size: frequency x amplitude points
  return field;
}

// A message about GridAxis field `field` ("frequency_hz.to") in the words of a FROM:TO flag:
// "frequency_hz.to: must be >= frequency_hz.from" -> "TO must be >= FROM".
std::string RangeMessage(const std::string& field, std::string message) {
  const size_t dot = field.find('.');
  const std::string axis = field.substr(0, dot), end = dot == std::string::npos ? "" : field.substr(dot + 1);
  for (const std::string& word : {axis + ".from", axis + ".to", std::string("from")}) {
    const std::string upper = word.ends_with("from") ? "FROM" : "TO";
    for (size_t at = message.find(word); at != std::string::npos; at = message.find(word, at + 1)) {
      const bool whole = (at == 0 || message[at - 1] == ' ') &&
                         (at + word.size() == message.size() || message[at + word.size()] == ' ');
      if (whole) message.replace(at, word.size(), upper);
    }
  }
  if (end == "from") return "FROM " + message;
  if (end == "to") return "TO " + message;
  return message;
}

SweepSpec SpecFromArgs(const Args& args) {
  SweepSpec spec;
  spec.model = LoadModel(args);

  const std::string grid = args.GetOr("--grid", "linear");
  if (grid != "linear" && grid != "geometric" && grid != "eq1")
    throw InputError("--grid", "unknown grid '" + grid + "' (known: linear, geometric, eq1)");
  const bool eq1 = grid == "eq1";
  const int frequency_points = AxisPoints(args, "--frequency-hz", "--frequency-points", 117);
  if (eq1) {
    if (args.Has("--frequency-hz"))
      throw InputError("--grid", "eq1 fixes the frequencies (5 Hz * 1.02^(n-1)); drop --frequency-hz");
    // Paper Eq. 1: w(n) = 10 pi 1.02^(n-1) rad/s.
    // (N < 1 keeps a valid range so that Validate names --frequency-points.)
    spec.frequency_hz = GridAxis{5.0, 5.0 * std::pow(1.02, std::max(frequency_points, 1) - 1), frequency_points, true};
  } else {
    const auto [from, to] = args.Range("--frequency-hz", 5.0, 50.0);
    spec.frequency_hz = GridAxis{from, to, frequency_points, grid == "geometric"};
  }
  const auto [v_from, v_to] = args.Range("--amplitude-v", 0.1, 0.6);
  spec.amplitude_v = GridAxis{v_from, v_to, AxisPoints(args, "--amplitude-v", "--amplitude-points", 6), false};
  spec.threads = args.Integer("--threads", static_cast<int>(std::max(1u, std::thread::hardware_concurrency())));
  spec.thresholds = !args.Has("--no-thresholds");
  try {
    Validate(spec);
  } catch (const InputError& e) {
    const std::string flag = FlagFor(e.field(), eq1);
    if (flag != "--frequency-hz" && flag != "--amplitude-v") throw InputError(flag, e.bare_message());
    // A range flag's message speaks of the FROM:TO the user typed: "TO must be >= FROM (got '50:5')".
    const auto typed = args.Get(flag);
    throw InputError(flag, RangeMessage(e.field(), e.bare_message()) + (typed ? " (got '" + *typed + "')" : ""));
  }
  return spec;
}

}  // namespace

int RunSweep(const std::vector<std::string>& argv) {
  const Args args(argv,
                  {"--model", "--set", "--frequency-hz", "--frequency-points", "--grid", "--amplitude-v",
                   "--amplitude-points", "--threads", "--out"},
                  {"--json", "--no-thresholds", "--help"}, {"--set"});
  if (args.Has("--help")) {
    std::cout << kSweepHelp;
    return 0;
  }
  if (!args.Positional().empty()) throw InputError(args.Positional().front(), "unexpected argument (see --help)");
  if (args.Has("--json") && args.Has("--out")) throw InputError("--json", "cannot be combined with --out");
  const SweepSpec spec = SpecFromArgs(args);
  const auto out = args.Get("--out");
  if (out) {
    std::error_code ec;
    std::filesystem::create_directories(*out, ec);
    if (ec) throw InputError("--out", "cannot create '" + *out + "': " + ec.message());
  }

  SweepResult result;
  {
    const InterruptGuard guard;
    ProgressLine progress(spec.thresholds ? "grid points and threshold columns" : "grid points");
    try {
      result = strokelab::RunSweep(spec, [&](const SweepProgress& p) { progress.Update(p); }, &interrupted);
    } catch (const Cancelled&) {
      progress.Clear();
      std::cerr << "strokelab: cancelled\n";
      return 130;
    }
  }

  if (args.Has("--json")) {
    std::cout << SweepToJson(result, spec.model).dump(2) << "\n";
  } else if (out) {
    WriteSweepFolder(result, spec.model, *out);
    std::cout << SweepSummaryText(result) << "\nwrote " << SweepFolderFiles().size() << " files to " << *out << "\n";
  } else {
    std::cout << SweepSummaryText(result);
  }
  return 0;
}

}  // namespace strokelab::cli
