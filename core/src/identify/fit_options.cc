// The fit's options (fit.h): the model kind by name, and FitOptions' validation.
#include <cmath>
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

bool FitOptions::IsValid(std::string* error) const {
  using fit_internal::Format;
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

namespace fit_internal {

void ThrowIfInvalid(const FitOptions& options) {
  std::string error;
  if (options.IsValid(&error)) return;
  const size_t colon = error.find(": ");
  throw InputError(error.substr(0, colon), error.substr(colon + 2));
}

}  // namespace fit_internal
}  // namespace strokelab
