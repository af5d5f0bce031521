// The cvode engine: SUNDIALS CVODE (6.4 C API) with root-finding on every switching surface.
//
// State y = [x, v]; y' = [v, f / m_p], f = BlockedForce(...) (dynamics.h, paper Eq. 2 in its
// continuous form); with the coil's pole (model.h) y = [x, v, F_e] and F_e' = CoilForceRate. The
// discrete contact mode is tracked here, not judged from the state: between
// two located events the right-hand side is one smooth vector field, so the multistep method keeps
// its order, and every mode change happens at a located root followed by CVodeReInit.
//
// Switching functions (all located by CVODE's Illinois root-finder, direction from CVodeGetRootInfo):
//   per stop present   g_geom  = p                                  penetration [m]
//                      g_force = StopForceUnclamped(p, p')          stop force before the clamp [N]
//                      (lower stop: p = d - x, p' = -v; upper stop: p = x - d_upper, p' = +v)
//   any stop present   g_apex  = v                                  velocity [m/s]
//                      (an extremum of x: catches a grazing contact that enters and leaves the
//                      stop within one step, which no sign change of g_geom at the step ends shows)
//   amplifier limit    V sin(w t + phi) - limit,  V sin(w t + phi) + limit   [V]
//                      (only when V > limit: the clipped drive has kinks there; a restart at each
//                      kink keeps the multistep history from straddling it)
//
// Mode rules at a root (dynamics.h, ContactMode: a stop pushes while p > 0 and its force > 0):
//   a stop that does not push starts pushing when g_geom rises through 0 (the mass enters the stop)
//     or when g_force rises through 0 while p > 0 (a damped stop that let go is pressed again);
//   a pushing stop lets go when g_force falls through 0 (with c_s = 0 that is also p returning to 0;
//     with c_s > 0 it comes first: the clamp that keeps the stop from pulling, model.h);
//   at an apex (g_apex = 0), a stop that does not push but would (ModeFromState) was entered
//     unseen inside the step: the entry instant is found by bisection on the step's interpolating
//     polynomial, the samples after it are discarded and the run restarts there in contact.
//
// Output samples are read off the step's interpolating polynomial (CVODE's own; CV_ONE_STEP
// stepping), ~30 samples per step at 51.2 kHz. Measured on the paper model (8 Hz / 0.5 V, 10 s):
// 46 ms, against 220 ms for CV_NORMAL with tout at every sample and 135 ms for one CVodeGetDky call
// per sample.
//
// Reference: "Nonlinear vibrations of a stroke-saturated inertial actuator", Eq. 2
// (in its continuous form, model.h).
#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <numbers>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "strokelab/base/cancel.h"
#include "strokelab/engines/engine.h"
#include "strokelab/base/errors.h"
#include "contact_log.h"

namespace strokelab {
namespace {

// Linear multistep method: Adams-Moulton. Measured on the paper model at 8 Hz / 0.5 V, a 10 s record
// at 51.2 kHz, default tolerances (rel 1e-10), Release, CPU time of one thread:
//   CV_ADAMS + Newton, dense, analytic Jacobian   46 ms   17.8k steps   22.7k RHS   max force error 4.5e-7 N
//   CV_BDF   + Newton, dense, analytic Jacobian   68 ms   38.3k steps   42.9k RHS   max force error 2.5e-6 N
//   CV_ADAMS + fixed-point iteration              43 ms   16.6k steps   29.3k RHS   max force error 8.1e-7 N
// (force errors against a run at rel 1e-13.) At this tolerance the step is set by accuracy, not by
// stability (|h lambda| << 1 even in contact, w_s = 6.4e3 rad/s), which is where Adams' higher order
// (up to 12; BDF stops at 5) pays. Newton (7% slower here) is kept over fixed-point iteration, which
// converges only while h |lambda| < ~1 and so would fail with stiffer stops or looser tolerances.
constexpr int kMultistepMethod = CV_ADAMS;

// CVODE's limit on internal steps per call; in CV_ONE_STEP mode a call takes one step, so the run
// is guarded by the two limits below instead.
constexpr long kMaxStepsPerCall = 100000;
// Step budget per period of the faster of drive and suspension. The paper model at 8 Hz / 0.5 V
// takes ~220 steps per period (contacts included); a run that needs 500 times more is stuck, e.g.
// chattering between modes: fail instead of spinning.
constexpr double kMaxStepsPerPeriod = 1e5;
// A diverging solution drives the step below the resolution of t (t + h == t): CVODE only warns
// about that and would go on forever. This many such steps in a row end the run.
constexpr int kMaxUnresolvedSteps = 10;
// The largest step, as a fraction of the shorter of drive and suspension period: keeps at most one
// extremum of x per step, so that the apex root sees every grazing contact. (It does not bind on
// the paper model at 1e-10: the steps there are 0.5-2 ms by accuracy alone.)
constexpr double kMaxStepFractionOfPeriod = 1.0 / 50.0;

enum class CvodeSurface {
  kLowerPenetration,   // g = d - x                          [m]
  kLowerForce,         // g = StopForceUnclamped(d - x, -v)  [N]
  kUpperPenetration,   // g = x - d_upper                    [m]
  kUpperForce,         // g = StopForceUnclamped(x - d_upper, v)  [N]
  kApex,               // g = v                              [m/s]
  kDriveAtPlusLimit,   // g = v_in(t) - limit                [V]
  kDriveAtMinusLimit,  // g = v_in(t) + limit                [V]
};

double LowerPenetrationM(const ActuatorModel& model, double x_m) { return model.lower_stop_m - x_m; }
double UpperPenetrationM(const ActuatorModel& model, double x_m) { return x_m - model.upper_stop_m; }

// Everything the SUNDIALS callbacks see (their user_data).
struct Problem {
  const ActuatorModel* model = nullptr;
  int size = 2;                   // ActuatorModel::StateSize
  const SineDrive* drive = nullptr;
  double inverse_mass_per_kg = 0.0;
  ContactMode mode;               // the tracked contact mode: the RHS uses it, never the state
  std::vector<CvodeSurface> surfaces;  // what each root function component is
  size_t rhs_evaluations = 0;
  std::string last_solver_message;  // CVODE's own words for the last error it reported
};

std::vector<CvodeSurface> SwitchingSurfaces(const ActuatorModel& model, const SineDrive& drive) {
  std::vector<CvodeSurface> surfaces;
  if (model.HasLowerStop()) {
    surfaces.push_back(CvodeSurface::kLowerPenetration);
    surfaces.push_back(CvodeSurface::kLowerForce);
  }
  if (model.HasUpperStop()) {
    surfaces.push_back(CvodeSurface::kUpperPenetration);
    surfaces.push_back(CvodeSurface::kUpperForce);
  }
  if (model.HasLowerStop() || model.HasUpperStop()) surfaces.push_back(CvodeSurface::kApex);
  // A drive that never reaches the limit is never clipped: no kinks to locate.
  if (model.HasAmplifierLimit() && drive.amplitude_v > model.amplifier_limit_v) {
    surfaces.push_back(CvodeSurface::kDriveAtPlusLimit);
    surfaces.push_back(CvodeSurface::kDriveAtMinusLimit);
  }
  return surfaces;
}

double SwitchingFunction(const Problem& problem, CvodeSurface surface, double t_s, double x_m, double v_m_per_s) {
  const ActuatorModel& model = *problem.model;
  switch (surface) {
    case CvodeSurface::kLowerPenetration:
      return LowerPenetrationM(model, x_m);
    case CvodeSurface::kLowerForce:
      return StopForceUnclamped(model, LowerPenetrationM(model, x_m), -v_m_per_s);
    case CvodeSurface::kUpperPenetration:
      return UpperPenetrationM(model, x_m);
    case CvodeSurface::kUpperForce:
      return StopForceUnclamped(model, UpperPenetrationM(model, x_m), v_m_per_s);
    case CvodeSurface::kApex:
      return v_m_per_s;
    case CvodeSurface::kDriveAtPlusLimit:
      return problem.drive->Voltage(t_s) - model.amplifier_limit_v;
    case CvodeSurface::kDriveAtMinusLimit:
      return problem.drive->Voltage(t_s) + model.amplifier_limit_v;
  }
  return 1.0;
}

// ---- SUNDIALS callbacks -------------------------------------------------------------------------

State Read(N_Vector y, int size) {
  return {NV_Ith_S(y, 0), NV_Ith_S(y, 1), size > 2 ? NV_Ith_S(y, 2) : 0.0};
}

void Write(const State& state, int size, N_Vector y) {
  NV_Ith_S(y, 0) = state.x_m;
  NV_Ith_S(y, 1) = state.v_m_per_s;
  if (size > 2) NV_Ith_S(y, 2) = state.coil_force_n;
}

int RightHandSide(sunrealtype t_s, N_Vector y, N_Vector ydot, void* user_data) {
  auto* problem = static_cast<Problem*>(user_data);
  ++problem->rhs_evaluations;
  const State state = Read(y, problem->size);
  const double voltage_v = problem->drive->Voltage(t_s);
  const double force_n = BlockedForce(*problem->model, voltage_v, state, problem->mode);
  NV_Ith_S(ydot, 0) = state.v_m_per_s;
  NV_Ith_S(ydot, 1) = force_n * problem->inverse_mass_per_kg;
  if (problem->size > 2) NV_Ith_S(ydot, 2) = CoilForceRateJacobian(*problem->model, voltage_v, state).rate_n_per_s;
  // A positive return is a recoverable failure: CVODE retries with a smaller step, and reports
  // CV_REPTD_RHSFUNC_ERR if that does not help.
  return std::isfinite(force_n) ? 0 : 1;
}

// Analytic Jacobian of y' = [v, f/m]: cheaper and more accurate than CVODE's difference quotients.
int Jacobian(sunrealtype t_s, N_Vector y, N_Vector /*fy*/, SUNMatrix jacobian, void* user_data, N_Vector /*tmp1*/,
             N_Vector /*tmp2*/, N_Vector /*tmp3*/) {
  const auto* problem = static_cast<const Problem*>(user_data);
  const State state = Read(y, problem->size);
  const double voltage_v = problem->drive->Voltage(t_s);
  const ForceJacobian j = BlockedForceJacobian(*problem->model, voltage_v, state, problem->mode);
  SUNMatZero(jacobian);
  SM_ELEMENT_D(jacobian, 0, 1) = 1.0;
  SM_ELEMENT_D(jacobian, 1, 0) = j.d_dx_n_per_m * problem->inverse_mass_per_kg;
  SM_ELEMENT_D(jacobian, 1, 1) = j.d_dv_n_s_per_m * problem->inverse_mass_per_kg;
  if (problem->size > 2) {
    const CoilForceRate r = CoilForceRateJacobian(*problem->model, voltage_v, state);
    SM_ELEMENT_D(jacobian, 1, 2) = j.d_dcoil * problem->inverse_mass_per_kg;
    SM_ELEMENT_D(jacobian, 2, 0) = r.d_dx_n_per_m_s;
    SM_ELEMENT_D(jacobian, 2, 1) = r.d_dv_n_per_m;
    SM_ELEMENT_D(jacobian, 2, 2) = r.d_dcoil_per_s;
  }
  return 0;
}

int RootFunctions(sunrealtype t_s, N_Vector y, sunrealtype* g, void* user_data) {
  const auto* problem = static_cast<const Problem*>(user_data);
  const double x_m = NV_Ith_S(y, 0);
  const double v_m_per_s = NV_Ith_S(y, 1);
  for (size_t i = 0; i < problem->surfaces.size(); ++i)
    g[i] = SwitchingFunction(*problem, problem->surfaces[i], t_s, x_m, v_m_per_s);
  return 0;
}

// CVODE would print its errors to stderr; keep them for the NumericalError instead.
void KeepErrorMessage(int /*error_code*/, const char* module, const char* function, char* msg, void* user_data) {
  auto* problem = static_cast<Problem*>(user_data);
  problem->last_solver_message = std::string(module) + "/" + function + ": " + msg;
}

// ---- SUNDIALS objects ---------------------------------------------------------------------------

// Owns the SUNDIALS objects of one run; frees them in reverse order of creation.
struct SundialsObjects {
  SUNContext context = nullptr;
  N_Vector y = nullptr;       // the solver's state: at t0, at a step's end or at a root
  N_Vector sample = nullptr;  // interpolated state at an output sample (CVodeGetDky)
  N_Vector absolute_tolerance = nullptr;
  SUNMatrix matrix = nullptr;
  SUNLinearSolver linear_solver = nullptr;
  void* cvode = nullptr;

  SundialsObjects() = default;
  SundialsObjects(const SundialsObjects&) = delete;
  SundialsObjects& operator=(const SundialsObjects&) = delete;
  ~SundialsObjects() {
    if (cvode != nullptr) CVodeFree(&cvode);
    if (linear_solver != nullptr) SUNLinSolFree(linear_solver);
    if (matrix != nullptr) SUNMatDestroy(matrix);
    if (absolute_tolerance != nullptr) N_VDestroy(absolute_tolerance);
    if (sample != nullptr) N_VDestroy(sample);
    if (y != nullptr) N_VDestroy(y);
    if (context != nullptr) SUNContext_Free(&context);
  }
};

// Throws NumericalError naming the SUNDIALS function, its flag and CVODE's message.
void Check(int flag, const char* function, const Problem& problem) {
  if (flag >= 0) return;
  std::ostringstream message;
  char* name = CVodeGetReturnFlagName(flag);  // malloc'ed by SUNDIALS
  message << "cvode engine: " << function << " failed with " << (name != nullptr ? name : "?") << " (" << flag << ")";
  std::free(name);
  if (!problem.last_solver_message.empty()) message << ": " << problem.last_solver_message;
  throw NumericalError(message.str());
}

std::string FormatNumber(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

void CheckCreated(const void* object, const char* function) {
  if (object == nullptr) throw NumericalError(std::string("cvode engine: ") + function + " returned NULL");
}

// The largest step [s]: a fraction of the drive period and of the suspension's natural period.
double MaxStepS(const ActuatorModel& model, const SineDrive& drive) {
  const double drive_period_s = 1.0 / drive.frequency_hz;
  const double natural_period_s = 2.0 * std::numbers::pi * std::sqrt(model.mass_kg / model.stiffness_n_per_m);
  return kMaxStepFractionOfPeriod * std::min(drive_period_s, natural_period_s);
}

void CreateSolver(const SimulationOptions& options, double max_step_s, Problem* problem, SundialsObjects* s) {
  // SUNContext_Create's flag is not a CVODE flag: no CVodeGetReturnFlagName for it.
  if (const int flag = SUNContext_Create(nullptr, &s->context); flag != 0)
    throw NumericalError("cvode engine: SUNContext_Create failed with flag " + std::to_string(flag));
  const int n = problem->size;
  s->y = N_VNew_Serial(n, s->context);
  CheckCreated(s->y, "N_VNew_Serial");
  s->sample = N_VNew_Serial(n, s->context);
  CheckCreated(s->sample, "N_VNew_Serial");
  s->absolute_tolerance = N_VNew_Serial(n, s->context);
  CheckCreated(s->absolute_tolerance, "N_VNew_Serial");
  Write(options.initial, n, s->y);
  NV_Ith_S(s->absolute_tolerance, 0) = options.cvode_absolute_tolerance_m;
  NV_Ith_S(s->absolute_tolerance, 1) = options.cvode_absolute_tolerance_m_per_s;
  if (n > 2) NV_Ith_S(s->absolute_tolerance, 2) = options.cvode_absolute_tolerance_n;

  s->cvode = CVodeCreate(kMultistepMethod, s->context);
  CheckCreated(s->cvode, "CVodeCreate");
  Check(CVodeSetErrHandlerFn(s->cvode, KeepErrorMessage, problem), "CVodeSetErrHandlerFn", *problem);
  Check(CVodeInit(s->cvode, RightHandSide, 0.0, s->y), "CVodeInit", *problem);
  Check(CVodeSetUserData(s->cvode, problem), "CVodeSetUserData", *problem);
  Check(CVodeSVtolerances(s->cvode, options.cvode_relative_tolerance, s->absolute_tolerance), "CVodeSVtolerances",
        *problem);
  s->matrix = SUNDenseMatrix(n, n, s->context);
  CheckCreated(s->matrix, "SUNDenseMatrix");
  s->linear_solver = SUNLinSol_Dense(s->y, s->matrix, s->context);
  CheckCreated(s->linear_solver, "SUNLinSol_Dense");
  Check(CVodeSetLinearSolver(s->cvode, s->linear_solver, s->matrix), "CVodeSetLinearSolver", *problem);
  Check(CVodeSetJacFn(s->cvode, Jacobian), "CVodeSetJacFn", *problem);
  Check(CVodeSetMaxNumSteps(s->cvode, kMaxStepsPerCall), "CVodeSetMaxNumSteps", *problem);
  Check(CVodeSetMaxStep(s->cvode, max_step_s), "CVodeSetMaxStep", *problem);
  if (!problem->surfaces.empty()) {
    Check(CVodeRootInit(s->cvode, static_cast<int>(problem->surfaces.size()), RootFunctions), "CVodeRootInit",
          *problem);
    // A root function that is exactly 0 at a restart is CVODE's business (it waits until it moves
    // away); no need to hear about it.
    Check(CVodeSetNoInactiveRootWarn(s->cvode), "CVodeSetNoInactiveRootWarn", *problem);
  }
}

// ---- The run ------------------------------------------------------------------------------------

class CvodeRun {
 public:
  CvodeRun(const ActuatorModel& model, const SineDrive& drive, const SimulationOptions& options, Record* out)
      : model_(model),
        drive_(drive),
        options_(options),
        out_(out),
        sample_count_(options.SampleCount()),
        end_s_(static_cast<double>(sample_count_) / options.sample_rate_hz) {
    problem_.model = &model;
    problem_.drive = &drive;
    problem_.size = model.StateSize();
    problem_.inverse_mass_per_kg = 1.0 / model.mass_kg;
    problem_.surfaces = SwitchingSurfaces(model, drive);
    problem_.mode = StartingMode(model, options.initial.x_m, options.initial.v_m_per_s);
    root_directions_.resize(problem_.surfaces.size());
    PrepareRecord();
  }

  void Run() {
    CreateSolver(options_, MaxStepS(model_, drive_), &problem_, &sundials_);
    Check(CVodeSetStopTime(sundials_.cvode, end_s_), "CVodeSetStopTime", problem_);
    contacts_.emplace(&out_->contacts, problem_.mode);
    EmitSample(0, options_.initial);
    next_sample_ = 1;

    const double max_steps = MaxSteps();
    double steps = 0;
    int unresolved_steps = 0;
    double t_s = 0.0;
    bool done = false;
    while (!done) {
      if (++steps > max_steps)
        throw WorkBudgetSpent("cvode engine: work budget spent: CVode took more than " + FormatNumber(max_steps) +
                             " steps, stuck near t = " + FormatNumber(t_s) + " s under the drive " +
                             FormatNumber(drive_.frequency_hz) + " Hz, " + FormatNumber(drive_.amplitude_v) +
                             " V (chattering between contact modes?)");
      if ((static_cast<uint64_t>(steps) & 1023) == 0) ThrowIfCancelled();  // cancel.h
      const int flag = CVode(sundials_.cvode, end_s_, sundials_.y, &t_s, CV_ONE_STEP);
      Check(flag, "CVode", problem_);
      CheckStepResolved(t_s, &unresolved_steps);
      polynomial_loaded_ = false;
      if (flag == CV_ROOT_RETURN) {
        Check(CVodeGetRootInfo(sundials_.cvode, root_directions_.data()), "CVodeGetRootInfo", problem_);
        if (FoundRoot(CvodeSurface::kApex)) {
          if (const std::optional<bool> over = RecoverMissedEntry(t_s)) {
            done = *over;
            continue;
          }
        }
      }
      EmitSamplesThrough(t_s);
      if (flag == CV_ROOT_RETURN) done = HandleRoots(t_s);
      if (flag == CV_TSTOP_RETURN || t_s >= end_s_) done = true;
    }
    // The stop time makes the last step end on t = N / fs (or a restart within rounding of it).
    out_->final_state = Read(sundials_.y, problem_.size);
    EmitRemainingSamples();
    contacts_->Finish(end_s_);
    out_->rhs_evaluations = problem_.rhs_evaluations;
  }

 private:
  double MaxSteps() const {
    const double natural_frequency_hz = std::sqrt(model_.stiffness_n_per_m / model_.mass_kg) / (2.0 * std::numbers::pi);
    const double periods = end_s_ * std::max(drive_.frequency_hz, natural_frequency_hz);
    return kMaxStepsPerPeriod * std::max(periods, 1.0);
  }

  void CheckStepResolved(double t_s, int* unresolved_steps) {
    double step_s = 0.0;
    Check(CVodeGetLastStep(sundials_.cvode, &step_s), "CVodeGetLastStep", problem_);
    const bool resolved = t_s + step_s != t_s;
    *unresolved_steps = resolved ? 0 : *unresolved_steps + 1;
    if (*unresolved_steps < kMaxUnresolvedSteps) return;
    std::string message = "cvode engine: CVode step size " + FormatNumber(step_s) +
                          " s is below the resolution of t = " + FormatNumber(t_s) +
                          " s (the solution diverges: x = " + FormatNumber(NV_Ith_S(sundials_.y, 0)) + " m)";
    if (!problem_.last_solver_message.empty()) message += ": " + problem_.last_solver_message;
    throw NumericalError(message);
  }

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

  double SampleTimeS(size_t n) const { return static_cast<double>(n) / options_.sample_rate_hz; }

  void EmitSample(size_t n, const State& state) {
    out_->displacement_m[n] = state.x_m;
    if (options_.record_velocity) out_->velocity_m_per_s[n] = state.v_m_per_s;
    out_->force_n[n] = BlockedForce(model_, drive_.Voltage(SampleTimeS(n)), state, problem_.mode);
    out_->in_contact[n] = problem_.mode.Any() ? 1 : 0;
  }

  // Emits every sample up to t_s (the end of the step, a located root or a recovered entry) from
  // the step's interpolating polynomial, in the current mode.
  void EmitSamplesThrough(double t_s) {
    if (next_sample_ >= sample_count_ || SampleTimeS(next_sample_) > t_s) return;
    LoadStepPolynomial();
    for (; next_sample_ < sample_count_ && SampleTimeS(next_sample_) <= t_s; ++next_sample_) {
      EmitSample(next_sample_, EvaluateStepPolynomial(SampleTimeS(next_sample_)));
    }
  }

  // Samples not reached: only when a restart fell within rounding of the record's end and the run
  // stopped there. They take the final state.
  void EmitRemainingSamples() {
    for (; next_sample_ < sample_count_; ++next_sample_)
      EmitSample(next_sample_, out_->final_state);
  }

  // The interpolant of the last step is the Nordsieck polynomial of degree q about t_n:
  //   y(t) = sum_{k=0..q} y^(k)(t_n) (t - t_n)^k / k!
  // Its coefficients come from CVodeGetDky(t_n, k), once per step; evaluating it per sample by
  // Horner's rule costs a few flops where a CVodeGetDky call per sample costs q vector operations
  // (that was 2/3 of the run time: ~30 samples per step at 51.2 kHz and 1e-10).
  void LoadStepPolynomial() {
    if (polynomial_loaded_) return;
    int order = 0;
    Check(CVodeGetLastOrder(sundials_.cvode, &order), "CVodeGetLastOrder", problem_);
    Check(CVodeGetCurrentTime(sundials_.cvode, &polynomial_time_s_), "CVodeGetCurrentTime", problem_);
    polynomial_.resize(static_cast<size_t>(order) + 1);
    double factorial = 1.0;
    for (int k = 0; k <= order; ++k) {
      if (k > 0) factorial *= k;
      Check(CVodeGetDky(sundials_.cvode, polynomial_time_s_, k, sundials_.sample), "CVodeGetDky", problem_);
      const State term = Read(sundials_.sample, problem_.size);
      polynomial_[static_cast<size_t>(k)] = {term.x_m / factorial, term.v_m_per_s / factorial,
                                             term.coil_force_n / factorial};
    }
    polynomial_loaded_ = true;
  }

  State EvaluateStepPolynomial(double t_s) const {
    const double dt_s = t_s - polynomial_time_s_;
    State state;
    for (size_t k = polynomial_.size(); k-- > 0;) {
      state.x_m = state.x_m * dt_s + polynomial_[k].x_m;
      state.v_m_per_s = state.v_m_per_s * dt_s + polynomial_[k].v_m_per_s;
      state.coil_force_n = state.coil_force_n * dt_s + polynomial_[k].coil_force_n;
    }
    return state;
  }

  bool FoundRoot(CvodeSurface surface) const {
    for (size_t i = 0; i < problem_.surfaces.size(); ++i)
      if (root_directions_[i] != 0 && problem_.surfaces[i] == surface) return true;
    return false;
  }

  // The mode after the roots CVODE found (directions: +1 rising, -1 falling), at displacement x.
  ContactMode ModeAfterRoots(ContactMode mode, double x_m) const {
    for (size_t i = 0; i < problem_.surfaces.size(); ++i) {
      const int direction = root_directions_[i];
      if (direction == 0) continue;
      switch (problem_.surfaces[i]) {
        case CvodeSurface::kLowerPenetration:
          if (direction > 0) mode.lower = true;  // entering the stop
          break;
        case CvodeSurface::kUpperPenetration:
          if (direction > 0) mode.upper = true;
          break;
        case CvodeSurface::kLowerForce:
          if (direction < 0) mode.lower = false;  // the stop would start pulling: it lets go
          if (direction > 0 && LowerPenetrationM(model_, x_m) > 0) mode.lower = true;  // pressed again
          break;
        case CvodeSurface::kUpperForce:
          if (direction < 0) mode.upper = false;
          if (direction > 0 && UpperPenetrationM(model_, x_m) > 0) mode.upper = true;
          break;
        case CvodeSurface::kApex:              // handled by RecoverMissedEntry
        case CvodeSurface::kDriveAtPlusLimit:  // a kink in time, not a mode
        case CvodeSurface::kDriveAtMinusLimit:
          break;
      }
    }
    return mode;
  }

  // Applies the roots found at t_root_s. Returns true when the run is over.
  bool HandleRoots(double t_root_s) {
    last_root_s_ = t_root_s;
    const ContactMode new_mode = ModeAfterRoots(problem_.mode, NV_Ith_S(sundials_.y, 0));
    const bool kink = FoundRoot(CvodeSurface::kDriveAtPlusLimit) || FoundRoot(CvodeSurface::kDriveAtMinusLimit);
    // No change (e.g. a damped stop that already let go is left behind): carry on with the step.
    if (new_mode == problem_.mode && !kink) return false;
    return SwitchAndRestart(t_root_s, new_mode);
  }

  // At an apex root: a stop that does not push but would, judged from the state (ModeFromState),
  // was entered and not seen, inside this step. Finds the entry instant by bisection on the step's
  // polynomial, between the step's start (or the last root in it) and the apex, emits the samples
  // before it and restarts there in contact; the rest of the step is discarded. Returns nothing
  // when no entry was missed, else whether the run is over.
  std::optional<bool> RecoverMissedEntry(double t_apex_s) {
    const ContactMode pushing = ModeFromState(model_, NV_Ith_S(sundials_.y, 0), NV_Ith_S(sundials_.y, 1));
    const ContactMode missed{pushing.lower && !problem_.mode.lower, pushing.upper && !problem_.mode.upper};
    if (!missed.Any()) {
      last_root_s_ = t_apex_s;
      return std::nullopt;
    }
    LoadStepPolynomial();
    double step_s = 0.0;
    Check(CVodeGetLastStep(sundials_.cvode, &step_s), "CVodeGetLastStep", problem_);
    auto missed_stop_pushes = [&](double t_s) {
      const State state = EvaluateStepPolynomial(t_s);
      const ContactMode mode = ModeFromState(model_, state.x_m, state.v_m_per_s);
      return (missed.lower && mode.lower) || (missed.upper && mode.upper);
    };
    double outside_s = std::max(polynomial_time_s_ - step_s, last_root_s_);
    double inside_s = t_apex_s;
    if (missed_stop_pushes(outside_s)) inside_s = outside_s;  // cannot look further back
    while (inside_s - outside_s > 2.0 * std::numeric_limits<double>::epsilon() * std::abs(inside_s)) {
      const double middle_s = 0.5 * (outside_s + inside_s);
      if (middle_s <= outside_s || middle_s >= inside_s) break;
      (missed_stop_pushes(middle_s) ? inside_s : outside_s) = middle_s;
    }
    EmitSamplesThrough(inside_s);
    Write(EvaluateStepPolynomial(inside_s), problem_.size, sundials_.y);
    ContactMode new_mode = problem_.mode;
    new_mode.lower = new_mode.lower || missed.lower;
    new_mode.upper = new_mode.upper || missed.upper;
    return SwitchAndRestart(inside_s, new_mode);
  }

  // Switches to new_mode at t_s, from the state in sundials_.y, recording the contacts that start
  // and end there. Returns true when t_s is the record's end (within rounding), too close to restart.
  bool SwitchAndRestart(double t_s, const ContactMode& new_mode) {
    contacts_->Update(t_s, new_mode);
    problem_.mode = new_mode;
    last_root_s_ = t_s;
    if (end_s_ - t_s <= 8.0 * std::numeric_limits<double>::epsilon() * end_s_) return true;
    // Restart from the located state: the vector field (or the drive's slope) has changed, and the
    // multistep history must not straddle the switch. CVodeReInit keeps the root functions, the
    // tolerances and the linear solver; the stop time is set again rather than relying on whether
    // a restart keeps it.
    Check(CVodeReInit(sundials_.cvode, t_s, sundials_.y), "CVodeReInit", problem_);
    Check(CVodeSetStopTime(sundials_.cvode, end_s_), "CVodeSetStopTime", problem_);
    return false;
  }

  const ActuatorModel& model_;
  const SineDrive& drive_;
  const SimulationOptions& options_;
  Record* out_;
  const size_t sample_count_;
  const double end_s_;  // t = N / fs, where final_state is taken [s]
  Problem problem_;
  SundialsObjects sundials_;
  std::vector<int> root_directions_;  // CVodeGetRootInfo: +1 rising, -1 falling, 0 no root
  double last_root_s_ = 0.0;          // the last root or restart [s]: the mode is known there
  size_t next_sample_ = 0;
  std::optional<ContactLog> contacts_;  // from the start of the run
  bool polynomial_loaded_ = false;    // the coefficients below belong to the last step
  double polynomial_time_s_ = 0.0;    // t_n, the end of the last step [s]
  std::vector<State> polynomial_;     // y^(k)(t_n) / k!, k = 0 .. q [the state's units / s^k]
};

class CvodeEngine final : public Engine {
 public:
  Method method() const override { return Method::kCvode; }


 protected:
  void Run(const ActuatorModel& model, const SineDrive& drive, const SimulationOptions& options,
           Record* out) const override {
    CvodeRun(model, drive, options, out).Run();
  }
};

}  // namespace

std::unique_ptr<Engine> MakeCvodeEngine() { return std::make_unique<CvodeEngine>(); }

}  // namespace strokelab
