// One candidate of the diagnosis fitted on every record (diagnose.h FitCandidate), the entry point of
// the z-score study (fit_study.cc): an effect that cannot show in the campaign is refused by name.
#include <gtest/gtest.h>

#include <vector>

#include "strokelab/base/errors.h"
#include "strokelab/data/synth.h"
#include "strokelab/diagnose/diagnose.h"

namespace strokelab {
namespace {

TEST(FitCandidateTest, RefusesAContactEffectOnACampaignClearOfTheStop) {
  SynthOptions o;
  o.frequencies_hz = {5, 6, 7, 8, 9, 11};
  o.amplitudes_v = {0.1};  // the paper's actuator stays clear of its stop at 0.1 V
  o.settle_s = 5.0;
  o.noise_rms_v = 0.0005;
  const Synthesis s = Synthesize(PaperModel(), o);
  const std::vector<Effect> hertz = {Effect::kHertzianContact};
  try {
    FitCandidate(s.campaign, hertz);
    FAIL() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "effects");
    EXPECT_STREQ(e.what(), "effects: hertzian_contact cannot show in this campaign (no record reaches the stop)");
  }
}

}  // namespace
}  // namespace strokelab
