// The CLI's subcommands. Each takes the arguments after its name and returns the exit code;
// bad input is thrown as InputError and reported by main() in one line.
#pragma once

#include <string>
#include <vector>

#include "args.h"
#include "strokelab/identify/fit.h"
#include "strokelab/model/model.h"

namespace strokelab::cli {

int RunSimulate(const std::vector<std::string>& argv);
int RunPaper(const std::vector<std::string>& argv);
int RunSweep(const std::vector<std::string>& argv);
int RunServe(const std::vector<std::string>& argv);
int RunWorker(const std::vector<std::string>& argv);
int RunSubmit(const std::vector<std::string>& argv);
int RunStatus(const std::vector<std::string>& argv);
int RunResults(const std::vector<std::string>& argv);
int RunRegress(const std::vector<std::string>& argv);
int RunSynth(const std::vector<std::string>& argv);
int RunFit(const std::vector<std::string>& argv);
int RunDiagnose(const std::vector<std::string>& argv);

// The fit's options from --model and the flags of FitOptionFields() (shared by fit and diagnose,
// which accept them with AddFitFlags); bad values are thrown as InputError naming the flag.
void AddFitFlags(std::vector<std::string>* valued, std::vector<std::string>* switches);
FitOptions FitOptionsFromArgs(const Args& args);
int RunBackup(const std::vector<std::string>& argv);

// --model (a preset name or a JSON model file) followed by every --set key=value, validated.
ActuatorModel LoadModel(const Args& args);

}  // namespace strokelab::cli
