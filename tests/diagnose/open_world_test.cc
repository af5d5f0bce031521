// The diagnosis in an open world (issue 13): a campaign with physics that no library effect holds
// gets "unexplained" with where, and no library effect named as its explanation.
//
// The concealed-effect campaign's control (paper model, perturbed parameters, noise, offset, hum;
// seed 1101, used nowhere else and tuned on by nothing) with a housing mode added to the measured
// force: every impact spike rings a 180 Hz mode with 5 % damping at a fifth of the spike's height
// (the force sensor sees the housing's ringing). No effect of the library makes a response at a
// fixed frequency in Hz that decays after each impact. The description finds the ring's frequency and
// decay in the residual's time series (FindRinging).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>

#include "concealed_effects.h"
#include "strokelab/diagnose/diagnose.h"
#include "strokelab/diagnose/open_world.h"
#include "strokelab/data/synth.h"
#include "strokelab/signal/signal.h"

namespace strokelab {
namespace {

constexpr double kRingHz = 180.0;
constexpr double kRingDamping = 0.05;     // ratio to critical
constexpr double kRingShare = 0.2;        // ring amplitude over the spike's height
constexpr double kRingTimeConstants = 8;  // added over this many decay times

// Returns the impacts that ring; each rings at `share` of its spike's height.
size_t AddHousingRing(Recording* r, double share = kRingShare) {
  const SampleWindow whole{0, r->size(), 0.0};
  const std::vector<Spike> spikes = DetectSpikes(r->response, r->sample_rate_hz, r->nominal_frequency_hz, whole);
  const double w = 2 * std::numbers::pi * kRingHz;
  const double wd = w * std::sqrt(1 - kRingDamping * kRingDamping);
  const auto span = static_cast<size_t>(kRingTimeConstants / (kRingDamping * w) * r->sample_rate_hz);
  for (const Spike& s : spikes)
    for (size_t n = s.peak_index; n < std::min(r->size(), s.peak_index + span); ++n) {
      const double t = static_cast<double>(n - s.peak_index) / r->sample_rate_hz;
      r->response[n] += share * s.peak_height * std::exp(-kRingDamping * w * t) * std::sin(wd * t);
    }
  return spikes.size();
}

TEST(OpenWorldTest, AHousingModeThatRingsAfterImpactsIsUnexplainedAndNothingIsNamed) {
  testing::EffectCase control{"housing_mode", "", 0.0, false, 1101};
  Synthesis s = Synthesize(testing::WithEffect(control), testing::CampaignOptions(control.seed));
  size_t ringing = 0;  // records
  for (Recording& r : s.campaign.records) ringing += AddHousingRing(&r) > 0;
  ASSERT_GE(ringing, 8u);  // the 0.4 and 0.5 V rows reach the stop
  const Diagnosis d = DiagnoseCampaign(s.campaign);
  std::string candidates;
  for (const CandidateFit& c : d.candidates) candidates += "\n  " + c.label + " held-out gain " + std::to_string(c.heldout_gain);
  SCOPED_TRACE(d.conclusion + candidates);
  std::printf("%s\n", d.conclusion.c_str());
  ASSERT_TRUE(d.unexplained);
  EXPECT_TRUE(d.missing_physics.empty());
  EXPECT_THAT(d.conclusion, ::testing::StartsWith("unexplained"));
  // Where: contacting records (0.4 and 0.5 V rows), none of the 0.1 V row, which never reaches the stop.
  ASSERT_FALSE(d.unexplained->places.empty());
  for (const Unexplained::Place& p : d.unexplained->places) EXPECT_GT(p.amplitude_v, 0.2) << p.record;
  EXPECT_GT(d.unexplained->misfit_to_noise, 1.5);
  // What: the residual rings at the mode's damped frequency, decaying at its rate (FindRinging), in
  // the worst records that ring, and the description says so.
  const double ring_hz = kRingHz * std::sqrt(1 - kRingDamping * kRingDamping);
  int rings = 0;
  for (size_t i = 0; i < d.unexplained->places.size() && i < 3; ++i) {
    const Unexplained::Place& p = d.unexplained->places[i];
    if (!std::isfinite(p.ring_frequency_hz)) continue;
    ++rings;
    EXPECT_NEAR(p.ring_frequency_hz, ring_hz, 0.02 * ring_hz) << p.record;
    EXPECT_NEAR(p.ring_damping_ratio, kRingDamping, 0.2 * kRingDamping) << p.record;
  }
  EXPECT_GE(rings, 2);
  EXPECT_THAT(d.conclusion, ::testing::HasSubstr("the residual rings at about"));
  // The selection ran again with the coil's inductance (diagnose.h), and each fit that added the coil
  // to a model without one stopped at tau_e's floor: the records ask for less lag (0.26.0's fits ran
  // tau_e down to that floor, the coil alone in 32 s).
  EXPECT_TRUE(d.coil_round);
  int coils = 0;
  for (const CandidateFit& c : d.candidates)
    if (c.effects.back() == Effect::kCoilInductance) {
      ++coils;
      EXPECT_THAT(c.note, ::testing::HasSubstr("the records ask for less tau_e than its floor")) << c.label;
    }
  EXPECT_GE(coils, 1);
}

// The diagnosis of the campaign of `effect` with every impact ringing at `share` of its spike's height.
Diagnosis DiagnoseWithRing(const testing::EffectCase& effect, double share) {
  Synthesis s = Synthesize(testing::WithEffect(effect), testing::CampaignOptions(effect.seed));
  for (Recording& r : s.campaign.records) AddHousingRing(&r, share);
  return DiagnoseCampaign(s.campaign);
}

// A ring 1/2000 of the spikes' height (1/400 of the test above's): the fitted harmonics (1..10, up to
// 110 Hz) stay within noise, and the test above them finds the mode. Nothing is named; the description
// gives the ring, and no missing-force surface (it would be the harmonics' noise).
TEST(OpenWorldTest, ARingTheHarmonicsDoNotShowIsUnexplainedAboveThem) {
  const Diagnosis d = DiagnoseWithRing({"housing_mode", "", 0.0, false, 1101}, 0.0005);
  SCOPED_TRACE(d.conclusion);
  std::printf("%s\n", d.conclusion.c_str());
  EXPECT_TRUE(d.missing_physics.empty());
  ASSERT_TRUE(d.unexplained);
  EXPECT_GE(d.unexplained->p_value, internal::kUnexplainedP);  // the harmonics alone pass
  EXPECT_FALSE(d.coil_round);
  EXPECT_THAT(d.conclusion, ::testing::HasSubstr("above harmonic 10 the residual rings after the impacts"));
  EXPECT_THAT(d.conclusion, ::testing::HasSubstr("the residual rings at about 1"));
  EXPECT_THAT(d.conclusion, ::testing::Not(::testing::HasSubstr("restoring-force surface")));
  const double ring_hz = kRingHz * std::sqrt(1 - kRingDamping * kRingDamping);
  ASSERT_FALSE(d.unexplained->places.empty());
  EXPECT_NEAR(d.unexplained->places.front().ring_frequency_hz, ring_hz, 0.02 * ring_hz);
}

// Contact damping concealed (c_s = 40 N s/m, a new seed) and a ring 1/500 of the spikes' height:
// contact damping fits the harmonics, but beside a mode the impacts excite an effect at the stop may
// only stand in for the stop's missing physics, so it is not named, and the verdict says why. (The
// price of the rule: a right effect at the stop goes unnamed where such a ring is found beside it.)
TEST(OpenWorldTest, AnEffectAtTheStopBesideARingIsNotNamed) {
  const Diagnosis d = DiagnoseWithRing({"contact_damping", "c_s", 40.0, false, 1102}, 0.002);
  SCOPED_TRACE(d.conclusion);
  EXPECT_TRUE(d.missing_physics.empty());
  ASSERT_TRUE(d.unexplained);
  EXPECT_THAT(d.conclusion, ::testing::HasSubstr("contact_damping fits the harmonics, but the impacts excite a mode"));
  int not_named = 0;
  for (const CandidateFit& c : d.candidates) not_named += c.label == "contact_damping" && c.decision.starts_with("not named");
  EXPECT_EQ(not_named, 1);
}

// The same campaign without the ring, against the model that made it: no ringing is found.
TEST(OpenWorldTest, NoRingingInARecordTheModelMatches) {
  testing::EffectCase control{"housing_mode", "", 0.0, false, 1101};
  const Synthesis s = Synthesize(testing::WithEffect(control), testing::CampaignOptions(control.seed));
  const FitOptions options;
  int contacting = 0;
  for (const Recording& r : s.campaign.records) {
    const RecordAnalysis a = AnalyseRecord(r, s.campaign.response, options);
    if (a.spikes.empty()) continue;
    ++contacting;
    Unexplained::Place place;
    internal::FindRinging(r, a, s.model, s.campaign.response, options.harmonic_orders, &place);
    EXPECT_TRUE(std::isnan(place.ring_frequency_hz)) << r.name << " rings at " << place.ring_frequency_hz << " Hz, "
                                                     << place.ring_to_noise << " x noise";
  }
  EXPECT_GE(contacting, 8);
}

}  // namespace
}  // namespace strokelab
