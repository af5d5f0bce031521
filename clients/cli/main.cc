// strokelab: one binary for local studies and, later, the service.
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "commands.h"
#include "strokelab/errors.h"

namespace {

constexpr const char* kUsage = R"(strokelab: stroke-saturated inertial actuator studies

usage: strokelab COMMAND [options]

commands:
  simulate   one time-domain record of a model under a sine drive (summary as text or --json, series as CSV)
  sweep      steady states over a frequency x amplitude grid: FRF branches, saturation thresholds, jumps
  paper      regenerate the paper's simulated figures (CSV + SVG) and a text summary into a folder

Run 'strokelab COMMAND --help' for a command's options.
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
    if (command == "simulate") return strokelab::cli::RunSimulate(rest);
    if (command == "paper") return strokelab::cli::RunPaper(rest);
    if (command == "sweep") return strokelab::cli::RunSweep(rest);
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
