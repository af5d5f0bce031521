// Three simulation engines behind one interface:
//   exact  closed-form propagation in each linear region, switching instants located on the
//          closed form; piecewise-linear models only. The fast path.
//   cvode  SUNDIALS CVODE with root-finding on every switching surface; any model.
//   ode3   fixed-step Bogacki-Shampine at the output rate, as the paper's Simulink run (section 4.1).
// "auto" (ChooseMethod) takes one of them by the model: the default wherever a caller need not name one.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "strokelab/model/dynamics.h"
#include "strokelab/model/model.h"

namespace strokelab {

enum class Method { kExact, kCvode, kOde3 };
Method ParseMethod(std::string_view text);  // throws InputError("method", ...)
const char* ToString(Method method);

// The engine for a model, named ("exact", "cvode", "ode3") or "auto": exact for a piecewise-linear
// model, else cvode, the best engine that takes any model. Throws InputError("method", ...) for an
// unknown name and for exact on a model it cannot take, saying what to use instead.
struct MethodChoice {
  Method method = Method::kExact;
  std::string reason;            // why auto chose it ("the model is piecewise linear"); empty when named
  std::string Describe() const;  // "exact", or "cvode (auto: the model has k3 ..., which the exact ...)"
};
MethodChoice ChooseMethod(std::string_view text, const ActuatorModel& model);

struct SimulationOptions {
  double duration_s = 10.0;        // record length T [s]; samples at t_n = n / fs, n = 0 .. N-1
  double sample_rate_hz = 51200.0; // fs [Hz]
  State initial;                   // state at t = 0 (rest by default)
  // CVODE tolerances (relative, dimensionless; absolute on x [m], v [m/s] and the coil's force [N]).
  double cvode_relative_tolerance = 1e-10;
  double cvode_absolute_tolerance_m = 1e-14;
  double cvode_absolute_tolerance_m_per_s = 1e-11;
  double cvode_absolute_tolerance_n = 1e-12;
  bool record_velocity = true;     // the velocity channel is optional (saves memory bandwidth)

  size_t SampleCount() const;
  std::optional<FieldError> IsValid() const;  // names duration_s / sample_rate_hz / initial
};

// One stop contact: from the instant the stop starts pushing to the instant it lets go.
struct ContactInterval {
  double start_s = 0.0;
  double end_s = 0.0;   // the record's end if the contact is still on there
  bool upper = false;   // false: the lower stop
  bool closed = true;   // false when the record ended during the contact
  double DurationS() const { return end_s - start_s; }
};

// A simulated record on the uniform grid t_n = n / fs.
struct Record {
  double sample_rate_hz = 0.0;
  std::vector<double> displacement_m;
  std::vector<double> velocity_m_per_s;  // empty when options.record_velocity is false
  std::vector<double> force_n;           // blocked force f = m_p x'' (model.h)
  std::vector<std::uint8_t> in_contact;  // 1 where a stop pushes at t_n
  std::vector<ContactInterval> contacts; // switching instants as the engine located them
  State final_state;                     // at t = N / fs
  size_t rhs_evaluations = 0;            // cost figure (0 for exact)
  size_t size() const { return displacement_m.size(); }
  double TimeS(size_t n) const { return static_cast<double>(n) / sample_rate_hz; }
};

class Engine {
 public:
  virtual ~Engine() = default;
  virtual Method method() const = 0;
  // Validates the model, the drive and the options (InputError naming the field), then fills *out
  // (reusing its storage). Throws InputError for a model the engine cannot run, NumericalError if
  // the solver fails.
  void Simulate(const ActuatorModel& model, const SineDrive& drive, const SimulationOptions& options,
                Record* out) const;
  Record Simulate(const ActuatorModel& model, const SineDrive& drive, const SimulationOptions& options) const {
    Record record;
    Simulate(model, drive, options, &record);
    return record;
  }

 protected:
  // The engine's own work, on validated input.
  virtual void Run(const ActuatorModel& model, const SineDrive& drive, const SimulationOptions& options,
                   Record* out) const = 0;
};

std::unique_ptr<Engine> MakeEngine(Method method);
std::unique_ptr<Engine> MakeExactEngine();
std::unique_ptr<Engine> MakeCvodeEngine();
std::unique_ptr<Engine> MakeOde3Engine();

}  // namespace strokelab
