// The extended fit (identify/extended_fit.h) is one nonlinear least-squares problem on exact
// Jacobians: converged means Ceres' own convergence test held, a fit cut off before it says so, and
// the standard errors from the Jacobian at the solution hold the truth.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "strokelab/data/synth.h"
#include "strokelab/identify/extended_fit.h"
#include "strokelab/identify/fit.h"

namespace strokelab {
namespace {

using internal::ExtendedFitOptions;
using internal::ExtendedFitResult;
using internal::ExtendedProblem;
using internal::FreeParameter;

// A concealed cubic suspension term (k3 = 1.5e7 N/m^3) on the paper's actuator with its linear
// parameters perturbed, the campaign of the diagnosis tests.
struct CubicCampaign {
  Synthesis synthesis;
  std::vector<RecordAnalysis> analyses;
  std::vector<const RecordAnalysis*> records;
};

CubicCampaign MakeCubicCampaign() {
  SynthOptions o;
  o.frequencies_hz = {5, 6, 7, 8, 9, 11};
  o.amplitudes_v = {0.1, 0.3, 0.4, 0.5};
  o.settle_s = 5.0;
  o.noise_rms_v = 0.0005;
  o.perturb = {{"k_p", 0.1}, {"c_p", 0.1}, {"g", 0.1}, {"d", 0.1}};
  o.seed = 1002;
  ActuatorModel truth = PaperModel();
  truth.cubic_stiffness_n_per_m3 = 1.5e7;
  CubicCampaign c{Synthesize(truth, o), {}, {}};
  for (const Recording& r : c.synthesis.campaign.records)
    c.analyses.push_back(AnalyseRecord(r, c.synthesis.campaign.response, FitOptions{}));
  for (const RecordAnalysis& a : c.analyses) c.records.push_back(&a);
  return c;
}

FreeParameter LogFree(std::string name, double ActuatorModel::*field, double start) {
  FreeParameter p;
  p.name = std::move(name);
  p.field = field;
  p.start = start;
  p.theta_min = 1.0 - std::log(2.0);
  p.theta_max = 1.0 + std::log(2.0);
  return p;
}

// The paper's parameters free from their nominal values and k3 from 0 (linear, 1e6 N/m^3 per theta).
ExtendedProblem CubicProblem() {
  const ActuatorModel start = PaperModel();
  ExtendedProblem problem;
  problem.base = start;
  problem.parameters = {LogFree("k_p", &ActuatorModel::stiffness_n_per_m, start.stiffness_n_per_m),
                        LogFree("c_p", &ActuatorModel::damping_n_s_per_m, start.damping_n_s_per_m),
                        LogFree("g", &ActuatorModel::gain_n_per_v, start.gain_n_per_v),
                        LogFree("d", &ActuatorModel::lower_stop_m, start.lower_stop_m),
                        LogFree("k_s", &ActuatorModel::contact_stiffness, start.contact_stiffness)};
  FreeParameter k3;
  k3.name = "k3";
  k3.field = &ActuatorModel::cubic_stiffness_n_per_m3;
  k3.log_scale = false;
  k3.start = 0.0;
  k3.scale = 1e6;
  k3.theta_min = 1.0 - 100.0;
  k3.theta_max = 1.0 + 100.0;
  problem.parameters.push_back(k3);
  return problem;
}

TEST(ExtendedFitTest, ConvergesAndItsStandardErrorsHoldTheTruth) {
  const CubicCampaign c = MakeCubicCampaign();
  const ExtendedFitResult r =
      internal::FitExtended(c.records, c.synthesis.campaign.response, CubicProblem(), ExtendedFitOptions{});
  EXPECT_TRUE(r.converged) << r.report;
  for (const FitParameter& p : r.parameters) {
    const double truth = c.synthesis.model.*(FindParameter(p.name).field);
    ASSERT_TRUE(std::isfinite(p.standard_error) && p.standard_error > 0) << p.name;
    // One campaign: a z-score beyond 4 happens by chance once in 16,000 (the study script checks
    // the distribution over many seeds).
    EXPECT_LT(std::abs(p.value - truth), 4.0 * p.standard_error)
        << p.name << " = " << p.value << " +- " << p.standard_error << ", truth " << truth;
  }
}

// An amplifier limit between 1 and 4 V on records driven at 0.5 V at most never clips: the records say
// nothing of it, so it gets no standard error and the fit says it is not identifiable.
TEST(ExtendedFitTest, AParameterTheRecordsDoNotConstrainIsNotIdentifiable) {
  const CubicCampaign c = MakeCubicCampaign();
  ExtendedProblem problem = CubicProblem();
  problem.parameters.push_back(LogFree("amplifier_limit_v", &ActuatorModel::amplifier_limit_v, 2.0));
  const ExtendedFitResult r = internal::FitExtended(c.records, c.synthesis.campaign.response, problem, ExtendedFitOptions{});
  EXPECT_FALSE(r.converged);
  EXPECT_NE(r.report.find("NOT IDENTIFIABLE from these records: amplifier_limit_v"), std::string::npos) << r.report;
  for (const FitParameter& p : r.parameters) {
    SCOPED_TRACE(p.name);
    if (p.name == "amplifier_limit_v") {
      EXPECT_FALSE(p.identifiable);
      EXPECT_TRUE(std::isnan(p.standard_error));
    } else {
      EXPECT_TRUE(p.identifiable);
      EXPECT_TRUE(std::isfinite(p.standard_error));
    }
  }
}

// k3's range ends at 5e6 N/m^3, a third of the truth: the records push it against that bound. The fit
// holds it there and converges in the others (Ceres alone crawls along the bound), and says so: no
// standard error for k3, and a note naming it.
TEST(ExtendedFitTest, AParameterPushedAgainstItsBoundIsHeldThereAndSaysSo) {
  const CubicCampaign c = MakeCubicCampaign();
  ExtendedProblem problem = CubicProblem();
  problem.parameters.back().theta_max = 1.0 + 5.0;  // k3 <= 5e6 N/m^3
  const ExtendedFitResult r = internal::FitExtended(c.records, c.synthesis.campaign.response, problem, ExtendedFitOptions{});
  // The capped model cannot fit these records; whether its fit converges (k_s may be pushed to its own
  // bound to make up for k3, and the sampling corrections may then keep moving) is not what is tested:
  // every parameter held at a bound says so and has no standard error, every other one has one.
  const size_t held = r.report.find("held at a bound of its range (the records push it beyond): ");
  ASSERT_NE(held, std::string::npos) << r.report;
  const std::string held_names = r.report.substr(held);
  EXPECT_NE(held_names.find("k3"), std::string::npos) << r.report;
  for (const FitParameter& p : r.parameters) {
    SCOPED_TRACE(p.name);
    const bool is_held = p.note.find("held at a bound") != std::string::npos;
    if (p.name == "k3") {
      EXPECT_NEAR(p.value, 5e6, 1.0);
      EXPECT_TRUE(is_held);
    }
    if (is_held) {
      EXPECT_FALSE(p.identifiable);
      EXPECT_TRUE(std::isnan(p.standard_error));
      EXPECT_NE(held_names.find(p.name), std::string::npos) << r.report;
    } else {
      EXPECT_TRUE(std::isfinite(p.standard_error)) << p.note;
    }
  }
}

// The passes' divergence test on moves (in standard errors) seen in a 72-record diagnosis: the right
// effect's passes (1290 then 1.1: contracting fast) go on; a wrong effect's that grow (0.219 then 4.95)
// or shrink too slowly for the tolerance of 0.01 in the solves left (0.0766 then 0.0549, 5 left:
// 0.717^5 / 0.283 x 0.0549 = 0.037) stop. Geometric moves of ratio 0.1 from 0.1 meet the tolerance
// within 2 more solves (0.1^2 / 0.9 x 0.01 = 1.1e-4) and go on; with 0 left they stop.
TEST(ExtendedFitTest, PassesThatDoNotContractStopAndSayWhy) {
  EXPECT_EQ(internal::PassesNotContracting(1.1, 1290, 6), "");
  EXPECT_EQ(internal::PassesNotContracting(4.95, 0.219, 5),
            "the passes stopped: they do not contract (moves of 0.219 then 4.95 standard errors)");
  EXPECT_EQ(internal::PassesNotContracting(0.0549, 0.0766, 5),
            "the passes stopped: they contract too slowly to settle in the 5 solves left (moves of 0.0766 then "
            "0.0549 standard errors)");
  EXPECT_EQ(internal::PassesNotContracting(0.01 * 1.0001, 0.1, 2), "");
  EXPECT_NE(internal::PassesNotContracting(0.02, 0.1, 0), "");
  EXPECT_NE(internal::PassesNotContracting(0.05, 0.05, 7), "");  // theta = 1: a constant move never settles
}

// The move between solves allowed as the sampling corrections' jitter: a parameter that jitters by
// delta standard errors has sqrt(1 + delta^2) times the error, an excess of 1 / sqrt(2 dof) (the
// standard error's own relative uncertainty; 0.0378 at dof 350, delta 0.2775). Fewer residuals allow more.
TEST(ExtendedFitTest, TheJitterAllowedIsWithinTheStandardErrorsOwnUncertainty) {
  EXPECT_NEAR(internal::JitterAllowance(350), 0.2775, 5e-4);
  for (const size_t dof : {size_t{10}, size_t{350}, size_t{100000}}) {
    const double delta = internal::JitterAllowance(dof);
    EXPECT_NEAR(std::sqrt(1.0 + delta * delta) - 1.0, 1.0 / std::sqrt(2.0 * static_cast<double>(dof)), 1e-12);
  }
  EXPECT_GT(internal::JitterAllowance(10), internal::JitterAllowance(350));
}

// A floor probe (the coil's tau_e in the diagnosis) looks first at the model with the parameter on its
// lower bound. Here k3 starts at 3e7 N/m^3 over records of k3 = 1.5e7. With its floor at 2e7, the
// Gauss-Newton step from the floor lowers it: the fit stops there and says so, where the fit without
// the probe ends after its iterations (k3 held at that bound). With the floor at 5e6 the step raises
// it, and the fit goes on as without the probe.
TEST(ExtendedFitTest, AFloorProbeStopsWhereTheRecordsAskForLessThanTheFloor) {
  const CubicCampaign c = MakeCubicCampaign();
  const ResponseKind kind = c.synthesis.campaign.response;
  ExtendedProblem problem = CubicProblem();
  const int k3 = static_cast<int>(problem.parameters.size()) - 1;
  problem.parameters[k3].start = 3e7;
  problem.parameters[k3].theta_min = 1.0 - 10.0;  // 2e7 N/m^3
  ExtendedFitOptions probed;
  probed.floor_probe = k3;
  const ExtendedFitResult stopped = internal::FitExtended(c.records, kind, problem, probed);
  const ExtendedFitResult full = internal::FitExtended(c.records, kind, problem, ExtendedFitOptions{});
  EXPECT_FALSE(stopped.floored.empty());
  EXPECT_FALSE(stopped.converged);
  EXPECT_NE(stopped.report.find("NOT FITTED: the records ask for less k3 than its floor (at its floor, 2e+07"),
            std::string::npos) << stopped.report;
  EXPECT_EQ(stopped.iterations, 0);
  EXPECT_NEAR(stopped.model.cubic_stiffness_n_per_m3, 2e7, 1.0);
  EXPECT_NEAR(full.model.cubic_stiffness_n_per_m3, 2e7, 1.0) << full.report;
  const size_t held = full.report.find("held at a bound of its range (the records push it beyond): ");
  ASSERT_NE(held, std::string::npos) << full.report;
  EXPECT_NE(full.report.find("k3", held), std::string::npos) << full.report;

  problem.parameters[k3].theta_min = 1.0 - 25.0;  // 5e6 N/m^3
  const ExtendedFitResult fitted = internal::FitExtended(c.records, kind, problem, probed);
  EXPECT_TRUE(fitted.floored.empty()) << fitted.floored;
  EXPECT_TRUE(fitted.converged) << fitted.report;
  const FitParameter& k3_fitted = fitted.parameters[k3];
  EXPECT_LT(std::abs(k3_fitted.value - 1.5e7), 4.0 * k3_fitted.standard_error) << k3_fitted.value;
}

TEST(ExtendedFitTest, CutOffBeforeCeresConvergesSaysSo) {
  const CubicCampaign c = MakeCubicCampaign();
  ExtendedFitOptions options;
  options.max_iterations = 1;  // k3 starts at 0, 1.5e7 away: one Levenberg-Marquardt step is not enough
  const ExtendedFitResult r = internal::FitExtended(c.records, c.synthesis.campaign.response, CubicProblem(), options);
  EXPECT_FALSE(r.converged);
  EXPECT_NE(r.report.find("NOT CONVERGED: Ceres did not meet its convergence test"), std::string::npos) << r.report;
}

}  // namespace
}  // namespace strokelab
