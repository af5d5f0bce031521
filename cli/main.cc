// strokelab: one binary for local studies and, later, the service.
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

#include "ceres_log.h"
#include "commands.h"
#include "strokelab/base/errors.h"

namespace {

constexpr const char* kUsage = R"(strokelab: stroke-saturated inertial actuator studies

usage: strokelab COMMAND [options]

commands:
  simulate   one time-domain record of a model under a sine drive (summary as text or --json, series as CSV)
  sweep      steady states over a frequency x amplitude grid: FRF branches, saturation thresholds, jumps
  regress    run job files and compare their results with stored baselines (CI regression jobs)
  synth      a synthetic measurement campaign (recordings layout) from a model, its truth apart
  fit        fit a model (paper, linear) to a campaign directory: parameters with standard errors
  diagnose   where a fitted model misses a campaign, the physics it left out, fitted, with the improvement
  paper      regenerate the paper's simulated figures (CSV + SVG) and a text summary into a folder

service:
  serve      the REST service: SQLite job store, worker pool, web page at /
  worker     a remote worker leasing tasks from a server (--server http://HOST:PORT)
  submit     submit a job file to a server (--wait: progress bar until it finishes)
  status     a job's status (--wait: until it finishes)
  results    a finished job's results: a sweep's steady states (JSON or --csv), a fit's or diagnosis's document
  backup     a consistent copy of the service's job store, safe while it runs (--db F --to G)

Run 'strokelab COMMAND --help' for a command's options.

Ceres' own log lines (the fits' solver) are dropped unless STROKELAB_CERES_LOG=LEVEL[:FILE] asks for
them: LEVEL error, warning or info (and above), on stderr or appended to FILE (serve: as JSON lines).
)";

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h") {
    std::cout << kUsage;
    return argc < 2 ? 2 : 0;
  }
  const std::string command = argv[1];
  const std::vector<std::string> rest(argv + 2, argv + argc);
  try {
    strokelab::cli::RouteCeresLog(strokelab::cli::CeresLogSettingsFrom(std::getenv("STROKELAB_CERES_LOG")));
    if (command == "simulate") return strokelab::cli::RunSimulate(rest);
    if (command == "paper") return strokelab::cli::RunPaper(rest);
    if (command == "sweep") return strokelab::cli::RunSweep(rest);
    if (command == "serve") return strokelab::cli::RunServe(rest);
    if (command == "worker") return strokelab::cli::RunWorker(rest);
    if (command == "submit") return strokelab::cli::RunSubmit(rest);
    if (command == "status") return strokelab::cli::RunStatus(rest);
    if (command == "results") return strokelab::cli::RunResults(rest);
    if (command == "regress") return strokelab::cli::RunRegress(rest);
    if (command == "synth") return strokelab::cli::RunSynth(rest);
    if (command == "fit") return strokelab::cli::RunFit(rest);
    if (command == "diagnose") return strokelab::cli::RunDiagnose(rest);
    if (command == "backup") return strokelab::cli::RunBackup(rest);
    std::cerr << "strokelab: error: unknown command '" << command << "' (see strokelab --help)\n";
    return 2;
  } catch (const strokelab::InputError& e) {
    std::cerr << "strokelab: error: " << e.what() << "\n";
    return 2;
  } catch (const strokelab::NumericalError& e) {
    std::cerr << "strokelab: numerical failure: " << e.what() << "\n";
    return 3;
  } catch (const std::exception& e) {
    std::cerr << "strokelab: failure: " << e.what() << "\n";
    return 1;
  }
}
