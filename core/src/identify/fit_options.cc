// The fit's options (fit.h): the model kind by name, FitOptions' validation and its names in jobs and
// on the command line (FitOptionFields).
#include <cmath>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fit_internal.h"
#include "strokelab/base/errors.h"
#include "strokelab/identify/fit.h"

namespace strokelab {

FitModelKind ParseFitModel(std::string_view text) {
  if (text == "paper") return FitModelKind::kPaper;
  if (text == "linear") return FitModelKind::kLinear;
  throw InputError("model", "unknown fit model '" + std::string(text) + "' (known: paper, linear)");
}

const char* ToString(FitModelKind kind) { return kind == FitModelKind::kPaper ? "paper" : "linear"; }

std::optional<FieldError> FitOptions::IsValid() const {
  using fit_internal::Format;
  if (!std::isfinite(mass_kg) || mass_kg <= 0)
    return FieldError{"mass_kg", "must be a finite number > 0, got " + Format(mass_kg)};
  if (harmonic_orders < 1) return FieldError{"harmonic_orders", "must be >= 1, got " + std::to_string(harmonic_orders)};
  if (!std::isfinite(max_clear_distortion) || max_clear_distortion <= 0)
    return FieldError{"max_clear_distortion", "must be a finite number > 0, got " + Format(max_clear_distortion)};
  if (!std::isfinite(mains_frequency_hz)) return FieldError{"mains_frequency_hz", "must be finite"};
  if (max_iterations < 1) return FieldError{"max_iterations", "must be >= 1, got " + std::to_string(max_iterations)};
  if (!(max_refinement_seconds > 0))
    return FieldError{"max_refinement_seconds", "must be > 0, got " + Format(max_refinement_seconds)};
  if (!std::isfinite(spikes.threshold_sigmas) || spikes.threshold_sigmas <= 0)
    return FieldError{"spikes.threshold_sigmas", "must be a finite number > 0"};
  if (spikes.baseline_harmonics < 0) return FieldError{"spikes.baseline_harmonics", "must be >= 0"};
  return std::nullopt;
}

const std::vector<OptionInfo<FitOptions>>& FitOptionFields() {
  static const std::vector<OptionInfo<FitOptions>> kFields = {
      {"harmonic_orders", "harmonics", "--harmonics", &FitOptions::harmonic_orders},
      {"mass_kg", "mass_kg", "--mass-kg", &FitOptions::mass_kg},
      {"mains_frequency_hz", "mains_hz", "--mains-hz", &FitOptions::mains_frequency_hz},
      {"max_clear_distortion", "max_distortion", "--max-distortion", &FitOptions::max_clear_distortion},
      {"max_iterations", "max_iterations", "--max-iterations", &FitOptions::max_iterations},
      {"fit_contact_damping", "fit_contact_damping", "--fit-contact-damping", &FitOptions::fit_contact_damping},
      {"refine", "refine", "--no-refine", &FitOptions::refine, true},
      {"max_refinement_seconds", "max_refinement_seconds", nullptr, &FitOptions::max_refinement_seconds},
  };
  return kFields;
}
}  // namespace strokelab
