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

// y' = [x', v', F_e'] = [v, f / m_p, CoilForceRate] at one stage (F_e' = 0 without the coil's pole).
struct Derivative {
  double x_rate_m_per_s = 0.0;
  double v_rate_m_per_s2 = 0.0;
  double coil_rate_n_per_s = 0.0;
};

// y + h k (the coil's force only with kCoilPole).
template <bool kCoilPole>
State Advance(const State& y, double h, const Derivative& k) {
  return {y.x_m + h * k.x_rate_m_per_s, y.v_m_per_s + h * k.v_rate_m_per_s2,
          kCoilPole ? y.coil_force_n + h * k.coil_rate_n_per_s : 0.0};
}

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
    State y = options_.initial;
    for (size_t n = 0; n < sample_count_; ++n) {
      if ((n & 4095) == 0) ThrowIfCancelled();  // cancel.h
      const StageDrive::Voltages drive_v = stage_drive_.AtStep(n);
      // The first stage doubles as the sample's force (no extra evaluation).
      const ContactMode mode = ModeFromState(model_, y.x_m, y.v_m_per_s);
      const double force_n = Force(drive_v.start_v, y, mode);
      EmitSample(n, y, force_n, mode);
      if (model_.HasCoilPole()) Step<true>(drive_v, force_n, &y);
      else Step<false>(drive_v, force_n, &y);
      if (!std::isfinite(y.x_m) || !std::isfinite(y.v_m_per_s) || !std::isfinite(y.coil_force_n))
        throw NumericalError("ode3 engine: the state is no longer finite at t = " + std::to_string(TimeS(n + 1)) +
                             " s (the fixed step 1/fs is unstable or the model diverges)");
    }
    out_->final_state = y;
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

  double Force(double drive_v, const State& y, ContactMode mode) {
    ++out_->rhs_evaluations;
    return BlockedForce(model_, drive_v, y, mode);
  }

  // F_e' with the coil's pole (a third state); nothing to integrate without it (the run's common case,
  // kept free of it).
  template <bool kCoilPole>
  double CoilRate(double drive_v, const State& y) const {
    if constexpr (kCoilPole) return CoilForceRateJacobian(model_, drive_v, y).rate_n_per_s;
    return 0.0;
  }

  template <bool kCoilPole>
  Derivative StageDerivative(double drive_v, const State& y) {
    const double force_n = Force(drive_v, y, ModeFromState(model_, y.x_m, y.v_m_per_s));
    return {y.v_m_per_s, force_n * inverse_mass_per_kg_, CoilRate<kCoilPole>(drive_v, y)};
  }

  // One Bogacki-Shampine step from t_n; k1 from the force already evaluated there.
  template <bool kCoilPole>
  void Step(const StageDrive::Voltages& drive_v, double force_n, State* y) {
    const double h = step_s_;
    const Derivative k1{y->v_m_per_s, force_n * inverse_mass_per_kg_, CoilRate<kCoilPole>(drive_v.start_v, *y)};
    const Derivative k2 = StageDerivative<kCoilPole>(drive_v.half_v, Advance<kCoilPole>(*y, 0.5 * h, k1));
    const Derivative k3 = StageDerivative<kCoilPole>(drive_v.three_quarter_v, Advance<kCoilPole>(*y, 0.75 * h, k2));
    y->x_m += h * (2.0 / 9.0 * k1.x_rate_m_per_s + 1.0 / 3.0 * k2.x_rate_m_per_s + 4.0 / 9.0 * k3.x_rate_m_per_s);
    y->v_m_per_s +=
        h * (2.0 / 9.0 * k1.v_rate_m_per_s2 + 1.0 / 3.0 * k2.v_rate_m_per_s2 + 4.0 / 9.0 * k3.v_rate_m_per_s2);
    if constexpr (kCoilPole)
      y->coil_force_n +=
          h * (2.0 / 9.0 * k1.coil_rate_n_per_s + 1.0 / 3.0 * k2.coil_rate_n_per_s + 4.0 / 9.0 * k3.coil_rate_n_per_s);
  }

  void EmitSample(size_t n, const State& y, double force_n, ContactMode mode) {
    out_->displacement_m[n] = y.x_m;
    if (options_.record_velocity) out_->velocity_m_per_s[n] = y.v_m_per_s;
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
