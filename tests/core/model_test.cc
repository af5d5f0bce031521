#include "strokelab/model/model.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "strokelab/base/errors.h"

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

}  // namespace
}  // namespace strokelab
