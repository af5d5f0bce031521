// The acceptance checks on the paper's model: engines agree on a saturating record, the
// linear saturation threshold holds, the bistability above resonance, and what the paper reports.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "strokelab/engines/engine.h"
#include "strokelab/model/linear_response.h"
#include "strokelab/engines/record_summary.h"
#include "strokelab/signal/signal.h"
#include "test_util.h"

namespace strokelab {
namespace {

Record RunPaperModel(Method method, double frequency_hz, double amplitude_v, double duration_s = 10.0) {
  SimulationOptions options;
  options.duration_s = duration_s;
  return MakeEngine(method)->Simulate(PaperModel(), SineDrive{amplitude_v, frequency_hz, 0.0}, options);
}

RecordSummary SummaryOf(Method method, double frequency_hz, double amplitude_v, double duration_s = 10.0) {
  return Summarize(RunPaperModel(method, frequency_hz, amplitude_v, duration_s), SineDrive{amplitude_v, frequency_hz, 0.0});
}

TEST(EnginesAgreeTest, SaturatingRecordAt8Hz) {
  // 8 Hz / 0.5 V from rest, 10 s at 51.2 kHz: the acceptance test.
  const RecordSummary exact = SummaryOf(Method::kExact, 8.0, 0.5);
  const RecordSummary cvode = SummaryOf(Method::kCvode, 8.0, 0.5);
  const RecordSummary ode3 = SummaryOf(Method::kOde3, 8.0, 0.5);
  ASSERT_EQ(exact.contacts, 8u);
  EXPECT_EQ(cvode.contacts, 8u);
  EXPECT_REL_NEAR(cvode.first_harmonic_force_n, exact.first_harmonic_force_n, 1e-6);
  EXPECT_NEAR(cvode.first_harmonic_phase_rad, exact.first_harmonic_phase_rad, 1e-6);
  EXPECT_REL_NEAR(cvode.peak_force_n, exact.peak_force_n, 1e-3);
  // |F1| = 0.0774131 N on an independent prototype.
  EXPECT_NEAR(exact.first_harmonic_force_n, 0.0774131, 5e-8);
  // ode3 at the output rate misses the spikes' peaks; its own error, measured 2.4e-4 relative in
  // |F1| (2.4e-4 on the prototype) and 0.009 N at the peak, is bounded here, not hidden.
  const double ode3_f1_error = std::abs(ode3.first_harmonic_force_n / exact.first_harmonic_force_n - 1);
  EXPECT_GT(ode3_f1_error, 1e-5);
  EXPECT_LT(ode3_f1_error, 5e-4);
}

TEST(EnginesAgreeTest, SampleBySampleForceAt8Hz) {
  const Record exact = RunPaperModel(Method::kExact, 8.0, 0.5);
  const Record cvode = RunPaperModel(Method::kCvode, 8.0, 0.5);
  ASSERT_EQ(exact.size(), cvode.size());
  double worst_n = 0, worst_x_m = 0;
  for (size_t n = 0; n < exact.size(); ++n) {
    worst_n = std::max(worst_n, std::abs(exact.force_n[n] - cvode.force_n[n]));
    worst_x_m = std::max(worst_x_m, std::abs(exact.displacement_m[n] - cvode.displacement_m[n]));
  }
  // Spikes reach 15 N; CVODE at rtol 1e-10 follows the closed form to ~1e-6 N (measured 4.5e-7).
  EXPECT_LT(worst_n, 1e-5);
  EXPECT_LT(worst_x_m, 1e-10);
  ASSERT_EQ(exact.contacts.size(), cvode.contacts.size());
  for (size_t i = 0; i < exact.contacts.size(); ++i) {
    EXPECT_NEAR(exact.contacts[i].start_s, cvode.contacts[i].start_s, 1e-9);
    EXPECT_NEAR(exact.contacts[i].end_s, cvode.contacts[i].end_s, 1e-9);
  }
}

// The lowest drive amplitude whose record from rest touches the stop in its last second, by
// bisection on [lo, hi] to `tolerance_v`.
double BisectContactAmplitude(double frequency_hz, double lo, double hi, double tolerance_v, double duration_s) {
  auto touches = [&](double v) { return SummaryOf(Method::kExact, frequency_hz, v, duration_s).contacts > 0; };
  EXPECT_FALSE(touches(lo));
  EXPECT_TRUE(touches(hi));
  while (hi - lo > tolerance_v) {
    const double mid = 0.5 * (lo + hi);
    (touches(mid) ? hi : lo) = mid;
  }
  return 0.5 * (lo + hi);
}

TEST(SaturationThresholdTest, LinearThresholdHoldsBelowResonance) {
  // V_sat(w) = |d| |k_p - m_p w^2 + j c_p w| / g (linear_response.h). Below resonance the steady
  // state is reached without the transient touching the stop, so the bisection lands on V_sat.
  for (double f_hz : {6.0, 8.0}) {
    const double v_sat = LinearSaturationThresholdV(PaperModel(), 2 * std::numbers::pi * f_hz);
    const double found = BisectContactAmplitude(f_hz, 0.9 * v_sat, 1.1 * v_sat, 1e-6 * v_sat, 6.0);
    EXPECT_REL_NEAR(found, v_sat, 1e-4) << f_hz << " Hz";
  }
}

TEST(SaturationThresholdTest, AboveResonanceTheTransientReachesTheStopFirst) {
  // At 13 Hz a record from rest reaches the stop near 0.415 V, well below the
  // closed-form grazing amplitude 0.4629 V: the start-up transient throws the mass onto the
  // contacting branch, which then persists (bistability in amplitude).
  const double v_sat = LinearSaturationThresholdV(PaperModel(), 2 * std::numbers::pi * 13.0);
  EXPECT_NEAR(v_sat, 0.4629, 1e-4);
  const double from_rest = BisectContactAmplitude(13.0, 0.35, v_sat, 1e-4, 10.0);
  EXPECT_NEAR(from_rest, 0.415, 0.005);
  EXPECT_LT(from_rest, v_sat - 0.04);
  // Just below the closed form, the contacting response keeps hitting the stop to the end.
  const RecordSummary s = SummaryOf(Method::kExact, 13.0, 0.45);
  EXPECT_EQ(s.contacts, 13u);
}

TEST(PaperBehaviourTest, SaturationOnsetAt8And13Hz) {
  // Section 5: the piecewise model saturates at 8 Hz / 0.3 V; at 13 Hz not at 0.4 V, yes at 0.5 V.
  EXPECT_GT(SummaryOf(Method::kExact, 8.0, 0.3).contacts, 0u);
  EXPECT_EQ(SummaryOf(Method::kExact, 13.0, 0.4).contacts, 0u);
  EXPECT_GT(SummaryOf(Method::kExact, 13.0, 0.5).contacts, 0u);
}

TEST(PaperBehaviourTest, SpikesAreOneSidedAndLastAbout049ms) {
  const SineDrive drive{0.5, 8.0, 0.0};
  const Record record = RunPaperModel(Method::kExact, drive.frequency_hz, drive.amplitude_v);
  const SampleWindow window = LastWholePeriods(record.size(), record.sample_rate_hz, drive.frequency_hz);
  const std::vector<Spike> spikes = DetectSpikes(record.force_n, record.sample_rate_hz, drive.frequency_hz, window);
  ASSERT_EQ(spikes.size(), 8u);  // one per period: one stop
  for (const Spike& s : spikes) {
    EXPECT_GT(s.peak_height, 0.0);  // the lower stop pushes the mass up: f = m_p x'' > 0
    EXPECT_NEAR(s.ContactTimeS(), 0.49e-3, 0.01e-3);
  }
  const RecordSummary summary = Summarize(record, drive);
  EXPECT_NEAR(summary.mean_contact_ms, 0.49, 0.01);
  EXPECT_LT(summary.contact_time_rsd, 1e-6);  // the piecewise model repeats each impact exactly
}

}  // namespace
}  // namespace strokelab
