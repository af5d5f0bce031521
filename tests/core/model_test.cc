#include "strokelab/model/model.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "strokelab/base/errors.h"
#include "strokelab/model/dynamics.h"

namespace strokelab {
namespace {

using ::testing::HasSubstr;

std::string ValidationMessage(const ActuatorModel& model) {
  try {
    Validate(model);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(ModelTest, PaperPresetIsTable2) {
  const ActuatorModel m = PresetModel("paper");
  EXPECT_EQ(m.mass_kg, 0.032);
  EXPECT_EQ(m.damping_n_s_per_m, 1.3);
  EXPECT_EQ(m.stiffness_n_per_m, 124.0);
  EXPECT_EQ(m.contact_damping_n_s_per_m, 0.0);
  EXPECT_EQ(m.contact_stiffness, 1.3e6);
  EXPECT_EQ(m.gain_n_per_v, 0.3);
  EXPECT_EQ(m.lower_stop_m, -1e-3);
  EXPECT_FALSE(m.HasUpperStop());
  EXPECT_TRUE(m.IsPiecewiseLinear());
  EXPECT_NO_THROW(Validate(m));
}

TEST(ModelTest, RejectsBadValuesNamingTheField) {
  ActuatorModel m = PaperModel();
  m.mass_kg = -0.1;
  EXPECT_THAT(ValidationMessage(m), HasSubstr("m_p: must be > 0"));
  m = PaperModel();
  m.stiffness_n_per_m = std::nan("");
  EXPECT_THAT(ValidationMessage(m), HasSubstr("k_p: must be a finite number"));
  m = PaperModel();
  m.lower_stop_m = 1e-3;
  EXPECT_THAT(ValidationMessage(m), HasSubstr("d: the lower stop must lie at or below"));
  m = PaperModel();
  m.contact_damping_n_s_per_m = -1;
  EXPECT_THAT(ValidationMessage(m), HasSubstr("c_s: must be >= 0"));
}

TEST(ModelTest, RefusesAbsurdModelsNamingTheField) {
  // Issue 15: these passed the sign checks and then hung every engine.
  ActuatorModel m = PaperModel();
  m.contact_stiffness = 1e40;
  EXPECT_THAT(ValidationMessage(m), HasSubstr("k_s: makes the stop's stiffness 8.06452e+37 times the suspension"));
  m = PaperModel();
  m.mass_kg = 1e-300;
  EXPECT_THAT(ValidationMessage(m), HasSubstr("m_p: must lie within [1e-06, 1000] kg, got 1e-300"));
  m = PaperModel();
  m.mass_kg = 1e-6;
  m.contact_stiffness = 1e8;  // 1.6 MHz on 1 mg
  EXPECT_THAT(ValidationMessage(m), HasSubstr("k_s: makes the stop's natural frequency"));
  m = PaperModel();
  m.damping_n_s_per_m = 1e5;
  EXPECT_THAT(ValidationMessage(m), HasSubstr("c_p: makes the suspension's damping ratio"));
  m = PaperModel();
  m.contact_damping_n_s_per_m = 1e9;
  EXPECT_THAT(ValidationMessage(m), HasSubstr("c_s: makes the stop's damping ratio"));
  m = PaperModel();
  m.cubic_stiffness_n_per_m3 = -1e18;
  EXPECT_THAT(ValidationMessage(m), HasSubstr("k3: makes k3 L^2"));
  m = PaperModel();
  m.stiffness_n_per_m = 1e14;
  EXPECT_THAT(ValidationMessage(m), HasSubstr("k_p: makes the suspension's natural frequency"));
}

TEST(ModelTest, KeepsEveryRealActuator) {
  // The extended models of the diagnosis and the tests' extremes stay valid.
  ActuatorModel m = PaperModel();
  m.contact_law = ContactLaw::kHertzian;
  m.contact_stiffness = 1e12;  // N/m^1.5
  m.cubic_stiffness_n_per_m3 = -1e12;
  m.quadratic_stiffness_n_per_m2 = 1e6;
  m.friction_force_n = 0.5;
  m.amplifier_limit_v = 1.0;
  m.upper_stop_m = 2e-3;
  m.contact_damping_n_s_per_m = 50;
  EXPECT_EQ(ValidationMessage(m), "");
  m = PaperModel();
  m.contact_stiffness = 4e10;  // the wrong-physics candidates' former top (N/m)
  EXPECT_EQ(ValidationMessage(m), "");
  m.mass_kg = 1e-6;  // a MEMS proof mass with the paper's stop
  m.contact_stiffness = 1.3e6;
  EXPECT_EQ(ValidationMessage(m), "");
  m.mass_kg = 1e3;
  EXPECT_EQ(ValidationMessage(m), "");
}

TEST(ModelTest, OverridesByKeyAndByJsonName) {
  ActuatorModel m = PaperModel();
  ApplyOverride(&m, "k3=4e7");
  ApplyOverride(&m, "gain_n_per_v=0.25");
  ApplyOverride(&m, "d_upper=2e-3");
  ApplyOverride(&m, "contact_law=hertzian");
  EXPECT_EQ(m.cubic_stiffness_n_per_m3, 4e7);
  EXPECT_EQ(m.gain_n_per_v, 0.25);
  EXPECT_EQ(m.upper_stop_m, 2e-3);
  EXPECT_EQ(m.contact_law, ContactLaw::kHertzian);
  EXPECT_FALSE(m.IsPiecewiseLinear());
  EXPECT_THAT(m.NonlinearTerms(), HasSubstr("k3"));
  EXPECT_THAT(m.NonlinearTerms(), HasSubstr("Hertzian"));
}

TEST(ModelTest, OverrideErrorsNameTheKey) {
  ActuatorModel m = PaperModel();
  try {
    ApplyOverride(&m, "k9=1");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "k9");
    EXPECT_THAT(e.what(), HasSubstr("unknown model parameter"));
  }
  try {
    ApplyOverride(&m, "k_p=abc");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "k_p");
    EXPECT_THAT(e.what(), HasSubstr("expected a number, got 'abc'"));
  }
  EXPECT_THROW(ApplyOverride(&m, "k_p=nan"), InputError);
  EXPECT_THROW(ApplyOverride(&m, "k_p"), InputError);
  EXPECT_THROW(PresetModel("papr"), InputError);
}

// The smoothed friction's derivatives (dynamics.cc, which computes tanh(v / v_s) once for the force, its
// slope and its parameter derivatives) against central differences of BlockedForce, at F_c = 0 too,
// where a fit starting without friction still needs d f / d F_c = -tanh(v / v_s).
TEST(DynamicsTest, FrictionDerivativesAreTheForcesDifferences) {
  using M = ActuatorModel;
  for (const double friction_n : {0.0, 0.01}) {
    ActuatorModel m = PaperModel();
    m.friction_force_n = friction_n;
    m.friction_velocity_m_per_s = 2e-3;
    for (const double v : {-3e-3, 5e-4, 4e-3}) {
      SCOPED_TRACE("F_c " + std::to_string(friction_n) + " N, v " + std::to_string(v) + " m/s");
      const State y{1e-4, v};
      const ForceJacobian j = BlockedForceJacobian(m, 0.2, y, {});
      auto force_with = [&](double M::*field, double value) {
        ActuatorModel changed = m;
        changed.*field = value;
        return BlockedForce(changed, 0.2, y, {});
      };
      // f is linear in F_c: the difference is exact to rounding.
      const double h_f = 1e-3;
      const double df_dfriction = BlockedForceParameterDerivative(m, &M::friction_force_n, 0.2, y, {}, j);
      EXPECT_NEAR(df_dfriction,
                  (force_with(&M::friction_force_n, friction_n + h_f) -
                   force_with(&M::friction_force_n, friction_n - h_f)) / (2 * h_f),
                  1e-12);
      EXPECT_NEAR(df_dfriction, -std::tanh(v / 2e-3), 1e-15);
      // v_s and v: truncation (h^2 / 6 times a third derivative ~ F_c v / v_s^4) far below the bounds,
      // rounding (1e-16 N over 1e-8) too.
      const double h_s = 1e-8, h_v = 1e-8, bound = 1e-6 * std::max(1.0, friction_n / 2e-3);
      EXPECT_NEAR(BlockedForceParameterDerivative(m, &M::friction_velocity_m_per_s, 0.2, y, {}, j),
                  (force_with(&M::friction_velocity_m_per_s, 2e-3 + h_s) -
                   force_with(&M::friction_velocity_m_per_s, 2e-3 - h_s)) / (2 * h_s),
                  bound);
      const double dv =
          (BlockedForce(m, 0.2, State{1e-4, v + h_v}, {}) - BlockedForce(m, 0.2, State{1e-4, v - h_v}, {})) / (2 * h_v);
      EXPECT_NEAR(j.d_dv_n_s_per_m, dv, bound);
      EXPECT_EQ(j.force_n, BlockedForce(m, 0.2, y, {}));
    }
  }
}

}  // namespace
}  // namespace strokelab
