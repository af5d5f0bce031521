// Spike detection on synthetic trains of half-sine contact pulses (paper section 4.1, Eq. 4), RSD
// (paper Eq. 6 with its square root restored) and k_s from the contact time (paper Eq. 5 and the
// damped relation).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <random>
#include <vector>

#include "strokelab/engines/engine.h"
#include "strokelab/base/errors.h"
#include "strokelab/model/model.h"
#include "strokelab/signal/signal.h"
#include "test_util.h"

namespace strokelab {
namespace {

using ::strokelab::testing::kPi;
using ::strokelab::testing::kFs;

// A contact time of 0.49 ms spans 25 samples (19.5 us each). The half-height crossings are
// interpolated linearly, so quantisation leaves well under a sample of error; the residual comes
// from the sampled peak missing the true one by up to half a sample (half height read up to 0.2 %
// low, 0.1 % in dT) and from the noise at the crossings. 2 % (10 us, half a sample) bounds all of it;
// the error measured on these signals is 0.1 %.
constexpr double kContactTimeRel = 0.02;

struct Pulse {
  double start_s;
  double base_s;     // contact time dT
  double height;     // signed
};

// A smooth force (offset, fundamental, second harmonic) plus half-sine pulses plus white noise.
std::vector<double> ForceWithPulses(double duration_s, double f, const std::vector<Pulse>& pulses, double noise_sigma,
                                    unsigned seed = 7) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_sigma);
  const size_t count = static_cast<size_t>(duration_s * kFs);
  std::vector<double> x(count);
  for (size_t n = 0; n < count; ++n) {
    const double t = static_cast<double>(n) / kFs;
    x[n] = 0.01 + 0.3 * std::sin(2 * kPi * f * t) + 0.05 * std::sin(4 * kPi * f * t + 0.3);
    if (noise_sigma > 0.0) x[n] += noise(rng);
  }
  for (const Pulse& p : pulses) {
    const size_t first = static_cast<size_t>(std::ceil(p.start_s * kFs));
    for (size_t n = first; static_cast<double>(n) / kFs < p.start_s + p.base_s && n < count; ++n) {
      x[n] += p.height * std::sin(kPi * (static_cast<double>(n) / kFs - p.start_s) / p.base_s);
    }
  }
  return x;
}

// One pulse per drive period at a fixed phase, off the sample grid.
std::vector<Pulse> PulseTrain(double duration_s, double f, double base_s, double height) {
  std::vector<Pulse> pulses;
  for (int k = 0; (k + 0.237) / f + base_s < duration_s; ++k) pulses.push_back({(k + 0.237) / f, base_s, height});
  return pulses;
}

TEST(DetectSpikesTest, HalfSineTrainOnSinusoidPlusNoise) {
  const double f = 8.0, base_s = 0.49e-3, duration_s = 2.0;
  const std::vector<Pulse> pulses = PulseTrain(duration_s, f, base_s, 1.0);
  const std::vector<double> force = ForceWithPulses(duration_s, f, pulses, 2e-3);
  const SampleWindow window = LastWholePeriods(force.size(), kFs, f, 1.0);
  const std::vector<Spike> spikes = DetectSpikes(force, kFs, f, window);

  ASSERT_EQ(spikes.size(), 8u);  // one per period of the 1 s window
  for (size_t i = 0; i < spikes.size(); ++i) {
    const Pulse& p = pulses[8 + i];
    EXPECT_REL_NEAR(spikes[i].ContactTimeS(), base_s, kContactTimeRel) << i;
    EXPECT_NEAR(spikes[i].start_s, p.start_s, kContactTimeRel * base_s) << i;
    EXPECT_NEAR(spikes[i].end_s, p.start_s + base_s, kContactTimeRel * base_s) << i;
    EXPECT_NEAR(spikes[i].peak_time_s, p.start_s + base_s / 2, 1.0 / kFs) << i;
    // Height above the baseline: positive polarity, the sampled peak within noise of 1.
    EXPECT_NEAR(spikes[i].peak_height, 1.0, 0.01) << i;
    EXPECT_EQ(spikes[i].peak_index, static_cast<size_t>(std::llround(spikes[i].peak_time_s * kFs)));
  }
}

TEST(DetectSpikesTest, NegativePolarityAndVaryingWidths) {
  // Contact times across the paper's range (Fig. 8: 0.4-0.7 ms), spikes below the baseline.
  const double f = 13.0, duration_s = 2.0;
  std::vector<Pulse> pulses = PulseTrain(duration_s, f, 0.5e-3, -0.8);
  for (size_t k = 0; k < pulses.size(); ++k) pulses[k].base_s = 0.4e-3 + 0.3e-3 * static_cast<double>(k % 4) / 3.0;
  const std::vector<double> force = ForceWithPulses(duration_s, f, pulses, 2e-3);
  const SampleWindow window = LastWholePeriods(force.size(), kFs, f, 1.0);
  const std::vector<Spike> spikes = DetectSpikes(force, kFs, f, window);

  std::vector<Pulse> expected;
  for (const Pulse& p : pulses) {
    if (p.start_s >= static_cast<double>(window.begin) / kFs) expected.push_back(p);
  }
  ASSERT_EQ(spikes.size(), expected.size());
  ASSERT_EQ(spikes.size(), 13u);
  for (size_t i = 0; i < spikes.size(); ++i) {
    EXPECT_LT(spikes[i].peak_height, 0.0) << i;
    EXPECT_NEAR(spikes[i].peak_height, -0.8, 0.01) << i;
    EXPECT_REL_NEAR(spikes[i].ContactTimeS(), expected[i].base_s, kContactTimeRel) << i;
  }
}

TEST(DetectSpikesTest, NoSpikesInASmoothSignal) {
  const double f = 8.0;
  const std::vector<double> noisy = ForceWithPulses(2.0, f, {}, 2e-3);
  const SampleWindow window = LastWholePeriods(noisy.size(), kFs, f, 1.0);
  EXPECT_TRUE(DetectSpikes(noisy, kFs, f, window).empty());
  // Noise-free: the residual is rounding error, which must not count as spikes.
  const std::vector<double> clean = ForceWithPulses(2.0, f, {}, 0.0);
  EXPECT_TRUE(DetectSpikes(clean, kFs, f, window).empty());
}

TEST(DetectSpikesTest, NoiseFreePulsesAreFound) {
  // A simulated record has no noise: sigma comes from the floor or the fit's residual.
  const double f = 8.0, base_s = 0.49e-3;
  const std::vector<Pulse> pulses = PulseTrain(2.0, f, base_s, 2.0);
  const std::vector<double> force = ForceWithPulses(2.0, f, pulses, 0.0);
  const SampleWindow window = LastWholePeriods(force.size(), kFs, f, 1.0);
  const std::vector<Spike> spikes = DetectSpikes(force, kFs, f, window);
  ASSERT_EQ(spikes.size(), 8u);
  for (const Spike& s : spikes) EXPECT_REL_NEAR(s.ContactTimeS(), base_s, kContactTimeRel);
}

TEST(DetectSpikesTest, SpikeCutByTheWindowEdgeIsSkipped) {
  const double f = 8.0, base_s = 0.49e-3;
  const std::vector<Pulse> pulses = PulseTrain(2.0, f, base_s, 1.0);
  const std::vector<double> force = ForceWithPulses(2.0, f, pulses, 2e-3);
  // One second (8 periods) from the middle of one pulse to the middle of the last pulse of the record:
  // both edge pulses are cut, the 7 between them are whole.
  const size_t middle = static_cast<size_t>((pulses.back().start_s + base_s / 2) * kFs);
  const SampleWindow window{middle - 51200, middle, 0.0};
  const std::vector<Spike> spikes = DetectSpikes(force, kFs, f, window);
  ASSERT_EQ(spikes.size(), 7u);
  for (const Spike& s : spikes) {
    EXPECT_GT(s.start_s, static_cast<double>(window.begin) / kFs + base_s);
    EXPECT_LT(s.end_s, pulses.back().start_s);
  }
}

TEST(DetectSpikesTest, SimulatedForceAgreesWithTheEngineContacts) {
  // One method against another: contact times read off the simulated force (half-sine estimate)
  // against the switching instants the exact engine located. The contact is not exactly a half-sine
  // (k_p and the drive act during it, the baseline curves), which the estimate absorbs to 0.2 % here;
  // 1 % leaves room without hiding a wrong factor (the 2/3 of Eq. 4 would be off by 33 %).
  constexpr double kEstimateRel = 0.01;
  const std::unique_ptr<Engine> engine = MakeEngine(Method::kExact);
  for (const auto& [f, volts] : {std::pair{8.0, 0.5}, std::pair{13.0, 0.6}}) {
    SineDrive drive;
    drive.amplitude_v = volts;
    drive.frequency_hz = f;
    SimulationOptions options;
    options.duration_s = 3.0;
    const Record record = engine->Simulate(PaperModel(), drive, options);
    const SampleWindow window = LastWholePeriods(record.size(), record.sample_rate_hz, f, 1.0);
    const std::vector<Spike> spikes = DetectSpikes(record.force_n, record.sample_rate_hz, f, window);
    std::vector<ContactInterval> contacts;
    for (const ContactInterval& c : record.contacts) {
      if (c.start_s >= record.TimeS(window.begin) && c.closed) contacts.push_back(c);
    }
    ASSERT_EQ(spikes.size(), contacts.size()) << f << " Hz";
    ASSERT_EQ(spikes.size(), static_cast<size_t>(f));  // one impact per period, paper section 5
    for (size_t i = 0; i < spikes.size(); ++i) {
      EXPECT_GT(spikes[i].peak_height, 0.0);  // the lower stop pushes up: f = m x'' > 0
      EXPECT_REL_NEAR(spikes[i].ContactTimeS(), contacts[i].DurationS(), kEstimateRel) << f << " Hz, " << i;
      EXPECT_NEAR(spikes[i].start_s, contacts[i].start_s, kEstimateRel * contacts[i].DurationS());
    }
  }
}

TEST(DetectSpikesTest, RejectsBadArgumentsNamingTheField) {
  const std::vector<double> x(1000, 0.0);
  try {
    DetectSpikes(x, kFs, 8.0, SampleWindow{0, 2000, 0.0});
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "window");
  }
  SpikeOptions options;
  options.threshold_sigmas = 0.0;
  EXPECT_THROW(DetectSpikes(x, kFs, 8.0, SampleWindow{0, 1000, 0.0}, options), InputError);
}

// ---- Paper Eq. 6 ----------------------------------------------------------------------------------

TEST(ContactTimeStatsTest, HandComputedExamples) {
  // {0.5, 0.6, 0.7} ms: mean 0.6 ms, squared deviations 0.01 + 0 + 0.01 ms^2 over N - 1 = 2 ->
  // sd 0.1 ms, RSD 1/6.
  const std::vector<double> three = {0.5e-3, 0.6e-3, 0.7e-3};
  const ContactTimeStatistics a = ContactTimeStats(three);
  EXPECT_EQ(a.count, 3u);
  EXPECT_REL_NEAR(a.mean_s, 0.6e-3, 1e-15);
  EXPECT_REL_NEAR(a.rsd, 1.0 / 6.0, 1e-13);
  // {1, 2, 3, 4}: mean 2.5, sum of squares 5, sd sqrt(5/3), RSD sqrt(5/3)/2.5 = 0.5163978.
  const std::vector<double> four = {1.0, 2.0, 3.0, 4.0};
  EXPECT_REL_NEAR(ContactTimeStats(four).rsd, std::sqrt(5.0 / 3.0) / 2.5, 1e-15);
  EXPECT_NEAR(ContactTimeStats(four).rsd, 0.5163978, 1e-7);
}

TEST(ContactTimeStatsTest, FewSpikes) {
  const std::vector<double> one = {0.5e-3};
  const ContactTimeStatistics a = ContactTimeStats(one);
  EXPECT_EQ(a.count, 1u);
  EXPECT_EQ(a.mean_s, 0.5e-3);
  EXPECT_TRUE(std::isnan(a.rsd));
  const ContactTimeStatistics none = ContactTimeStats({});
  EXPECT_EQ(none.count, 0u);
  EXPECT_TRUE(std::isnan(none.mean_s));
  EXPECT_TRUE(std::isnan(none.rsd));
  const std::vector<double> bad = {0.5e-3, -1.0};
  EXPECT_THROW(ContactTimeStats(bad), InputError);
}

// ---- Paper Eq. 5 and the damped relation -----------------------------------------------------------

constexpr double kMass = 0.032;      // m_p [kg], Table 2
constexpr double kSuspension = 124;  // k_p [N/m]
constexpr double kContact = 1.3e6;   // k_s [N/m]

TEST(ContactStiffnessTest, Eq5RoundTripAndPaperContactTime) {
  const double dt = kPi * std::sqrt(kMass / kContact);  // undamped, k_p neglected
  EXPECT_NEAR(dt, 0.49e-3, 0.005e-3);                    // from Table 2 and Eq. 4-5: 0.49 ms
  EXPECT_REL_NEAR(ContactStiffnessEq5(kMass, dt), kContact, 1e-14);
  // Fig. 7: 0.4 ms -> about 2 MN/m.
  EXPECT_REL_NEAR(ContactStiffnessEq5(kMass, 0.4e-3), kMass * std::pow(kPi / 0.4e-3, 2), 1e-15);
}

TEST(ContactStiffnessTest, DampedRelationRoundTrips) {
  for (const double damping : {0.0, 1.3, 30.0}) {
    const double dt = ContactHalfPeriodS(kMass, kSuspension, kContact, damping);
    EXPECT_REL_NEAR(ContactStiffnessDamped(kMass, dt, kSuspension, damping), kContact, 1e-12) << damping;
  }
  // Without suspension and damping it is Eq. 5.
  const double dt = ContactHalfPeriodS(kMass, 0.0, kContact, 0.0);
  EXPECT_REL_NEAR(ContactStiffnessEq5(kMass, dt), kContact, 1e-14);
  EXPECT_REL_NEAR(ContactStiffnessDamped(kMass, dt, 0.0, 0.0), kContact, 1e-14);
  // Table 2: Eq. 5 overestimates k_s by k_p (c_p adds (c/2m)^2 m = 13 N/m in the other direction).
  const double dt_table2 = ContactHalfPeriodS(kMass, kSuspension, kContact, 1.3);
  EXPECT_NEAR(ContactStiffnessEq5(kMass, dt_table2) - kContact,
              kSuspension - kMass * std::pow(1.3 / (2 * kMass), 2), 1e-6);
}

TEST(ContactStiffnessTest, OverdampedContactHasNoHalfPeriod) {
  // c^2 > 4 m (k_p + k_s): critical damping is 2 sqrt(0.032 * 1300124) = 408 N s/m.
  EXPECT_THROW(ContactHalfPeriodS(kMass, kSuspension, kContact, 500.0), NumericalError);
  EXPECT_THROW(ContactStiffnessEq5(kMass, 0.0), InputError);
  EXPECT_THROW(ContactStiffnessDamped(kMass, 1.0, kSuspension, 0.0), InputError);  // slower than the suspension
}

}  // namespace
}  // namespace strokelab
