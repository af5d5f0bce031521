// One campaign of the extended fit's z-score study (fit_zscore_study.py): synthesises the diagnosis
// tests' concealed-effect campaign for one effect and one seed (concealed_effects.h), fits the
// diagnosis's candidate with that effect on every record (diagnose.h FitCandidate), and prints one
// JSON line: effect, seed, fitted, converged, seconds, and for every fitted parameter its estimate,
// standard error, truth (the synthesised model's value) and z = (estimate - truth) / standard error.
//
//   fit_study --effect cubic_stiffness --seed 5001
//   fit_study --list        # the effect ids it knows, one a line
//
// A fit that throws still prints its line (fitted false, "error"); bad flags exit with code 2.
#include <charconv>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <iostream>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <nlohmann/json.hpp>

#include "concealed_effects.h"
#include "strokelab/base/errors.h"
#include "strokelab/data/synth.h"
#include "strokelab/diagnose/diagnose.h"
#include "strokelab/model/model.h"

namespace strokelab {
namespace {

using testing::EffectCase;

struct StudyFlags {
  const EffectCase* effect = nullptr;
  uint64_t seed = 0;
};

const char kUsage[] = "usage: fit_study --effect ID --seed N | fit_study --list\n";

// The diagnosis tests' cases and the study's own.
std::vector<const EffectCase*> StudyCases() {
  std::vector<const EffectCase*> cases;
  for (const EffectCase& c : testing::ConcealedEffectCases()) cases.push_back(&c);
  for (const EffectCase& c : testing::StudyOnlyEffectCases()) cases.push_back(&c);
  return cases;
}

const EffectCase& FindCase(std::string_view id) {
  std::string known;
  for (const EffectCase* p : StudyCases()) {
    const EffectCase& c = *p;
    if (c.name == id) return c;
    known += (known.empty() ? "" : ", ") + c.name;
  }
  throw InputError("--effect", "unknown effect '" + std::string(id) + "' (known: " + known + ")");
}

StudyFlags ParseStudyFlags(std::span<char* const> args) {
  StudyFlags flags;
  bool has_seed = false;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string_view flag = args[i];
    if (i + 1 >= args.size()) throw InputError(std::string(flag), "expected a value after it");
    const std::string_view value = args[++i];
    if (flag == "--effect") {
      flags.effect = &FindCase(value);
    } else if (flag == "--seed") {
      const auto [end, error] = std::from_chars(value.data(), value.data() + value.size(), flags.seed);
      if (error != std::errc() || end != value.data() + value.size())
        throw InputError("--seed", "expected a non-negative integer, got '" + std::string(value) + "'");
      has_seed = true;
    } else {
      throw InputError(std::string(flag), "unknown flag");
    }
  }
  if (flags.effect == nullptr) throw InputError("--effect", "missing");
  if (!has_seed) throw InputError("--seed", "missing");
  return flags;
}

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

nlohmann::ordered_json StudyCampaign(const EffectCase& effect, uint64_t seed) {
  nlohmann::ordered_json line = {{"effect", effect.name}, {"seed", seed}, {"fitted", false}, {"converged", false}};
  const auto start = std::chrono::steady_clock::now();
  try {
    const Synthesis synthesis = Synthesize(WithEffect(effect), testing::CampaignOptions(seed));
    line["synth_seconds"] = Seconds(start);
    std::vector<Effect> effects;
    if (!effect.parameter.empty()) effects.push_back(ParseEffect(effect.name));
    const CandidateFit fit = FitCandidate(synthesis.campaign, effects);
    line["fitted"] = fit.fitted;
    line["converged"] = fit.converged;
    line["fit_seconds"] = fit.seconds;
    line["passes"] = fit.passes;
    line["residual_variance"] = fit.figures.residual_variance;
    if (!fit.note.empty()) line["note"] = fit.note;
    nlohmann::ordered_json parameters = nlohmann::ordered_json::array();
    for (const FitParameter& p : fit.parameters) {
      const double truth = synthesis.model.*(FindParameter(p.name).field);
      // A standard error of 0 (none known) gives a non-finite z, written as null.
      const double z = p.standard_error > 0 ? (p.value - truth) / p.standard_error
                                            : std::numeric_limits<double>::quiet_NaN();
      nlohmann::ordered_json parameter = {{"name", p.name}, {"unit", p.unit}, {"estimate", p.value},
                                          {"standard_error", p.standard_error}, {"truth", truth}, {"z", z}};
      if (!p.note.empty()) parameter["note"] = p.note;  // "held at a bound ..."
      parameters.push_back(parameter);
    }
    line["parameters"] = parameters;
  } catch (const std::exception& e) {
    line["error"] = e.what();
  }
  line["seconds"] = Seconds(start);
  return line;
}

}  // namespace
}  // namespace strokelab

int main(int argc, char** argv) {
  using namespace strokelab;
  if (argc == 2 && std::string_view(argv[1]) == "--list") {
    for (const testing::EffectCase* c : StudyCases()) std::cout << c->name << "\n";
    return 0;
  }
  StudyFlags flags;
  try {
    flags = ParseStudyFlags(std::span<char* const>(argv + 1, static_cast<size_t>(argc - 1)));
  } catch (const InputError& e) {
    std::cerr << e.what() << "\n" << kUsage;
    return 2;
  }
  std::cout << StudyCampaign(*flags.effect, flags.seed).dump() << std::endl;
  return 0;
}
