// The ode3 engine: fixed-step Bogacki-Shampine, one step per output sample, as the paper's Simulink
// run (paper section 4.1: "ode3 solver, with a sample rate of 51.2 kHz").
//
// Bogacki & Shampine (1989), the third-order pair behind Simulink's ode3, step h = 1/fs:
//   k1 = f(t, y)
//   k2 = f(t + h/2,  y + h/2  k1)
//   k3 = f(t + 3h/4, y + 3h/4 k2)
//   y_next = y + h (2/9 k1 + 1/3 k2 + 4/9 k3)
// Like Simulink's fixed-step solvers it locates no events: the contact mode at every stage comes from
// the stage state alone (ModeFromState), so a switch inside a step is smeared over that step. That is
// the error a fixed-step run of the paper's model carries (spikes, contact times quantised to 1/fs).
//
// Reference: P. Bogacki, L. F. Shampine, "A 3(2) pair of Runge-Kutta formulas", Appl. Math. Lett. 2
// (1989) 321-325; "Nonlinear vibrations of a stroke-saturated inertial actuator", section 4.1
// (the Simulink ode3 run).
#include <cmath>
#include <complex>
#include <optional>
#include <string>

#include "strokelab/base/cancel.h"
#include "strokelab/engines/engine.h"
#include "strokelab/base/errors.h"
#include "contact_log.h"

namespace strokelab {
namespace {

// y' = [x', v'] = [v, f / m_p] at one stage.
struct Derivative {
  double x_rate_m_per_s = 0.0;
  double v_rate_m_per_s2 = 0.0;
};

// The drive v_in = V sin(w t + phi) at the three stage times of step n: t_n, t_n + h/2, t_n + 3h/4.
// Three sin() calls per step were 80% of the run time; instead the phasor e^{j(w t_n + phi)} is
// rotated by e^{j w h} from step to step and recomputed exactly every kAnchorSteps steps, which
// bounds the rounding drift to about kAnchorSteps ulp (~1e-14 relative).
class StageDrive {
 public:
  struct Voltages {
    double start_v = 0.0;          // at t_n [V]
    double half_v = 0.0;           // at t_n + h/2 [V]
    double three_quarter_v = 0.0;  // at t_n + 3h/4 [V]
  };

  StageDrive(const SineDrive& drive, double sample_rate_hz)
      : drive_(drive),
        sample_rate_hz_(sample_rate_hz),
        step_rotation_(Rotation(1.0)),
        half_rotation_(Rotation(0.5)),
        three_quarter_rotation_(Rotation(0.75)) {}

  // Steps must be asked for in order, n = 0, 1, 2, ...
  Voltages AtStep(size_t n) {
    if (n % kAnchorSteps == 0) {
      const double phase_rad =
          drive_.AngularFrequency() * (static_cast<double>(n) / sample_rate_hz_) + drive_.phase_rad;
      phasor_ = {std::cos(phase_rad), std::sin(phase_rad)};
    } else {
      phasor_ *= step_rotation_;
    }
    const double amplitude_v = drive_.amplitude_v;
    return {amplitude_v * phasor_.imag(), amplitude_v * (phasor_ * half_rotation_).imag(),
            amplitude_v * (phasor_ * three_quarter_rotation_).imag()};
  }

 private:
  static constexpr size_t kAnchorSteps = 256;

  std::complex<double> Rotation(double fraction_of_step) const {
    const double angle_rad = drive_.AngularFrequency() * fraction_of_step / sample_rate_hz_;
    return {std::cos(angle_rad), std::sin(angle_rad)};
  }

  const SineDrive& drive_;
  const double sample_rate_hz_;
  const std::complex<double> step_rotation_;
  const std::complex<double> half_rotation_;
  const std::complex<double> three_quarter_rotation_;
  std::complex<double> phasor_;
};

class Ode3Run {
 public:
  Ode3Run(const ActuatorModel& model, const SineDrive& drive, const SimulationOptions& options, Record* out)
      : model_(model),
        options_(options),
        out_(out),
        sample_count_(options.SampleCount()),
        step_s_(1.0 / options.sample_rate_hz),
        inverse_mass_per_kg_(1.0 / model.mass_kg),
        stage_drive_(drive, options.sample_rate_hz),
        contacts_(&out->contacts, ContactMode{}) {}

  void Run() {
    PrepareRecord();
    double x_m = options_.initial.x_m;
    double v_m_per_s = options_.initial.v_m_per_s;
    for (size_t n = 0; n < sample_count_; ++n) {
      if ((n & 4095) == 0) ThrowIfCancelled();  // cancel.h
      const StageDrive::Voltages drive_v = stage_drive_.AtStep(n);
      // The first stage doubles as the sample's force (no extra evaluation).
      const ContactMode mode = ModeFromState(model_, x_m, v_m_per_s);
      const double force_n = Force(drive_v.start_v, x_m, v_m_per_s, mode);
      EmitSample(n, x_m, v_m_per_s, force_n, mode);
      Step(drive_v, force_n, &x_m, &v_m_per_s);
      if (!std::isfinite(x_m) || !std::isfinite(v_m_per_s))
        throw NumericalError("ode3 engine: the state is no longer finite at t = " + std::to_string(TimeS(n + 1)) +
                             " s (the fixed step 1/fs is unstable or the model diverges)");
    }
    out_->final_state = {x_m, v_m_per_s};
    contacts_.Finish(TimeS(sample_count_));
  }

 private:
  double TimeS(size_t n) const { return static_cast<double>(n) / options_.sample_rate_hz; }

  void PrepareRecord() {
    out_->sample_rate_hz = options_.sample_rate_hz;
    out_->displacement_m.resize(sample_count_);
    if (options_.record_velocity) {
      out_->velocity_m_per_s.resize(sample_count_);
    } else {
      out_->velocity_m_per_s.clear();
    }
    out_->force_n.resize(sample_count_);
    out_->in_contact.resize(sample_count_);
    out_->contacts.clear();
    out_->final_state = {};
    out_->rhs_evaluations = 0;
  }

  double Force(double drive_v, double x_m, double v_m_per_s, ContactMode mode) {
    ++out_->rhs_evaluations;
    return BlockedForce(model_, drive_v, x_m, v_m_per_s, mode);
  }

  Derivative StageDerivative(double drive_v, double x_m, double v_m_per_s) {
    const double force_n = Force(drive_v, x_m, v_m_per_s, ModeFromState(model_, x_m, v_m_per_s));
    return {v_m_per_s, force_n * inverse_mass_per_kg_};
  }

  // One Bogacki-Shampine step from t_n; k1 from the force already evaluated there.
  void Step(const StageDrive::Voltages& drive_v, double force_n, double* x_m, double* v_m_per_s) {
    const double h = step_s_;
    const Derivative k1{*v_m_per_s, force_n * inverse_mass_per_kg_};
    const Derivative k2 =
        StageDerivative(drive_v.half_v, *x_m + 0.5 * h * k1.x_rate_m_per_s, *v_m_per_s + 0.5 * h * k1.v_rate_m_per_s2);
    const Derivative k3 = StageDerivative(drive_v.three_quarter_v, *x_m + 0.75 * h * k2.x_rate_m_per_s,
                                          *v_m_per_s + 0.75 * h * k2.v_rate_m_per_s2);
    *x_m += h * (2.0 / 9.0 * k1.x_rate_m_per_s + 1.0 / 3.0 * k2.x_rate_m_per_s + 4.0 / 9.0 * k3.x_rate_m_per_s);
    *v_m_per_s +=
        h * (2.0 / 9.0 * k1.v_rate_m_per_s2 + 1.0 / 3.0 * k2.v_rate_m_per_s2 + 4.0 / 9.0 * k3.v_rate_m_per_s2);
  }

  void EmitSample(size_t n, double x_m, double v_m_per_s, double force_n, ContactMode mode) {
    out_->displacement_m[n] = x_m;
    if (options_.record_velocity) out_->velocity_m_per_s[n] = v_m_per_s;
    out_->force_n[n] = force_n;
    out_->in_contact[n] = mode.Any() ? 1 : 0;
    // A fixed-step solver knows contacts only from its samples: a contact starts at the first sample
    // in contact and ends at the first sample out of it, so both instants are quantised to 1/fs (a
    // contact shorter than one step may be missed altogether).
    contacts_.Update(TimeS(n), mode);
  }

  const ActuatorModel& model_;
  const SimulationOptions& options_;
  Record* out_;
  const size_t sample_count_;
  const double step_s_;               // h = 1 / fs [s]
  const double inverse_mass_per_kg_;  // 1 / m_p [1/kg]
  StageDrive stage_drive_;
  ContactLog contacts_;  // no contact before the first sample
};

class Ode3Engine final : public Engine {
 public:
  Method method() const override { return Method::kOde3; }


 protected:
  void Run(const ActuatorModel& model, const SineDrive& drive, const SimulationOptions& options,
           Record* out) const override {
    Ode3Run(model, drive, options, out).Run();
  }
};

}  // namespace

std::unique_ptr<Engine> MakeOde3Engine() { return std::make_unique<Ode3Engine>(); }

}  // namespace strokelab
