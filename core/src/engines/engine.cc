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

void Validate(const SimulationOptions& o) {
  if (!std::isfinite(o.sample_rate_hz) || o.sample_rate_hz <= 0)
    throw InputError("sample_rate_hz", "must be a finite number > 0");
  if (!std::isfinite(o.duration_s) || o.duration_s <= 0) throw InputError("duration_s", "must be a finite number > 0");
  if (o.SampleCount() < 2) throw InputError("duration_s", "the record must hold at least 2 samples");
  if (o.SampleCount() > 200'000'000)
    throw InputError("duration_s", "duration x sample rate exceeds 2e8 samples");
  if (!std::isfinite(o.initial.x_m)) throw InputError("initial.x_m", "must be finite");
  if (!std::isfinite(o.initial.v_m_per_s)) throw InputError("initial.v_m_per_s", "must be finite");
  if (!(o.cvode_relative_tolerance > 0) || !(o.cvode_absolute_tolerance_m > 0) ||
      !(o.cvode_absolute_tolerance_m_per_s > 0))
    throw InputError("cvode tolerances", "must be > 0");
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
