// The fit's options (fit.h): the model kind by name, and FitOptions' validation.
#include <cmath>
#include <optional>
#include <string>
#include <string_view>

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
}  // namespace strokelab
