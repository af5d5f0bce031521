// An extended fit whose defect-correction passes are cut off before they settle must say so where
// its numbers are read: the candidate is not converged, and each parameter the last pass still moved
// carries how far it moved (extended_fit.cc), since its standard error does not hold the distance
// still to go. A converged candidate carries no such note.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "strokelab/diagnose/diagnose.h"
#include "strokelab/data/synth.h"

namespace strokelab {
namespace {

bool StillMoving(const FitParameter& p) { return p.note.find("still moving: the last pass changed it by") != std::string::npos; }

TEST(UnconvergedFit, ParametersTheLastPassMovedSaySo) {
  SynthOptions o;
  o.frequencies_hz = {5, 6, 7, 8, 9, 11};
  o.amplitudes_v = {0.1, 0.3, 0.4, 0.5};
  o.settle_s = 5.0;
  o.noise_rms_v = 0.0005;
  o.perturb = {{"k_p", 0.1}, {"c_p", 0.1}, {"g", 0.1}, {"d", 0.1}};
  o.seed = 1002;
  ActuatorModel truth = PaperModel();
  truth.cubic_stiffness_n_per_m3 = 1.5e7;
  const Synthesis s = Synthesize(truth, o);

  DiagnoseOptions options;
  options.max_passes = 1;  // k3 moves from 0 by ~0.5 in theta in the first pass: far from settled
  options.pairs = false;
  options.max_seconds = 20;
  const Diagnosis d = DiagnoseCampaign(s.campaign, options);

  const CandidateFit* cubic = nullptr;
  for (const CandidateFit& c : d.candidates) {
    if (c.label == "cubic_stiffness") cubic = &c;
    if (!c.converged) continue;
    for (const FitParameter& p : c.parameters) {
      EXPECT_FALSE(StillMoving(p)) << c.label << " " << p.name << ": " << p.note;
    }
  }
  ASSERT_NE(cubic, nullptr);
  ASSERT_TRUE(cubic->fitted) << cubic->note;
  EXPECT_FALSE(cubic->converged);
  EXPECT_EQ(cubic->passes, 1);
  const FitParameter* k3 = nullptr;
  for (const FitParameter& p : cubic->parameters)
    if (p.name == "k3") k3 = &p;
  ASSERT_NE(k3, nullptr);
  EXPECT_TRUE(StillMoving(*k3)) << k3->note;
  std::printf("k3 = %.4g +- %.2g N/m^3 (%s)\n", k3->value, k3->standard_error, k3->note.c_str());
}

}  // namespace
}  // namespace strokelab
