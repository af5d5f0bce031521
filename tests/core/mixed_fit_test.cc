// The joint fit of a mixed campaign (identify/mixed_campaign.h): stepped sines and multisines of one
// actuator, synthesised with known truth, fit to the same parameters as each half alone, within that
// half's standard errors, and to smaller errors than either half's.
#include "strokelab/identify/mixed_campaign.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <string>

#include "strokelab/base/errors.h"
#include "strokelab/data/synth.h"
#include "strokelab/identify/broadband_campaign.h"
#include "strokelab/identify/extended_fit.h"
#include "strokelab/model/model.h"

namespace strokelab {
namespace {

// The paper's model, each parameter moved off the data sheet's (the fits start from the data sheet's
// or from the records).
ActuatorModel MixedTruth() {
  ActuatorModel m = PaperModel();
  m.stiffness_n_per_m *= 1.06;
  m.damping_n_s_per_m *= 0.92;
  m.gain_n_per_v *= 1.04;
  m.lower_stop_m *= 0.97;
  m.contact_stiffness *= 0.8;
  return m;
}

// Stepped sines over 5..11 Hz at 0.1, 0.3 and 0.5 V (the upper two reach the stop), force response.
Campaign SteppedHalf(const ActuatorModel& truth) {
  SynthOptions o;
  o.frequencies_hz = {5, 6, 7, 8, 9, 11};
  o.amplitudes_v = {0.1, 0.3, 0.5};
  o.settle_s = 5.0;
  o.noise_rms_v = 5e-4;
  o.offset_v = 0.01;
  o.hum_v = 5e-4;
  o.seed = 2611;
  return Synthesize(truth, o).campaign;
}

// Odd multisines over 2..200 Hz at 0.1 (clear) and 0.6 V rms (impacts), 1 s at 8192 Hz each.
Campaign BroadbandHalf(const ActuatorModel& truth) {
  SynthOptions o;
  o.excitation = Excitation::kMultisine;
  o.levels_v_rms = {0.1, 0.6};
  o.duration_s = 1.0;
  o.settle_s = 2.0;
  o.sample_rate_hz = 8192.0;
  o.noise_rms_v = 2e-4;
  o.offset_v = 3e-3;
  o.hum_v = 5e-4;
  o.seed = 2612;
  Campaign c = Synthesize(truth, o).campaign;
  for (Recording& r : c.records) r.name = "broadband-" + r.name;  // unique beside the stepped records' names
  return c;
}

double ActuatorModel::*FieldNamed(const std::string& name) {
  if (name == "k_p") return &ActuatorModel::stiffness_n_per_m;
  if (name == "c_p") return &ActuatorModel::damping_n_s_per_m;
  if (name == "g") return &ActuatorModel::gain_n_per_v;
  if (name == "d") return &ActuatorModel::lower_stop_m;
  return &ActuatorModel::contact_stiffness;
}

const FitParameter* Named(const std::vector<FitParameter>& parameters, const std::string& name) {
  for (const FitParameter& p : parameters)
    if (p.name == name) return &p;
  return nullptr;
}

TEST(MixedCampaign, FitsJointlyToTheParametersOfEachHalf) {
  const ActuatorModel truth = MixedTruth();
  const Campaign stepped = SteppedHalf(truth), broadband = BroadbandHalf(truth);
  Campaign mixed = stepped;
  mixed.records.insert(mixed.records.end(), broadband.records.begin(), broadband.records.end());

  const FitResult stepped_fit = FitCampaign(stepped);
  ASSERT_TRUE(stepped_fit.refinement.converged) << stepped_fit.refinement.report;
  const BroadbandCampaignFit broadband_fit = FitBroadbandCampaign(broadband, FitOptions{});
  ASSERT_TRUE(broadband_fit.result.fit.converged) << broadband_fit.result.fit.report;
  ASSERT_FALSE(broadband_fit.result.rejected) << broadband_fit.result.fit.report;
  const MixedCampaignFit joint = FitMixedCampaign(mixed, FitOptions{});
  const internal::ExtendedFitResult& fit = joint.result.fit;
  ASSERT_TRUE(fit.converged) << fit.report;
  EXPECT_FALSE(joint.result.rejected) << fit.report;
  EXPECT_EQ(joint.stepped_used, joint.result.stepped.size());
  EXPECT_GE(joint.stepped_used, stepped.records.size() - 2);  // the refinement uses nearly every record
  EXPECT_EQ(joint.result.records.size(), broadband.records.size());

  for (const char* name : {"k_p", "c_p", "g", "d", "k_s"}) {
    const FitParameter* j = Named(fit.parameters, name);
    const FitParameter* s = stepped_fit.Find(name);
    const FitParameter* b = Named(broadband_fit.result.fit.parameters, name);
    ASSERT_TRUE(j && s && b) << name;
    ASSERT_TRUE(j->identifiable && std::isfinite(s->standard_error) && std::isfinite(b->standard_error)) << name;
    const std::string values = std::string(name) + ": joint " + std::to_string(j->value) + " +- " +
                               std::to_string(j->standard_error) + ", stepped " + std::to_string(s->value) + " +- " +
                               std::to_string(s->standard_error) + ", broadband " + std::to_string(b->value) +
                               " +- " + std::to_string(b->standard_error);
    // The joint estimate is nearly the halves' error-weighted mean: its difference from a half has a
    // variance below that half's (se_half^2 - se_joint^2), so 3 of the half's errors is a 3-sigma bound.
    EXPECT_LT(std::abs(j->value - s->value), 3.0 * s->standard_error) << values;
    EXPECT_LT(std::abs(j->value - b->value), 3.0 * b->standard_error) << values;
    // Both halves' information: the joint error is below either half's (5 % for the residual variance's
    // own spread).
    EXPECT_LT(j->standard_error, 1.05 * std::min(s->standard_error, b->standard_error)) << values;
    // And the truth within 4 of the joint errors.
    EXPECT_LT(std::abs(j->value - truth.*FieldNamed(name)), 4.0 * j->standard_error)
        << values;
  }
  // A second method for the joint errors: the halves' information added, (C_s^-1 + C_b^-1)^-1, with C_b
  // the broadband half's covariance and C_s the extended fit's (extended_fit.h) of the stepped records
  // the joint fit took, at the same parameters. The two agree to within the linearisation about two
  // solutions a few standard errors apart (10 %; 2 % seen). The errors a half's marginal errors alone would give,
  // 1 / sqrt(1 / se_s^2 + 1 / se_b^2), are far larger: the halves pin down different combinations.
  std::vector<std::string> warnings;
  const std::vector<RecordAnalysis> analyses = AnalyseCampaign(stepped, FitOptions{}, &warnings);
  std::vector<const RecordAnalysis*> used;
  for (size_t i = 0; i < analyses.size(); ++i)
    if (joint.stepped.records[i].used_refinement) used.push_back(&analyses[i]);
  internal::ExtendedProblem problem;
  problem.base = joint.stepped.model;
  for (const char* name : {"k_p", "c_p", "g", "d", "k_s"}) {
    double ActuatorModel::*field = FieldNamed(name);
    problem.parameters.push_back(internal::LogParameter(name, "", field, joint.stepped.model.*field, 3.0));
  }
  const internal::ExtendedFitResult stepped_alone =
      internal::FitExtended(used, ResponseKind::kForce, problem, internal::ExtendedFitOptions{});
  ASSERT_TRUE(stepped_alone.converged) << stepped_alone.report;
  const Eigen::Map<const Eigen::Matrix<double, 5, 5, Eigen::RowMajor>> c_s(stepped_alone.covariance.data());
  const Eigen::Map<const Eigen::Matrix<double, 5, 5, Eigen::RowMajor>> c_b(broadband_fit.result.fit.covariance.data());
  ASSERT_EQ(broadband_fit.result.fit.parameters.size(), 5u);
  const Eigen::Matrix<double, 5, 5> added = (c_s.inverse() + c_b.inverse()).inverse();
  for (int i = 0; i < 5; ++i) {
    const FitParameter& j = fit.parameters[i];
    EXPECT_NEAR(j.standard_error / std::sqrt(added(i, i)), 1.0, 0.1)
        << j.name << ": joint " << j.standard_error << ", from the halves' information " << std::sqrt(added(i, i));
  }

  // Each half's records are left with their noise: chi-square per residual near 1.
  for (const internal::SteppedRecordFit& r : joint.result.stepped)
    EXPECT_LT(r.chi2 / static_cast<double>(r.residuals), 3.0) << r.name;
  for (const internal::BroadbandRecordFit& r : joint.result.records) EXPECT_NEAR(r.chi2_per_sample, 1.0, 0.08) << r.name;
}

// Without the refinement only the stepped-sine fit has staged estimates to stop at.
TEST(MixedCampaign, WithoutTheRefinementOnlyTheSteppedSinesAreFitted) {
  Campaign stepped, broadband, mixed;
  stepped.records.resize(2);
  broadband.records.resize(2);
  for (Recording& r : broadband.records) r.broadband = true;
  mixed.records = {stepped.records[0], broadband.records[0]};
  FitOptions staged;
  staged.refine = false;
  EXPECT_EQ(FitKindOf(mixed), CampaignFitKind::kMixed);
  EXPECT_EQ(FitKindOf(mixed, staged), CampaignFitKind::kSteppedSine);
  EXPECT_EQ(FitKindOf(stepped, staged), CampaignFitKind::kSteppedSine);
  EXPECT_EQ(FitKindOf(broadband, FitOptions{}), CampaignFitKind::kBroadband);
  try {
    FitKindOf(broadband, staged);
    FAIL() << "a broadband campaign has no staged estimates";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "refine");
  }
}

TEST(MixedCampaign, RefusesACampaignOfOneKind) {
  const Campaign stepped = SteppedHalf(MixedTruth());
  try {
    FitMixedCampaign(stepped, FitOptions{});
    FAIL() << "no broadband record";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "records");
    EXPECT_NE(std::string(e.what()).find("holds 18 and 0"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace strokelab
