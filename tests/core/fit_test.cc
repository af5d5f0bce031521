// Tests of the fit pipeline (fit.h) on synthetic campaigns with known truth, and of OrbitHarmonics
// (steady_state.h) against a time-domain DFT.
//
// The campaigns come from data's synthesiser (strokelab/data/synth.h, as `strokelab synth` makes
// them): the exact engine runs a known model, paper Table 2 with k_p +8 %, c_p -10 %, g +5 %, k_s -30 %
// (d = -1 mm), at 6, 7, 8, 9, 11, 13 Hz x 0.1, 0.3, 0.4, 0.5 V from rest, each record with its own
// drive phase and a drive frequency 2e-4 above the manifest's nominal one; after 10 s of settling 1 s
// is recorded at 51.2 kHz. The rig's imperfections are added: white sensor noise (2 mN), a DC offset
// (50 mN) and 50 Hz mains hum (3 mN) on the response, an offset (2 mV) and noise (0.1 mV) on the
// voltage channel. 8 records stay clear of the stop, 16 hit it once a period.
//
// Calibration of the standard errors (a 64-seed study on these campaigns, seeds 1001-1064, run by
// hand; too long for the suite and not kept): the estimates scatter about the truth with mean
// z = (estimate - truth) / standard error within +-0.13 (its own standard error is 0.125) and
// sd(z) 0.88-1.10 for each of k_p, c_p, g, d, k_s; the largest |z| seen was 2.89 (g). The test's
// former generator, with the same noise model and other random numbers, gave mean z within +-0.09,
// sd(z) 0.97-1.05 and |z| up to 2.96 (d); on its seeds 1-24 k_s showed sd(z) 1.3 and |z| up to 3.1, a
// draw that the fresh seeds did not repeat. The tests use one seed, fixed below, and ask for
// |z| <= 3: about 1 % of seeds would fail one parameter.
#include "strokelab/identify/extended_fit.h"
#include "strokelab/identify/fit.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <complex>
#include <cstdlib>
#include <iostream>
#include <nlohmann/json.hpp>
#include <numbers>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "engine_test_util.h"
#include "strokelab/base/errors.h"
#include "strokelab/data/synth.h"
#include "strokelab/engines/engine.h"
#include "strokelab/identify/fit_orbit.h"
#include "strokelab/signal/signal.h"
#include "strokelab/steady/steady_state.h"
#include "gen2_grids.h"
#include "test_util.h"

namespace strokelab {
namespace {

using ::testing::Contains;
using ::testing::HasSubstr;
constexpr double kTwoPi = 2.0 * std::numbers::pi;

// Named tolerances.
using ::strokelab::testing::kSigmaBound;  // (see above)
// Within 1 % of the truth: the perturbations are 5-30 %, so this shows the fit went to the truth and
// not stayed at the data sheet; the standard errors are far smaller (k_s 0.15 %, the others 0.002 %).
constexpr double kTruthRelTol = 0.01;
constexpr unsigned kSeed = 2;  // the one draw the tests look at (|z| <= 0.87 for all five)

// An empty stepped-sine record: its name, sample rate and the manifest's drive (the caller fills the
// voltage and response channels).
Recording EmptyRecord(std::string name, double fs, double f, double amplitude_v) {
  Recording r;
  r.name = std::move(name);
  r.sample_rate_hz = fs;
  r.nominal_frequency_hz = f;
  r.nominal_amplitude_v = amplitude_v;
  return r;
}

// The truth: paper Table 2 with k_p +8 %, c_p -10 %, g +5 %, k_s -30 %; d as in the paper.
ActuatorModel Truth() {
  ActuatorModel m = PaperModel();
  m.stiffness_n_per_m = 124.0 * 1.08;
  m.damping_n_s_per_m = 1.3 * 0.90;
  m.gain_n_per_v = 0.3 * 1.05;
  m.contact_stiffness = 1.3e6 * 0.70;
  return m;
}

// The rig's settings on data's synthesiser for a force or acceleration response (its default grid,
// settling and record length are the campaign above). The sensor's sensitivity is 1 V per response
// unit, so that the response channel's imperfections are given in that unit: 1 N of blocked force is
// 1 / m_p m/s^2 of acceleration.
SynthOptions RigOptions(ResponseKind response) {
  const double force_to_response = response == ResponseKind::kForce ? 1.0 : 1.0 / Truth().mass_kg;
  SynthOptions o;
  o.response = response;
  o.sensitivity = 1.0;
  o.noise_rms_v = 2e-3 * force_to_response;
  o.offset_v = 0.05 * force_to_response;
  o.hum_v = 3e-3 * force_to_response;
  o.voltage_noise_rms_v = 1e-4;
  o.voltage_offset_v = 2e-3;
  o.drive_frequency_error = 2e-4;
  o.random_drive_phase = true;
  o.seed = kSeed;
  return o;
}

// The records of a stepped-sine campaign on the truth, with the rig's imperfections.
Campaign RigCampaign(const SynthOptions& o) { return Synthesize(Truth(), o).campaign; }

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// |estimate - truth| within kSigmaBound standard errors and kTruthRelTol of the truth.
::testing::AssertionResult Recovers(const FitResult& result, const std::string& name, double truth) {
  const FitParameter* p = result.Find(name);
  if (p == nullptr) return ::testing::AssertionFailure() << "no parameter " << name;
  const double z = (p->value - truth) / p->standard_error;
  const double rel = std::abs(p->value - truth) / std::abs(truth);
  std::ostringstream what;
  what << name << " = " << p->value << " +- " << p->standard_error << " " << p->unit << ", truth " << truth
       << ": z = " << z << ", relative error " << rel;
  if (!(p->standard_error > 0.0) || !(std::abs(z) <= kSigmaBound) || !(rel <= kTruthRelTol))
    return ::testing::AssertionFailure() << what.str();
  std::cout << "  " << what.str() << "\n";
  return ::testing::AssertionSuccess();
}

// ---- OrbitHarmonics --------------------------------------------------------------------------------

TEST(OrbitHarmonics, MatchesTimeDomainDftOfContactingOrbit) {
  const ActuatorModel model = PaperModel();
  const PeriodMap map(model, 8.0, 0.5);
  const SteadyState s = SolveAttractor(map, map.ClippedLinearStart());
  ASSERT_EQ(s.period, 1);
  ASSERT_GT(s.figures.contacts, 0);
  constexpr int kOrders = 12;
  const std::vector<std::complex<double>> closed = OrbitHarmonics(map, s.start, s.period, kOrders);
  // The first harmonic is the one OrbitFigures already has (the same closed form).
  EXPECT_LT(std::abs(closed[0] - s.figures.x1), 1e-12 * std::abs(s.figures.x1));

  // Time-domain DFT of the orbit sampled at 2^16 points per period.
  SimulationOptions sim;
  sim.duration_s = 1.0 / 8.0;
  sim.sample_rate_hz = 65536 * 8.0;
  sim.initial = s.start;
  const Record r = MakeExactEngine()->Simulate(model, SineDrive{0.5, 8.0, 0.0}, sim);
  for (int h = 1; h <= kOrders; ++h) {
    const std::complex<double> dft = testing::ComplexAmplitude(r.displacement_m, 0, sim.sample_rate_hz, h * 8.0);
    // The sampled orbit's DFT aliases the harmonics near 2^16 onto h; the contact kinks x'' so that
    // C_h falls like h^-3, which leaves ~1e-11 of |C_1|: 1e-9 is a bound with room.
    EXPECT_LT(std::abs(dft - closed[h - 1]), 1e-9 * std::abs(closed[0])) << "h = " << h;
  }
}

TEST(OrbitHarmonics, RejectsBadArguments) {
  const PeriodMap map(PaperModel(), 8.0, 0.1);
  EXPECT_THROW(OrbitHarmonics(map, {}, 0, 3), InputError);
  EXPECT_THROW(OrbitHarmonics(map, {}, 1, 0), InputError);
}

// ---- SamplingCorrection ----------------------------------------------------------------------------

// A damped stop's force jumps by J = c_s v at entry. At 8 Hz and 51.2 kHz the 8 periods of the window
// start at one position between two samples (6400 a period), so every harmonic steps by 2 J / 6400
// when the entry crosses a sample instant; over where it falls between two samples the correction runs
// a sawtooth of that height: a variance of (2 J / 6400)^2 / 12 of the complex harmonic, half of it per
// Re and Im, and (1 - 1/8^2) of that on the 8 evenly spread shifts. Without contact damping the force is
// continuous: its kinks keep the record's own grid's correction and nothing is added.
// One second of `model`'s steady state at f under a sine drive, as a force record at fs with 1 mN noise
// (seed 13); `simulated` gets the exact engine's record (contacts, velocity).
Recording DampedStopRecording(const ActuatorModel& model, double f, double fs, double amplitude_v, Record* simulated) {
  const PeriodMap map(model, f, amplitude_v);
  const SteadyState steady = SolveAttractor(map, map.ClippedLinearStart());
  EXPECT_EQ(steady.period, 1);
  SimulationOptions sim;
  sim.duration_s = 1.0;
  sim.sample_rate_hz = fs;
  sim.initial = steady.start;
  sim.record_velocity = true;
  *simulated = MakeExactEngine()->Simulate(model, SineDrive{amplitude_v, f, 0.0}, sim);
  std::mt19937_64 rng(13);
  std::normal_distribution<double> noise(0.0, 1e-3);
  Recording record = EmptyRecord("damped_stop", fs, f, amplitude_v);
  for (size_t n = 0; n < simulated->size(); ++n) {
    record.voltage_v.push_back(amplitude_v * std::sin(kTwoPi * f * simulated->TimeS(n)));
    record.response.push_back(simulated->force_n[n] + noise(rng));
  }
  return record;
}

TEST(SamplingCorrection, AJumpBetweenSamplesIsNoiseAndAContinuousForceIsNot) {
  const double f = 8.0, fs = 51200.0, amplitude_v = 0.4;
  for (const double c_s : {40.0, 0.0}) {
    ActuatorModel model = PaperModel();
    model.contact_damping_n_s_per_m = c_s;
    Record r;
    const RecordAnalysis a =
        AnalyseRecord(DampedStopRecording(model, f, fs, amplitude_v, &r), ResponseKind::kForce, {});
    const std::optional<internal::ModelOrbit> orbit = internal::BestMatchingOrbit(model, a, ResponseKind::kForce, 10);
    ASSERT_TRUE(orbit);
    const internal::SampledCorrection sampled =
        internal::SamplingCorrection(model, a, *orbit, ResponseKind::kForce, 10);
    if (c_s == 0.0) {
      EXPECT_EQ(sampled.jitter_variance, 0.0);
      continue;
    }
    ASSERT_FALSE(r.contacts.empty());
    const auto before = static_cast<size_t>(std::floor(r.contacts.back().start_s * fs));  // in free flight
    const double step = 2.0 * c_s * std::abs(r.velocity_m_per_s[before]) / (fs / f);
    const double expected = step * step / 24.0 * (1.0 - 1.0 / 64.0);
    // 16 % above it measured: the force's kinks where the stop lets go and where k_s p takes over add
    // smaller sawtooths of their own (their slopes change by ~5e4 N/s, ~0.1 N over a sample).
    EXPECT_NEAR(sampled.jitter_variance, expected, 0.25 * expected);
    EXPECT_GT(std::sqrt(sampled.jitter_variance), a.harmonic_se);  // it matters: more than the noise's
  }
}

// The jitter is the model's own, and a model can lower a chi-square over it by predicting more of it:
// a contact-damping fit weighted so reached c_s = 1200 N s/m, with a stop at the resolution's stiffness,
// on a campaign with a concealed second stop. Candidates are compared (Chi2At, the diagnosis's gains)
// on the record's noise alone, while the prediction's variance holds the jitter for the held-out test.
// (Here, with nothing missing, the truth's chi-square is 2.1e4 over the noise and 39 over noise and
// jitter; ten times its c_s gives 9.3e7 and 1.9e3.)
TEST(SamplingCorrection, AModelsOwnJitterDoesNotLowerTheChiSquareCandidatesAreComparedOn) {
  const double f = 8.0, fs = 51200.0, amplitude_v = 0.4;
  ActuatorModel truth = PaperModel();
  truth.contact_damping_n_s_per_m = 40.0;
  Record simulated;
  const RecordAnalysis a =
      AnalyseRecord(DampedStopRecording(truth, f, fs, amplitude_v, &simulated), ResponseKind::kForce, {});
  const std::vector<const RecordAnalysis*> records = {&a};
  auto chi2_at = [&](double c_s) {
    internal::ExtendedProblem problem;
    problem.base = truth;
    problem.base.contact_damping_n_s_per_m = c_s;
    const std::optional<internal::Prediction> p = internal::Predict(problem.base, a, ResponseKind::kForce, 10);
    EXPECT_TRUE(p);
    EXPECT_GT(p->variance, a.harmonic_se * a.harmonic_se);  // it has a jitter
    const double chi2 = internal::Chi2At(records, ResponseKind::kForce, problem, {}, 10);
    EXPECT_DOUBLE_EQ(chi2, internal::MismatchSquared(a, p->harmonics) / (a.harmonic_se * a.harmonic_se));
    return chi2;
  };
  EXPECT_LT(chi2_at(40.0), chi2_at(400.0));
}

// An accelerometer at 44.1 kHz with every drive frequency a whole number of samples a period: every
// period samples the impacts' kinks at one place, and the sampling correction moves by tens of
// standard errors when a contact moves by a sample. Fitted with the correction held frozen between
// solves, this campaign (gen2 control 9706's actuator and grid; synth seeds 1-8 tried, this one chosen
// as the worst of 0.22.0's) ended with k_s 15 standard errors below the truth (and 4.3, 4.4, 6.0 on
// seeds 1, 2, 5); the correction's slopes (linearised_correction.h) bring it within 1.6 on all five.
TEST(SamplingCorrection, ImpactsOnAWholeNumberGridDoNotBiasTheFit) {
  const ActuatorModel truth = testing::Gen2Control9706();
  SynthOptions o = testing::Gen2Accelerometer44kHz();
  o.sensitivity = 0.0102;
  o.seed = 4;
  const FitResult r = FitCampaign(Synthesize(truth, o).campaign);
  ASSERT_TRUE(r.refinement.converged) << r.refinement.report;
  const FitParameter* k_s = r.Find("k_s");
  ASSERT_NE(k_s, nullptr);
  // A z-score beyond 4 happens by chance once in 16,000.
  EXPECT_LT(std::abs(k_s->value - truth.contact_stiffness), 4.0 * k_s->standard_error)
      << k_s->value << " +- " << k_s->standard_error;
}

// ---- Step 1: the drive and one record --------------------------------------------------------------

TEST(EstimateDrive, FindsTrueFrequencyAmplitudePhaseAndOffset) {
  // 2 s at 51.2 kHz of 0.4 V at 9.063 Hz (0.7 % above the nominal 9 Hz), phase 1.1 rad, offset 3 mV,
  // noise 1 mV. Cramer-Rao bounds: amplitude sigma sqrt(2/n) = 4.4e-6 V, phase (at the record's
  // start, correlated with the frequency) ~2.2e-5 rad, frequency sqrt(24) sigma / (2 pi V sqrt(n) T)
  // = 3e-6 Hz, offset sigma / sqrt(n) = 3e-6 V; the tolerances are about 5 of them.
  constexpr double kFs = 51200, kF = 9.063, kV = 0.4, kPhase = 1.1, kOffset = 3e-3, kNoise = 1e-3;
  std::mt19937 rng(11);
  std::normal_distribution<double> normal(0.0, kNoise);
  std::vector<double> v(2 * 51200);
  for (size_t n = 0; n < v.size(); ++n) v[n] = kOffset + kV * std::sin(kTwoPi * kF * n / kFs + kPhase) + normal(rng);
  const DriveEstimate d = EstimateDrive(v, kFs, 9.0);
  EXPECT_NEAR(d.frequency_hz, kF, 2e-5);
  EXPECT_NEAR(d.amplitude_v, kV, 2.2e-5);
  EXPECT_NEAR(d.phase_rad, kPhase, 1.1e-4);
  EXPECT_NEAR(d.offset_v, kOffset, 1.6e-5);
  EXPECT_NEAR(d.noise_rms_v, kNoise, 0.02 * kNoise);
  EXPECT_LE(d.newton_steps, 8);
}

TEST(EstimateDrive, RejectsDrivesItCannotRead) {
  const std::vector<double> flat(51200, 0.0);
  try {
    EstimateDrive(flat, 51200, 8.0);
    FAIL() << "a constant voltage has no drive";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "voltage");
    EXPECT_THAT(e.what(), HasSubstr("no sinusoidal component"));
  }
  const std::vector<double> short_record(1000, 0.0);  // 20 ms: less than two periods of 8 Hz
  EXPECT_THROW(EstimateDrive(short_record, 51200, 8.0), InputError);
  EXPECT_THROW(EstimateDrive(flat, 51200, -1.0), InputError);
}

TEST(EquivalentForceFrf, KinematicResponsesBecomeBlockedForce) {
  const std::complex<double> h(0.3, -0.2);
  constexpr double kF = 10.0, kM = 0.032, kW = kTwoPi * kF;
  EXPECT_EQ(EquivalentForceFrf(h, ResponseKind::kForce, kF, kM), h);
  EXPECT_REL_NEAR(EquivalentForceFrf(h, ResponseKind::kAcceleration, kF, kM), kM * h, 1e-15);
  EXPECT_REL_NEAR(EquivalentForceFrf(h, ResponseKind::kVelocity, kF, kM), kM * std::complex<double>(0, kW) * h, 1e-15);
  EXPECT_REL_NEAR(EquivalentForceFrf(h, ResponseKind::kDisplacement, kF, kM), -kM * kW * kW * h, 1e-15);
}

// The force campaign, analysed and fitted once for the tests below.
class ForceCampaign : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const auto start = std::chrono::steady_clock::now();
    campaign_ = new Campaign(RigCampaign(RigOptions(ResponseKind::kForce)));
    std::cout << "  synthesis: " << SecondsSince(start) << " s\n";
    analyses_ = new std::vector<RecordAnalysis>();
    for (const Recording& r : campaign_->records) analyses_->push_back(AnalyseRecord(r, campaign_->response, {}));
    const auto fit_start = std::chrono::steady_clock::now();
    result_ = new FitResult(FitCampaign(*campaign_));
    std::cout << "  FitCampaign: " << SecondsSince(fit_start) << " s (refinement " << result_->refinement.seconds
              << " s)\n";
  }
  static void TearDownTestSuite() {
    delete campaign_;
    delete analyses_;
    delete result_;
  }
  static Campaign* campaign_;
  static std::vector<RecordAnalysis>* analyses_;
  static FitResult* result_;
};
Campaign* ForceCampaign::campaign_ = nullptr;
std::vector<RecordAnalysis>* ForceCampaign::analyses_ = nullptr;
FitResult* ForceCampaign::result_ = nullptr;

TEST_F(ForceCampaign, RecordAnalysisRemovesOffsetAndHumAndReadsTheFrf) {
  const ActuatorModel truth = Truth();
  for (const RecordAnalysis& a : *analyses_) {
    SCOPED_TRACE(a.name);
    // Cramer-Rao bounds for a real sine of amplitude V in white noise sigma over n samples and T
    // seconds: frequency sqrt(24) sigma / (2 pi V sqrt(n) T), amplitude sigma sqrt(2 / n); 5 of them.
    const double n = static_cast<double>(a.samples()), sigma = 1e-4;
    const double frequency_crb = std::sqrt(24.0) * sigma / (kTwoPi * a.nominal_amplitude_v * std::sqrt(n) * 1.0);
    EXPECT_NEAR(a.drive.frequency_hz, a.nominal_frequency_hz * 1.0002, 5 * frequency_crb);
    EXPECT_NEAR(a.drive.amplitude_v, a.nominal_amplitude_v, 5 * sigma * std::sqrt(2.0 / n));
    EXPECT_NEAR(a.response_offset, 0.05, 1e-3);  // the DC of the force channel
    EXPECT_EQ(a.hum_frequency_hz, 50.0);
    EXPECT_NEAR(a.hum_amplitude, 3e-3, 1e-4);  // its standard error is 1.3e-5 N
    EXPECT_NEAR(a.noise_rms, 2e-3, 1e-4);      // the sensor noise, impacts or not
    if (!a.clear) continue;
    // A clear record is the linear model: its FRF is paper Eq. 3, to the noise (5 standard errors).
    const std::complex<double> eq3 = testing::PaperEq3(truth, kTwoPi * a.drive.frequency_hz);
    EXPECT_LT(std::abs(a.frf - eq3), 5 * a.harmonic_se / a.drive.amplitude_v);
    EXPECT_TRUE(a.spikes.empty());
  }
}

// A stepped-sine record of 1 s at 11 Hz (11 drive periods, 8192 Hz) whose response repeats every
// `response_periods` drive periods: harmonics C_h = 0.1 e^{j h} / h of the drive, and of the response's
// own period between them (0.03 / k, 2 k of them per drive harmonic for period 3), offset, 50 Hz hum
// and white noise (2 mN).
Recording SubharmonicRecord(int response_periods, std::vector<std::complex<double>>* drive_harmonics) {
  const double fs = 8192.0, f = 11.0, amplitude_v = 0.5;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> noise(0.0, 2e-3);
  Recording r = EmptyRecord("period" + std::to_string(response_periods), fs, f, amplitude_v);
  drive_harmonics->clear();
  for (int h = 1; h <= 10; ++h) drive_harmonics->push_back(std::polar(0.1 / h, 1.0 * h));
  for (int i = 0; i < static_cast<int>(fs); ++i) {
    const double t = i / fs, theta = kTwoPi * f * t;
    double y = 0.05 + 3e-3 * std::sin(kTwoPi * 50.0 * t + 0.3) + noise(rng);
    for (int h = 1; h <= 10; ++h) y += std::real((*drive_harmonics)[h - 1] * std::polar(1.0, h * theta));
    for (int k = 1; k <= 10 * response_periods; ++k) {
      if (k % response_periods != 0) y += 0.03 / k * std::cos(k * theta / response_periods + 0.7 * k);
    }
    r.voltage_v.push_back(amplitude_v * std::sin(theta));
    r.response.push_back(y);
  }
  return r;
}

// A period-2 or period-3 response (impacts that alternate, near a stop) over 11 drive periods: its
// subharmonics are not orthogonal to the drive's harmonics there and would leak into them by ~2e-3, 50
// standard errors. It is analysed over the last 10 or 9 periods, and the drive's harmonics come out to
// the noise; a period-1 response keeps its 11 periods.
TEST(AnalyseRecord, ASubharmonicResponseIsAnalysedOverWholePeriodsOfItsOwn) {
  for (const auto& [response_periods, window_periods] : {std::pair{1, 11.0}, {2, 10.0}, {3, 9.0}}) {
    SCOPED_TRACE(response_periods);
    std::vector<std::complex<double>> truth;
    const RecordAnalysis a = AnalyseRecord(SubharmonicRecord(response_periods, &truth), ResponseKind::kForce, {});
    EXPECT_EQ(a.window.periods, window_periods);
    EXPECT_NEAR(a.noise_rms, 2e-3, 1e-4);
    ASSERT_EQ(a.harmonics.size(), truth.size());
    EXPECT_EQ(a.response_periods, response_periods);
    for (size_t h = 0; h < truth.size(); ++h)
      EXPECT_LT(std::abs(a.harmonics[h] - truth[h]), 5 * a.harmonic_se) << "harmonic " << h + 1;
  }
}

// 0.5 s at 7 Hz and 10 kHz (3 whole periods, 0.43 s): 50 Hz hum lies 0.43 bins from harmonic 7, which
// cannot be told from it and is left out (usable false). The hum is removed all the same: left in, a
// hum of 1 mN (2.5 times the noise) leaked into harmonics 6 and 8 (2.6 bins away) by 7 and 9 standard
// errors. Fitted in turn with the drive's harmonics (three passes), a hum of 10 mN was half removed and
// the rest leaked into harmonics 5, 6, 8 and 9 by 4.9-9.1 standard errors; fitted together, nothing leaks.
TEST(AnalyseRecord, HumBesideAHigherHarmonicIsRemovedAndSparesItsNeighbours) {
  for (const double hum : {1e-3, 1e-2}) {
    SCOPED_TRACE(hum);
    const double fs = 10000.0, f = 7.0, amplitude_v = 0.3;
    std::mt19937_64 rng(11);
    std::normal_distribution<double> noise(0.0, 4e-4);
    Recording r = EmptyRecord("hum_beside_h7", fs, f, amplitude_v);
    std::vector<std::complex<double>> truth;
    for (int h = 1; h <= 10; ++h) truth.push_back(std::polar(0.05 / h, 0.5 * h));
    for (int i = 0; i < static_cast<int>(0.5 * fs); ++i) {
      const double t = i / fs, theta = kTwoPi * f * t;
      double y = hum * std::sin(kTwoPi * 50.0 * t + 0.3) + noise(rng);
      for (int h = 1; h <= 10; ++h) y += std::real(truth[h - 1] * std::polar(1.0, h * theta));
      r.voltage_v.push_back(amplitude_v * std::sin(theta));
      r.response.push_back(y);
    }
    const RecordAnalysis a = AnalyseRecord(r, ResponseKind::kForce, {});
    ASSERT_EQ(a.window.periods, 3.0);
    EXPECT_FALSE(a.usable[6]);
    EXPECT_EQ(a.hum_frequency_hz, 50.0);
    for (size_t h = 0; h < truth.size(); ++h) {
      if (a.usable[h]) {
        EXPECT_LT(std::abs(a.harmonics[h] - truth[h]), 4 * a.harmonic_se) << "harmonic " << h + 1;
      }
    }
  }
}

// 1.5 s at 7.5 Hz and 44.1 kHz (11 whole periods, 1.467 s: 73.3 cycles of 50 Hz): an impact a period,
// a Gaussian pulse of 0.1 ms whose harmonics run to several hundred (far above the 25 fitted beside the
// hum), with 60 Hz hum (harmonic 8, left out) and noise. The 50 Hz fit took those higher harmonics in
// (73.3 cycles are not orthogonal to them): a hum of 1.1e-3 where there is none, taken out of harmonics
// 6 and 7, which moved by 19 and 35 standard errors. With the samples around the impacts left out of the
// hum's fit it is 1.4e-6 (the standard error 2.2e-6), and every harmonic within 2.3 standard errors.
TEST(AnalyseRecord, ImpactsDoNotLeakIntoTheHumFit) {
  const double fs = 44100.0, f = 7.5, amplitude_v = 0.3, sigma_s = 1e-4, pulse_at_s = 0.02, period_s = 1.0 / f;
  const double pulse = 0.5 * period_s / (2.0 * sigma_s * std::sqrt(kTwoPi));  // |C_h| = 0.5 exp(-(h w sigma)^2 / 2)
  std::mt19937_64 rng(12);
  std::normal_distribution<double> noise(0.0, 4e-4);
  Recording r = EmptyRecord("impacts_and_hum", fs, f, amplitude_v);
  for (int i = 0; i < static_cast<int>(1.5 * fs); ++i) {
    const double t = i / fs, in_period = std::fmod(t, period_s);
    double y = 1e-3 * std::sin(kTwoPi * 60.0 * t + 0.3) + noise(rng);
    for (int k = -1; k <= 1; ++k) {  // the pulse and its neighbours' tails
      const double u = (in_period - pulse_at_s - k * period_s) / sigma_s;
      y += pulse * std::exp(-0.5 * u * u);
    }
    r.voltage_v.push_back(amplitude_v * std::sin(kTwoPi * f * t));
    r.response.push_back(y);
  }
  const RecordAnalysis a = AnalyseRecord(r, ResponseKind::kForce, {});
  ASSERT_EQ(a.window.periods, 11.0);
  EXPECT_FALSE(a.usable[7]);
  for (int h = 1; h <= 10; ++h) {
    if (!a.usable[h - 1]) continue;
    const double w = kTwoPi * f * h;
    // C_h relative to the drive's phase (0): the pulse train's Fourier coefficient, 2 / T times its transform.
    const std::complex<double> truth = std::polar(0.5 * std::exp(-0.5 * std::pow(w * sigma_s, 2)), -w * pulse_at_s);
    EXPECT_LT(std::abs(a.harmonics[h - 1] - truth), 5 * a.harmonic_se) << "harmonic " << h;
  }
}

TEST_F(ForceCampaign, ClassifiesRecordsByImpacts) {
  // Linear displacement amplitude g V / |k_p - m w^2 + j c_p w| against |d|: the records above it hit the
  // stop (none is bistable on this grid), the others stay clear.
  const ActuatorModel t = Truth();
  for (const RecordAnalysis& a : *analyses_) {
    const double w = kTwoPi * a.drive.frequency_hz;
    const double amplitude =
        t.gain_n_per_v * a.drive.amplitude_v /
        std::abs(std::complex<double>(t.stiffness_n_per_m - t.mass_kg * w * w, t.damping_n_s_per_m * w));
    EXPECT_EQ(a.clear, amplitude < 1e-3) << a.name << ": amplitude " << amplitude;
    if (!a.clear) {
      EXPECT_NEAR(a.spikes.size(), a.window.periods, 1.0) << a.name << ": one impact per period";
    }
  }
}

TEST_F(ForceCampaign, LinearStepAloneMatchesEq3Truth) {
  const LinearStage stage = FitClearRecords(*analyses_, ResponseKind::kForce, {});
  const ActuatorModel t = Truth();
  ASSERT_TRUE(stage.summary.converged) << stage.summary.report;
  EXPECT_EQ(stage.records.size(), 8u);
  const FrfFitSummary& s = stage.summary;
  for (auto [value, se, truth, name] : {std::tuple{s.stiffness_n_per_m, s.stiffness_se, t.stiffness_n_per_m, "k_p"},
                                        std::tuple{s.damping_n_s_per_m, s.damping_se, t.damping_n_s_per_m, "c_p"},
                                        std::tuple{s.gain_n_per_v, s.gain_se, t.gain_n_per_v, "g"}}) {
    EXPECT_LE(std::abs(value - truth), kSigmaBound * se) << name << " " << value << " +- " << se << " truth " << truth;
    EXPECT_REL_NEAR(value, truth, 1e-3);
  }
}

// A suspension nonlinearity can distort every record that stays off the stop (a gen2 campaign with
// k2 = 2e4 N/m^2 had 2 of 24 records under 5 %): with fewer than 3 clear records, paper Eq. 3 takes
// the spike-free records under the least distortion limit that admits 3. Exact FRFs of the paper's
// linear part at 4 .. 8 Hz give back its parameters; the record with a spike and the most distorted
// are left out.
TEST(FitClearRecords, TooFewClearRecordsRaiseTheDistortionLimitToAdmitThree) {
  const ActuatorModel paper = PaperModel();
  const double distortions[] = {0.02, 0.08, 0.30, 0.07, 0.01};
  std::vector<RecordAnalysis> records(5);
  for (size_t i = 0; i < records.size(); ++i) {
    RecordAnalysis& a = records[i];
    a.drive.frequency_hz = 4.0 + static_cast<double>(i);
    const double w = kTwoPi * a.drive.frequency_hz;
    a.frf = -paper.gain_n_per_v * paper.mass_kg * w * w /  // paper Eq. 3, force response
            std::complex<double>(paper.stiffness_n_per_m - paper.mass_kg * w * w, paper.damping_n_s_per_m * w);
    a.distortion = distortions[i];
    a.clear = a.distortion < FitOptions{}.max_clear_distortion;
  }
  records[4].clear = false;
  records[4].spikes.push_back(Spike{0, 0.01, 5.0, 0.0100, 0.0103});
  const LinearStage stage = FitClearRecords(records, ResponseKind::kForce, {});
  EXPECT_EQ(stage.records, (std::vector<size_t>{0, 1, 3}));
  EXPECT_DOUBLE_EQ(stage.distortion_limit, 0.08);
  EXPECT_REL_NEAR(stage.summary.stiffness_n_per_m, paper.stiffness_n_per_m, 1e-9);
  EXPECT_REL_NEAR(stage.summary.damping_n_s_per_m, paper.damping_n_s_per_m, 1e-9);
  EXPECT_REL_NEAR(stage.summary.gain_n_per_v, paper.gain_n_per_v, 1e-9);

  records[3].spikes = records[4].spikes;
  records[2].spikes = records[4].spikes;  // two spike-free records left: too few for three parameters
  EXPECT_THROW(FitClearRecords(records, ResponseKind::kForce, {}), InputError);
}

// Three records at 5 Hz on the paper's linear part (linear amplitudes g V / |k_p - m_p w^2 + j c_p w|:
// 0.30, 0.59 and 0.89 mm for 0.1, 0.2, 0.3 V): clear; distorted without spikes; with an impact spike.
// The distorted one bounds neither side of |d|: its impacts may be lost in a displacement channel's
// noise (it was taken as below the stop, which put |d| above 0.59 mm).
TEST(EstimateContact, ARecordDistortedWithoutSpikesBoundsNeitherSideOfTheStop) {
  const ActuatorModel paper = PaperModel();
  FrfFitSummary linear;
  linear.stiffness_n_per_m = paper.stiffness_n_per_m;
  linear.damping_n_s_per_m = paper.damping_n_s_per_m;
  linear.gain_n_per_v = paper.gain_n_per_v;
  std::vector<RecordAnalysis> records(3);
  for (int i = 0; i < 3; ++i) {
    records[i].drive.frequency_hz = 5.0;
    records[i].drive.amplitude_v = 0.1 * (i + 1);
  }
  records[0].clear = true;
  records[2].spikes.push_back(Spike{0, 0.01, 5.0, 0.0100, 0.0103});
  const auto amplitude_m = [&](const RecordAnalysis& a) {
    const double w = kTwoPi * a.drive.frequency_hz;
    const std::complex<double> dynamic_stiffness(linear.stiffness_n_per_m - paper.mass_kg * w * w,
                                                 linear.damping_n_s_per_m * w);
    return linear.gain_n_per_v * a.drive.amplitude_v / std::abs(dynamic_stiffness);
  };
  const ContactEstimate c = EstimateContact(records, ResponseKind::kDisplacement, linear, {});
  EXPECT_DOUBLE_EQ(c.largest_clear_amplitude_m, amplitude_m(records[0]));
  EXPECT_DOUBLE_EQ(c.smallest_contacting_amplitude_m, amplitude_m(records[2]));
  EXPECT_EQ(c.records, (std::vector<size_t>{1, 2}));
}

TEST_F(ForceCampaign, ContactTimesGiveStopStiffnessWithinItsSpread) {
  const LinearStage stage = FitClearRecords(*analyses_, ResponseKind::kForce, {});
  const ContactEstimate c = EstimateContact(*analyses_, ResponseKind::kForce, stage.summary, {});
  const ActuatorModel t = Truth();
  EXPECT_EQ(c.records.size(), 16u);
  EXPECT_GT(c.spikes, 100u);
  EXPECT_TRUE(c.lower_stop);
  std::cout << "  k_s from contact times: " << c.stiffness_n_per_m << " +- " << c.stiffness_spread_n_per_m
            << " N/m (truth " << t.contact_stiffness << "), contact time " << c.contact_time_s << " s, RSD "
            << c.contact_time_rsd << "\n";
  EXPECT_LE(std::abs(c.stiffness_n_per_m - t.contact_stiffness), c.stiffness_spread_n_per_m);
  EXPECT_REL_NEAR(c.contact_time_s,
                  ContactHalfPeriodS(t.mass_kg, t.stiffness_n_per_m, t.contact_stiffness, t.damping_n_s_per_m), 0.01);
  // |d| lies between the largest clear amplitude and the smallest contacting one.
  EXPECT_LT(c.largest_clear_amplitude_m, 1e-3);
  EXPECT_GT(c.smallest_contacting_amplitude_m, 1e-3);
  EXPECT_REL_NEAR(c.stop_distance_m, 1e-3, 0.05);
}

TEST_F(ForceCampaign, JointRefinementRecoversTheTruth) {
  const FitResult& r = *result_;
  const ActuatorModel t = Truth();
  ASSERT_TRUE(r.refinement.converged) << r.refinement.report;
  EXPECT_TRUE(Recovers(r, "k_p", t.stiffness_n_per_m));
  EXPECT_TRUE(Recovers(r, "c_p", t.damping_n_s_per_m));
  EXPECT_TRUE(Recovers(r, "g", t.gain_n_per_v));
  EXPECT_TRUE(Recovers(r, "d", t.lower_stop_m));
  EXPECT_TRUE(Recovers(r, "k_s", t.contact_stiffness));
  ASSERT_NE(r.Find("c_s"), nullptr);
  EXPECT_TRUE(r.Find("c_s")->fixed);
  EXPECT_TRUE(r.Find("m_p")->fixed);
  // Only noise is left: the residual variance in units of the harmonics' standard errors is 1 (to its
  // own scatter, sqrt(2 / 475) = 0.065; 4 of those), and every record is fitted to its noise.
  EXPECT_NEAR(r.refinement.residual_variance, 1.0, 0.26);
  for (const RecordFit& f : r.records) {
    EXPECT_TRUE(f.used_refinement) << f.name;
    EXPECT_EQ(f.used_linear, f.clear) << f.name;
    EXPECT_EQ(f.used_contact, !f.clear) << f.name;
    EXPECT_LT(f.chi2, 2.5) << f.name;
    EXPECT_LT(f.nrmse, 0.01) << f.name;
    EXPECT_EQ(f.model_period, 1) << f.name;
  }
  EXPECT_LT(r.nrmse, 0.1 * r.nrmse_initial);  // the refinement did the work the staged estimates left
  EXPECT_TRUE(r.warnings.empty()) << r.warnings.front();
}

TEST_F(ForceCampaign, ResultAsJson) {
  const nlohmann::json j = FitResultToJson(*result_);
  EXPECT_EQ(j["model"], "paper");
  EXPECT_EQ(j["response"], "force");
  EXPECT_EQ(j["absolute_scale"], true);
  for (const char* name : {"k_p", "c_p", "g", "d", "k_s", "c_s", "m_p"}) {
    ASSERT_TRUE(j["parameters"].contains(name)) << name;
    EXPECT_TRUE(j["parameters"][name]["value"].is_number()) << name;
    // A fixed parameter (c_s held at 0, m_p) has no standard error (issue 16, point 5).
    const bool fixed = j["parameters"][name]["fixed"].get<bool>();
    EXPECT_EQ(fixed, std::string(name) == "c_s" || std::string(name) == "m_p") << name;
    EXPECT_EQ(j["parameters"][name]["standard_error"].is_number(), !fixed) << name;
  }
  EXPECT_EQ(j["records"].size(), 24u);
  EXPECT_EQ(j["records"][0]["used_for"], nlohmann::json({"linear", "refinement"}));
  EXPECT_TRUE(j["records"][0]["contact_time_s"].is_null());  // clear: no contact, NaN written as null
  EXPECT_EQ(j["fitted_model"]["lower_stop_m"], result_->model.lower_stop_m);
  EXPECT_TRUE(j["stages"]["refinement"]["converged"].get<bool>());
  EXPECT_EQ(j["stages"]["linear"]["records"], 8);
  EXPECT_THAT(j["identifiability"].get<std::string>(), HasSubstr("m_p"));
}

TEST_F(ForceCampaign, LinearModelUsesTheClearRecordsOnly) {
  FitOptions options;
  options.model = FitModelKind::kLinear;
  const FitResult r = FitCampaign(*campaign_, options);
  const ActuatorModel t = Truth();
  ASSERT_TRUE(r.refinement.converged) << r.refinement.report;
  EXPECT_TRUE(Recovers(r, "k_p/m_p", t.stiffness_n_per_m / t.mass_kg));
  EXPECT_TRUE(Recovers(r, "c_p/m_p", t.damping_n_s_per_m / t.mass_kg));
  EXPECT_TRUE(Recovers(r, "g", t.gain_n_per_v));  // a force response fixes the absolute gain
  EXPECT_EQ(r.Find("k_s"), nullptr);
  EXPECT_FALSE(r.model.HasLowerStop());
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_THAT(r.warnings[0], HasSubstr("16 records are not clear of the stop"));
  for (const RecordFit& f : r.records) {
    EXPECT_EQ(f.used_refinement, f.clear) << f.name;
    if (!f.clear) {
      EXPECT_GT(f.nrmse, 0.1) << f.name << ": the linear model cannot follow an impacting record";
    }
  }
}

// ---- Other responses, unknown scale ------------------------------------------------------------------

TEST(FitCampaign, AccelerationWithUnknownSensitivityGivesRatios) {
  // An accelerometer whose true sensitivity is 25 % above the nominal one: the fit cannot know, so
  // g and d come out 25 % high, and the ratios that do not depend on it are exact.
  SynthOptions o = RigOptions(ResponseKind::kAcceleration);
  o.sensitivity_error = 0.25;
  o.nominal = true;    // the manifest's sensitivity is the data sheet's
  o.seed = kSeed + 1;  // a noise draw of its own
  const auto start = std::chrono::steady_clock::now();
  const FitResult r = FitCampaign(RigCampaign(o));
  std::cout << "  synthesis and fit: " << SecondsSince(start) << " s\n";
  const ActuatorModel t = Truth();
  ASSERT_TRUE(r.refinement.converged) << r.refinement.report;
  EXPECT_FALSE(r.absolute_scale);
  EXPECT_TRUE(Recovers(r, "k_p/m_p", t.stiffness_n_per_m / t.mass_kg));
  EXPECT_TRUE(Recovers(r, "c_p/m_p", t.damping_n_s_per_m / t.mass_kg));
  EXPECT_TRUE(Recovers(r, "k_s/m_p", t.contact_stiffness / t.mass_kg));
  EXPECT_TRUE(Recovers(r, "d/g", t.lower_stop_m / t.gain_n_per_v));
  ASSERT_NE(r.Find("g"), nullptr);
  EXPECT_FALSE(r.Find("g")->identifiable);
  EXPECT_FALSE(r.Find("d")->identifiable);
  EXPECT_REL_NEAR(r.Find("g")->value, 1.25 * t.gain_n_per_v, 1e-3);
  EXPECT_REL_NEAR(r.Find("d")->value, 1.25 * t.lower_stop_m, 1e-3);
  EXPECT_EQ(r.Find("k_p"), nullptr);
  EXPECT_THAT(r.identifiability, HasSubstr("d/g"));
}

// ---- Records that sample every period alike ---------------------------------------------------------

// A record analysed over `periods` drive periods at f [Hz] on a 51.2 kHz grid.
RecordAnalysis AnalysedOver(double f, double periods) {
  RecordAnalysis a;
  a.sample_rate_hz = 51200.0;
  a.drive.frequency_hz = f;
  const auto samples = static_cast<size_t>(std::llround(periods * a.sample_rate_hz / f));
  a.window = SampleWindow{0, samples, periods};
  return a;
}

// Where the window's periods start between two samples (fit_orbit.h SamplesEveryPeriodAlike).
TEST(SamplesEveryPeriodAlike, OnlyWherePeriodsStartWithinHalfASampleOfOneAnother) {
  using internal::SamplesEveryPeriodAlike;
  EXPECT_TRUE(SamplesEveryPeriodAlike(AnalysedOver(5.0, 5)));        // 10,240 samples a period
  EXPECT_TRUE(SamplesEveryPeriodAlike(AnalysedOver(4.9999998, 5)));  // as estimated: 0.002 samples apart in all
  EXPECT_TRUE(SamplesEveryPeriodAlike(AnalysedOver(8.0, 8)));
  EXPECT_TRUE(SamplesEveryPeriodAlike(AnalysedOver(7.0, 1)));        // one period: its impacts sampled once
  EXPECT_FALSE(SamplesEveryPeriodAlike(AnalysedOver(6.0, 6)));       // 8,533 1/3: three positions
  EXPECT_FALSE(SamplesEveryPeriodAlike(AnalysedOver(5.0371, 5)));    // 10,164.58: spread over the sample
  EXPECT_FALSE(SamplesEveryPeriodAlike(AnalysedOver(51200.0 / 10240.5, 4)));  // two positions half a sample apart
}

// Impacts at 8 Hz on a 51.2 kHz grid (6,400 samples a period) are sampled alike in every period; at 6,
// 7 and 8.0917 Hz they are not. The fit says so once, naming 8 Hz alone.
TEST(FitCampaign, WarnsWhereImpactsAreSampledAlikeInEveryPeriod) {
  SynthOptions o;
  o.frequencies_hz = {6, 7, 8, 8.0917};
  o.amplitudes_v = {0.1, 0.5};  // clear of the stop, then impacts at every frequency
  o.settle_s = 5.0;
  o.noise_rms_v = 0.0005;
  o.seed = 5801;
  const FitResult r = FitCampaign(Synthesize(PaperModel(), o).campaign);
  ASSERT_TRUE(r.refinement.converged) << r.refinement.report;
  for (const RecordFit& f : r.records)
    EXPECT_EQ(f.model_contacts_per_period > 0.0, f.amplitude_v > 0.3) << f.name;
  ASSERT_EQ(r.warnings.size(), 1u) << ::testing::PrintToString(r.warnings);
  EXPECT_THAT(r.warnings[0], HasSubstr("records at 8 Hz touch the stop with a drive period of a whole number of "
                                       "samples at 51200 Hz"));
}

// ---- Bad input ---------------------------------------------------------------------------------------

// A wide |d| bracket: the campaign's 6 x 4 grid with every fourth record held out (as the diagnosis
// splits it), on an actuator (found by the second generator, tools/gen2, seed 1301) whose 0.3 V row
// already reaches the stop at 5-9 Hz while its 0.3 V, 11 Hz record is held out. The bracket is then
// 0.36 .. 0.92 mm around |d| = 0.906 mm, and its geometric middle started the refinement in another
// minimum (k_p 213 N/m, g 0.49 N/V, both stop parameters on their bounds). The start chosen on a grid
// over the bracket by the contacting records' chi-square leads to the truth.
TEST(FitCampaign, AWideStopBracketStartsTheRefinementAtItsBestPoint) {
  ActuatorModel truth = PaperModel();
  truth.stiffness_n_per_m = 112.34679877904951;
  truth.damping_n_s_per_m = 1.3919461561420108;
  truth.gain_n_per_v = 0.2813105807582602;
  truth.lower_stop_m = -0.0009058240828179618;
  truth.contact_stiffness = 1201787.9133958821;
  SynthOptions o;
  o.frequencies_hz = {5, 6, 7, 8, 9, 11};
  o.amplitudes_v = {0.1, 0.3, 0.4, 0.5};
  o.settle_s = 5.0;
  o.noise_rms_v = 0.0005;
  o.offset_v = 0.01;
  o.hum_v = 0.0005;
  o.seed = 1301;
  Campaign c = Synthesize(truth, o).campaign;
  std::vector<Recording> kept;
  for (size_t i = 0; i < c.records.size(); ++i)
    if (i % 4 != 3) kept.push_back(c.records[i]);
  c.records = kept;
  const FitResult r = FitCampaign(c);
  ASSERT_TRUE(r.refinement.converged) << r.refinement.report;
  EXPECT_LT(r.contact.largest_clear_amplitude_m, 0.5 * r.contact.smallest_contacting_amplitude_m);  // wide
  EXPECT_TRUE(Recovers(r, "k_p", truth.stiffness_n_per_m));
  EXPECT_TRUE(Recovers(r, "g", truth.gain_n_per_v));
  EXPECT_TRUE(Recovers(r, "d", truth.lower_stop_m));
}

// A stop no record's orbit reaches leaves d and k_s out of the Jacobian's rank: they are reported
// without an error and not identifiable (they were reported with errors of 0, as was every other
// parameter), keep their staged values, and the fit converges on k_p, c_p and g, which keep the errors
// of the problem that holds the stop (it ended NOT converged).
TEST(FitCampaign, AStopNoOrbitReachesIsNotIdentifiedAndTheOthersKeepTheirErrors) {
  SynthOptions o;
  o.frequencies_hz = {5, 6, 7, 8, 9, 11};
  o.amplitudes_v = {0.05, 0.1, 0.15};  // below the stop at every frequency
  o.noise_rms_v = 0.0005;
  o.offset_v = 0.01;
  o.hum_v = 0.0005;
  o.seed = 1109;
  const ActuatorModel truth = PaperModel();
  const FitResult r = FitCampaign(Synthesize(truth, o).campaign);
  for (const RecordFit& f : r.records) ASSERT_EQ(f.model_contacts_per_period, 0.0) << f.name;
  EXPECT_TRUE(r.refinement.converged) << r.refinement.report;
  EXPECT_EQ(r.refinement.unidentified, (std::vector<std::string>{"d", "k_s"})) << r.refinement.report;
  EXPECT_THAT(r.refinement.report, HasSubstr("the stop's parameters (d, k_s) are not identifiable from these records"));
  EXPECT_THAT(r.warnings, Contains(HasSubstr("keep their staged values, which are not estimates")));
  EXPECT_EQ(r.model.lower_stop_m, r.staged.lower_stop_m);
  EXPECT_EQ(r.model.contact_stiffness, r.staged.contact_stiffness);
  for (const char* name : {"d", "k_s"}) {
    const FitParameter* p = r.Find(name);
    ASSERT_NE(p, nullptr) << name;
    EXPECT_FALSE(p->identifiable) << name;
    EXPECT_TRUE(std::isnan(p->standard_error)) << name << " +- " << p->standard_error;
    EXPECT_THAT(p->note, HasSubstr("not identifiable from these records")) << name;
  }
  EXPECT_TRUE(Recovers(r, "k_p", truth.stiffness_n_per_m));
  EXPECT_TRUE(Recovers(r, "c_p", truth.damping_n_s_per_m));
  EXPECT_TRUE(Recovers(r, "g", truth.gain_n_per_v));
  // The bound the records set on |d|: the fitted orbits' largest excursion, which below the stop is the
  // linear model's largest amplitude, g V / |k_p - m_p w^2 + j c_p w| (paper Eq. 1 without the stop),
  // to the sampling of its crest (1 - cos(pi f / fs) < 1e-6 at 11 Hz and 51.2 kHz).
  double amplitude_m = 0.0;
  for (const RecordFit& f : r.records) {
    if (!f.used_refinement) continue;
    const double w = kTwoPi * f.frequency_hz;
    const std::complex<double> dynamic_stiffness(r.model.stiffness_n_per_m - r.model.mass_kg * w * w,
                                                 r.model.damping_n_s_per_m * w);
    amplitude_m = std::max(amplitude_m, r.model.gain_n_per_v * f.amplitude_v / std::abs(dynamic_stiffness));
  }
  EXPECT_REL_NEAR(r.refinement.largest_excursion_m, amplitude_m, 1e-5);
  EXPECT_LT(r.refinement.largest_excursion_m, -truth.lower_stop_m);
  EXPECT_THAT(r.warnings, Contains(HasSubstr(" m toward the stop, so |d| is above that")));
}

TEST(FitCampaign, RejectsAnEmptyCampaign) {
  try {
    FitCampaign(Campaign{});
    FAIL() << "no records";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "records");
    EXPECT_THAT(e.what(), HasSubstr("holds no records"));
  }
}

TEST(FitCampaign, RejectsACampaignWithoutClearRecords) {
  SynthOptions o = RigOptions(ResponseKind::kForce);
  o.amplitudes_v = {0.5};  // every record hits the stop
  o.frequencies_hz = {7, 9, 11};
  o.settle_s = 1.0;
  try {
    FitCampaign(RigCampaign(o));
    FAIL() << "no clear records";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "records");
    EXPECT_THAT(e.what(), HasSubstr("0 of 3 records are free of impact spikes (3 show them)"));
    EXPECT_THAT(e.what(), HasSubstr("needs at least 3 records clear of the stop"));
  }
}

TEST(FitCampaign, RejectsBroadbandOnlyAndBrokenRecords) {
  SynthOptions o = RigOptions(ResponseKind::kForce);
  o.amplitudes_v = {0.1};
  o.frequencies_hz = {8};
  o.settle_s = 0.5;
  Campaign c = RigCampaign(o);
  c.records[0].broadband = true;
  EXPECT_THROW(
      {
        try {
          FitCampaign(c);
        } catch (const InputError& e) {
          EXPECT_THAT(e.what(), HasSubstr("no stepped-sine record"));
          throw;
        }
      },
      InputError);
  c.records[0].broadband = false;
  c.records[0].response.pop_back();
  try {
    FitCampaign(c);
    FAIL() << "channels of different lengths";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "rec_001.csv");
    EXPECT_THAT(e.what(), HasSubstr("51200 voltage samples but 51199 response samples"));
  }
  c.records[0].response.push_back(std::nan(""));
  try {
    FitCampaign(c);
    FAIL() << "a NaN sample";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("rec_001.csv"));
    EXPECT_THAT(e.what(), HasSubstr("non-finite"));
  }
  FitOptions bad;
  bad.harmonic_orders = 0;
  try {
    FitCampaign(c, bad);
    FAIL() << "bad options";
  } catch (const InputError& e) {
    EXPECT_EQ(e.field(), "harmonic_orders");
  }
  EXPECT_THROW(ParseFitModel("cubic"), InputError);
}

TEST(FitOptionsTest, IsValidNamesTheFieldAndWhatIsWrong) {
  using ::strokelab::testing::IsValidText;
  FitOptions options;
  EXPECT_EQ(IsValidText(options), "");
  options.harmonic_orders = 0;
  EXPECT_EQ(IsValidText(options), "harmonic_orders: must be >= 1, got 0");
  options.mass_kg = -0.5;  // mass_kg is checked first
  EXPECT_EQ(IsValidText(options), "mass_kg: must be a finite number > 0, got -0.5");
  options = FitOptions{};
  options.spikes.baseline_harmonics = -1;
  EXPECT_EQ(IsValidText(options), "spikes.baseline_harmonics: must be >= 0");
}

// The one table of the fit's option names (fit.h): every name pinned, and each field named as IsValid
// names it.
TEST(FitOptionsTest, FieldTableNamesEachOptionInJobsAndOnTheCommandLine) {
  EXPECT_EQ(::strokelab::testing::OptionNames(FitOptionFields()),
            "harmonic_orders harmonics --harmonics; mass_kg mass_kg --mass-kg; mains_frequency_hz mains_hz --mains-hz; "
            "max_clear_distortion max_distortion --max-distortion; max_iterations max_iterations --max-iterations; "
            "fit_contact_damping fit_contact_damping --fit-contact-damping; refine refine --no-refine (clears); "
            "max_refinement_seconds max_refinement_seconds -");
  EXPECT_EQ(FindOption(FitOptionFields(), "mass_kg"), &FitOptionFields()[1]);
  EXPECT_EQ(FindOption(FitOptionFields(), "model"), nullptr);
}

TEST(FitOptionsTest, FieldTableUsesTheFieldNamesOfIsValid) {
  ::strokelab::testing::ExpectTableFieldsAreIsValidFields<FitOptions>(FitOptionFields());
}

}  // namespace
}  // namespace strokelab
