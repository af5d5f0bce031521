#include "strokelab/engines/engine.h"

#include <cmath>

namespace strokelab {

Method ParseMethod(std::string_view text) {
  if (text == "exact") return Method::kExact;
  if (text == "cvode") return Method::kCvode;
  if (text == "ode3") return Method::kOde3;
  throw InputError("method", "unknown method '" + std::string(text) + "' (known: exact, cvode, ode3)");
}

const char* ToString(Method method) {
  switch (method) {
    case Method::kExact: return "exact";
    case Method::kCvode: return "cvode";
    case Method::kOde3: return "ode3";
  }
  return "?";
}

MethodChoice ChooseMethod(std::string_view text, const ActuatorModel& model) {
  const std::string nonlinear = model.NonlinearTerms();
  if (text == "auto") {
    if (nonlinear.empty()) return {Method::kExact, "the model is piecewise linear"};
    return {Method::kCvode, "the model has " + nonlinear + ", which the exact engine cannot take"};
  }
  if (text != "exact" && text != "cvode" && text != "ode3")
    throw InputError("method", "unknown method '" + std::string(text) + "' (known: auto, exact, cvode, ode3)");
  const Method method = ParseMethod(text);
  if (method == Method::kExact && !nonlinear.empty())
    throw InputError("method", "the exact engine needs a piecewise-linear model; this one has " + nonlinear +
                                   " (use auto, the default, or cvode)");
  return {method, ""};
}

std::string MethodChoice::Describe() const {
  return reason.empty() ? ToString(method) : std::string(ToString(method)) + " (auto: " + reason + ")";
}

void Engine::Simulate(const ActuatorModel& model, const SineDrive& drive, const SimulationOptions& options,
                      Record* out) const {
  Validate(model);
  Validate(drive);
  Validate(options);
  Run(model, drive, options, out);
}

size_t SimulationOptions::SampleCount() const {
  return static_cast<size_t>(std::llround(duration_s * sample_rate_hz));
}

std::optional<FieldError> SimulationOptions::IsValid() const {
  if (!std::isfinite(sample_rate_hz) || sample_rate_hz <= 0)
    return FieldError{"sample_rate_hz", "must be a finite number > 0"};
  if (!std::isfinite(duration_s) || duration_s <= 0) return FieldError{"duration_s", "must be a finite number > 0"};
  if (SampleCount() < 2) return FieldError{"duration_s", "the record must hold at least 2 samples"};
  if (SampleCount() > 200'000'000)
    return FieldError{"duration_s", "duration x sample rate exceeds 2e8 samples"};
  if (!std::isfinite(initial.x_m)) return FieldError{"initial.x_m", "must be finite"};
  if (!std::isfinite(initial.v_m_per_s)) return FieldError{"initial.v_m_per_s", "must be finite"};
  if (!std::isfinite(initial.coil_force_n)) return FieldError{"initial.coil_force_n", "must be finite"};
  if (!(cvode_relative_tolerance > 0) || !(cvode_absolute_tolerance_m > 0) ||
      !(cvode_absolute_tolerance_m_per_s > 0) || !(cvode_absolute_tolerance_n > 0))
    return FieldError{"cvode tolerances", "must be > 0"};
  return std::nullopt;
}

std::unique_ptr<Engine> MakeEngine(Method method) {
  switch (method) {
    case Method::kExact: return MakeExactEngine();
    case Method::kCvode: return MakeCvodeEngine();
    case Method::kOde3: return MakeOde3Engine();
  }
  return nullptr;
}

}  // namespace strokelab
