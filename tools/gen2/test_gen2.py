#!/usr/bin/python3
"""Checks of the second generator against strokelab (README.md, "Checks").

    STROKELAB_BINARY=build/release/strokelab /usr/bin/python3 tools/gen2/test_gen2.py        # all
    STROKELAB_BINARY=... /usr/bin/python3 -m unittest -v test_gen2.FastTest                    # ctest gen2_fast

Noiseless records of both generators for the same drive are compared by the complex amplitudes of
their first harmonics (a DFT over the whole periods of the record); then noise, offset and hum are
checked against what was asked, and `strokelab fit` / `strokelab diagnose` must read the campaigns.
"""
import json
import math
import os
import subprocess
import sys
import tempfile
import unittest

import numpy as np

from campaign_io import harmonics, read_campaign

HERE = os.path.dirname(os.path.abspath(__file__))
GENERATOR = os.path.join(HERE, "synth_campaign.py")
PYTHON = "/usr/bin/python3"


def binary():
    path = os.environ.get("STROKELAB_BINARY", os.path.join(HERE, "..", "..", "build", "release", "strokelab"))
    if not os.path.exists(path):
        raise unittest.SkipTest(f"no strokelab binary at {path} (set STROKELAB_BINARY)")
    return path


def run(command, **kwargs):
    result = subprocess.run(command, capture_output=True, text=True, **kwargs)
    if result.returncode != 0:
        raise AssertionError(f"{' '.join(command)} failed ({result.returncode}):\n{result.stdout}\n{result.stderr}")
    return result


def generate(out, flags):
    run([PYTHON, GENERATOR, "--out", out] + list(flags))


def compare(test, common, gen2_extra=(), tolerance=1e-6, label=""):
    """Both generators on the same drive, no noise: max over records and harmonics of
    |A_h(gen2) - A_h(synth)| / |A_1(synth)|; returns it (and prints the worst harmonic-relative one)."""
    with tempfile.TemporaryDirectory(prefix="gen2_") as work:
        run([PYTHON, GENERATOR, "--out", os.path.join(work, "gen2")] + list(common) + list(gen2_extra))
        run([binary(), "synth", "--out", os.path.join(work, "synth")] + list(common))
        ours, theirs = read_campaign(os.path.join(work, "gen2")), read_campaign(os.path.join(work, "synth"))
        test.assertEqual(len(ours), len(theirs))
        worst, worst_each = 0.0, 0.0
        for (entry, header, a, sa, fs), (entry_b, header_b, b, sb, _) in zip(ours, theirs):
            test.assertEqual(header, header_b)
            test.assertEqual((entry["drive_frequency_hz"], entry["drive_amplitude_v"]),
                             (entry_b["drive_frequency_hz"], entry_b["drive_amplitude_v"]))
            test.assertEqual(a.shape, b.shape)
            np.testing.assert_allclose(a[:, 0], b[:, 0], rtol=1e-9, atol=0)   # time (synth writes fewer digits)
            np.testing.assert_allclose(a[:, 1], b[:, 1], rtol=0, atol=1e-9)    # drive voltage (10 digits)
            f = entry["drive_frequency_hz"]
            ha, hb = harmonics(a[:, 2] / sa, f, fs), harmonics(b[:, 2] / sb, f, fs)
            difference = np.abs(ha - hb) / abs(hb[0])
            each = np.abs(ha - hb) / np.maximum(np.abs(hb), 1e-300)
            significant = np.abs(hb) > 1e-6 * abs(hb[0])
            worst = max(worst, difference.max())
            worst_each = max(worst_each, each[significant].max())
        print(f"\n  {label}: max |dA_h|/|A_1| = {worst:.2e}; max |dA_h|/|A_h| (harmonics above 1e-6 A_1) = "
              f"{worst_each:.2e}", file=sys.stderr)
        test.assertLess(worst, tolerance, label)
        return worst


FAST = ["--frequencies-hz", "8", "--amplitudes-v", "0.1,0.5", "--settle-s", "1.5", "--duration-s", "0.25"]


class FastTest(unittest.TestCase):
    """A few seconds: 2 short records of the paper's model (one linear, one hitting the stop)."""

    def test_paper_model_agrees_with_strokelab_synth(self):
        compare(self, FAST, tolerance=1e-8, label="paper model, 8 Hz, 0.1 and 0.5 V")

    def test_a_grazing_contact_is_not_stepped_over(self):
        # The stop 1.5 um inside the orbit's lowest point: at rtol 1e-10 solve_ivp's steps spanned the
        # whole contact, which it then missed on every other period (a period-2 record where the model's
        # orbit is period-1, seed 9606's truth).
        grazing = {"mass_kg": 0.032, "damping_n_s_per_m": 1.1788920056252452, "stiffness_n_per_m": 119.3889633600148,
                   "gain_n_per_v": 0.272452640789929, "lower_stop_m": -0.0009103314947283824,
                   "contact_stiffness": 1393215.9706921198, "contact_law": "linear"}
        with tempfile.TemporaryDirectory(prefix="gen2_grazing_") as work:
            model = os.path.join(work, "grazing.json")
            with open(model, "w") as f:
                json.dump(grazing, f)
            compare(self, ["--model", model, "--frequencies-hz", "8", "--amplitudes-v", "0.25", "--settle-s", "3",
                           "--duration-s", "0.25"], tolerance=1e-6, label="grazing contact, 8 Hz, 0.25 V")

    def test_noise_offset_and_hum_are_what_was_asked(self):
        with tempfile.TemporaryDirectory(prefix="gen2_noise_") as work:
            base = ["--frequencies-hz", "8", "--amplitudes-v", "0.1,0.5", "--settle-s", "0.3", "--duration-s", "0.25",
                    "--seed", "5"]
            generate(os.path.join(work, "clean"), base)
            generate(os.path.join(work, "noisy"), base + ["--noise-rms", "0.002", "--offset-v", "0.01",
                                                          "--hum-v", "0.003", "--voltage-noise-rms", "0.001"])
            clean, noisy = read_campaign(os.path.join(work, "clean")), read_campaign(os.path.join(work, "noisy"))
            for (_, _, a, _, fs), (_, _, b, _, _) in zip(clean, noisy):
                extra = b[:, 2] - a[:, 2]
                t = a[:, 0]
                self.assertAlmostEqual(np.mean(extra), 0.01, delta=3 * 0.002 / math.sqrt(len(t)) + 1e-4)
                hum = abs(2 * np.mean((extra - 0.01) * np.exp(-2j * math.pi * 50 * t)))
                self.assertAlmostEqual(hum, 0.003, delta=2e-4)
                residual = extra - 0.01
                hum_removed = residual - 2 * np.real(np.mean(residual * np.exp(-2j * math.pi * 50 * t))
                                                     * np.exp(2j * math.pi * 50 * t))
                self.assertAlmostEqual(np.std(hum_removed), 0.002, delta=0.002 * 0.05)
                self.assertAlmostEqual(np.std(b[:, 1] - a[:, 1]), 0.001, delta=0.001 * 0.05)
            with open(os.path.join(work, "noisy", "truth.json")) as f:
                truth = json.load(f)
            self.assertEqual(truth["noise_rms_v"], 0.002)
            self.assertEqual(len({r["hum_phase_rad"] for r in truth["records"]}), 2)

    def test_strokelab_fit_reads_the_campaign(self):
        with tempfile.TemporaryDirectory(prefix="gen2_fit_") as work:
            out = os.path.join(work, "c")
            # The linear fit needs 3 records clear of the stop.
            generate(out, ["--frequencies-hz", "8,10,13", "--amplitudes-v", "0.1", "--settle-s", "1",
                           "--duration-s", "0.5", "--noise-rms", "0.0005", "--perturb", "k_p=0.1,g=0.1", "--seed", "9"])
            result = run([binary(), "fit", "--data", out, "--json"])
            json.loads(result.stdout)


class UnlistedEffectsTest(unittest.TestCase):
    """The effects in no library that are linear in the motion, against their closed forms (README.md)."""

    def test_creep_heating_and_sensor_against_the_linear_response(self):
        k_m, tau_m, alpha_g, a_s = 30.0, 5e-3, 0.4, 0.5
        with tempfile.TemporaryDirectory(prefix="gen2_unlisted_") as work:  # 8 and 12.8 Hz: whole samples a period
            out = os.path.join(work, "c")
            generate(out, ["--model", "linear", "--response", "displacement", "--frequencies-hz", "8,12.8",
                           "--amplitudes-v", "0.1,0.5", "--settle-s", "2", "--duration-s", "0.5",
                           "--effect", f"suspension_creep={k_m}", "--effect", f"gain_compression={alpha_g}",
                           "--effect", f"sensor_quadratic={a_s}"])
            with open(os.path.join(out, "truth.json")) as f:
                model = json.load(f)["model"]
            m, c_p, k_p, g = (model[k] for k in ("mass_kg", "damping_n_s_per_m", "stiffness_n_per_m", "gain_n_per_v"))
            c_emf = model["back_emf_damping_n_s_per_m"]
            for entry, _, data, sensitivity, fs in read_campaign(out):
                w, amplitude = 2 * math.pi * entry["drive_frequency_hz"], entry["drive_amplitude_v"]
                compression = 1 / (1 + alpha_g * amplitude ** 2)
                creep = k_m * 1j * w * tau_m / (1 + 1j * w * tau_m)  # the Maxwell element's complex stiffness
                dynamic = k_p - m * w * w + 1j * w * (c_p - c_emf + c_emf * compression) + creep
                # The drive's complex amplitude from its own column; y = s x + a_s (s x)^2 puts a_s y1^2 / 2 at 2 w.
                drive = harmonics(data[:, 1], entry["drive_frequency_hz"], fs, 1)[0]
                y1 = sensitivity * g * compression / dynamic * drive
                h = harmonics(data[:, 2], entry["drive_frequency_hz"], fs, 2)
                self.assertLess(abs(h[0] - y1) / abs(y1), 1e-7, entry)
                self.assertLess(abs(h[1] - a_s * y1 * y1 / 2) / abs(a_s * y1 * y1 / 2), 1e-6, entry)


class MultisineTest(unittest.TestCase):
    """The multisine drive (gen2_integrate.MultisineDrive) on the linear model, against its closed form."""

    def test_each_line_is_the_linear_response_and_the_level_is_the_rms(self):
        level, low, high, period = 0.3, 2.0, 200.0, 0.5
        with tempfile.TemporaryDirectory(prefix="gen2_multisine_") as work:
            out = os.path.join(work, "c")
            generate(out, ["--model", "linear", "--response", "displacement", "--excitation", "multisine",
                           "--levels-v-rms", str(level), "--band-hz", f"{low}:{high}", "--duration-s", str(period),
                           "--settle-s", "3", "--sample-rate-hz", "8192"])
            with open(os.path.join(out, "truth.json")) as f:
                truth = json.load(f)
            model = truth["model"]
            m, c_p, k_p, g = (model[k] for k in ("mass_kg", "damping_n_s_per_m", "stiffness_n_per_m", "gain_n_per_v"))
            [(entry, _, data, sensitivity, fs)] = read_campaign(out)
            self.assertEqual(entry, {"file": "rec_001.csv", "excitation": "broadband"})
            voltage, response = data[:, 1], data[:, 2]
            n = len(voltage)
            self.assertEqual(n, round(period * fs))
            # Lines at k / period in 2 .. 200 Hz, odd k: 1 .. 99 for 0.5 s (2, 6, .. 198 Hz).
            lines = [k for k in range(1, round(high * period) + 1) if k % 2 == 1 and k / period >= low]
            self.assertEqual(truth["records"][0]["lines"], len(lines))
            self.assertAlmostEqual(math.sqrt(np.mean(voltage ** 2)), level, delta=1e-12)
            u, y = np.fft.rfft(voltage) / n, np.fft.rfft(response) / n
            even = [k for k in range(1, round(high * period)) if k % 2 == 0]
            self.assertLess(np.max(np.abs(u[even])), 1e-12)  # the odd grid leaves the even lines empty
            worst = 0.0
            for k in lines:
                w = 2 * math.pi * k / period
                x = g / (k_p - m * w * w + 1j * w * c_p) * u[k]  # x = g u / (k_p - m w^2 + j w c_p)
                worst = max(worst, abs(y[k] - sensitivity * x) / abs(sensitivity * x))
            self.assertLess(worst, 1e-6)


COMMON = ["--frequencies-hz", "6,8,13", "--amplitudes-v", "0.1,0.3,0.5", "--settle-s", "5", "--duration-s", "1"]


class AgreementTest(unittest.TestCase):
    """The paper's model and two library effects, 9 records each (about a minute each)."""

    def test_paper_model(self):
        compare(self, COMMON, tolerance=1e-8, label="paper model")

    def test_cubic_stiffness(self):
        compare(self, COMMON + ["--set", "k3=1.5e7"], label="k3 = 1.5e7 N/m^3")

    def test_hertzian_contact(self):
        compare(self, COMMON + ["--set", "k_s=1.5e7", "--set", "contact_law=hertzian"],
                label="Hertzian contact k_s = 1.5e7 N/m^1.5")


class ReadersTest(unittest.TestCase):
    """strokelab fit and diagnose read a noisy 24-record campaign with a new effect."""

    def test_fit_and_diagnose_read_it(self):
        with tempfile.TemporaryDirectory(prefix="gen2_diag_") as work:
            out = os.path.join(work, "c")
            generate(out, ["--frequencies-hz", "5,6,7,8,9,11", "--amplitudes-v", "0.1,0.3,0.4,0.5",
                           "--settle-s", "5", "--duration-s", "1", "--noise-rms", "0.0005", "--offset-v", "0.01",
                           "--hum-v", "0.0005", "--perturb", "k_p=0.1,c_p=0.1,g=0.1,d=0.1,k_s=0.1",
                           "--effect", "quadratic_damping=2", "--seed", "77", "--jobs", "2"])
            json.loads(run([binary(), "fit", "--data", out, "--json"]).stdout)
            json.loads(run([binary(), "diagnose", "--data", out, "--json"]).stdout)


# The diagnosis on concealed campaigns of this generator (issue 13, "What it must show"): the
# diagnosis tests' campaign shape (6 frequencies x 4 amplitudes, 0.5 mV noise, 10 mV offset, 0.5 mV
# hum, k_p, c_p, g, d, k_s perturbed by up to 10 %), one actuator (perturbation seed 1400) and new
# noise seeds 1401-1410, never diagnosed before these tests were written. About a minute per case
# (generation; the diagnosis takes seconds): ctest label `slow`.
CAMPAIGN = ["--frequencies-hz", "5,6,7,8,9,11", "--amplitudes-v", "0.1,0.3,0.4,0.5", "--settle-s", "5",
            "--duration-s", "1", "--noise-rms", "0.0005", "--offset-v", "0.01", "--hum-v", "0.0005",
            "--perturb", "k_p=0.1,c_p=0.1,g=0.1,d=0.1,k_s=0.1", "--perturb-seed", "1400", "--jobs", "2"]


# Another rig (later flags override CAMPAIGN's): an accelerometer at 44.1 kHz, 1.5 s records, 60 Hz hum.
ACCELERATION_44K = ["--frequencies-hz", "4.5,6,7.5,9,10.5,12", "--amplitudes-v", "0.15,0.3,0.45", "--duration-s", "1.5",
                    "--sample-rate-hz", "44100", "--response", "acceleration", "--offset-v", "0", "--hum-v", "0.001",
                    "--hum-hz", "60"]


class DiagnosisTest(unittest.TestCase):
    """Library effects alone and in pairs are named with their parameters within 25 % and the held-out
    error at least halved, nothing else is named; controls get nothing named and no `unexplained`;
    an effect in no library (damping that grows with x^2) gets `unexplained` and no library effect
    named; the coil's inductance is named, tried where the other effects leave the misfit unexplained or
    on request (--coil-inductance), and left unexplained with --no-coil-when-unexplained.
    One case fails today and is marked an expected failure with what happens:
    an unexpected success is reported, so a fix shows."""

    def diagnose(self, seed, effects, options=()):
        with tempfile.TemporaryDirectory(prefix="gen2_diagnosis_") as work:
            out = os.path.join(work, "c")
            generate(out, CAMPAIGN + ["--seed", str(seed)] + effects)
            d = json.loads(run([binary(), "diagnose", "--data", out, "--json", "--map-frequency-points", "0",
                                *options]).stdout)
        print(f"\n  seed {seed} {' '.join(effects)}: {d['conclusion'][:300]}", file=sys.stderr)
        return d

    def expect_named(self, seed, effects, truth, options=()):
        """truth: {effect id: {parameter: true value}}; exactly these effects must be named."""
        d = self.diagnose(seed, effects, options)
        named = {m["effect"]: m for m in d["missing_physics"]}
        self.assertEqual(set(named), set(truth), d["conclusion"])
        for effect, parameters in truth.items():
            for key, value in parameters.items():
                estimate = named[effect]["parameters"][key]["value"]
                self.assertLess(abs(estimate - value), 0.25 * abs(value), f"{effect} {key} = {estimate}, truth {value}")
        self.assertLessEqual(d["fit_after"]["heldout_nrmse"], 0.5 * d["fit_before"]["heldout_nrmse"])

    def expect_nothing(self, seed, effects, unexplained, options=()):
        d = self.diagnose(seed, effects, options)
        self.assertEqual(d["missing_physics"], [], d["conclusion"])
        if unexplained:
            self.assertIsNotNone(d["unexplained"], d["conclusion"])
        else:
            self.assertIsNone(d["unexplained"], d["conclusion"])

    def test_control_1(self):
        self.expect_nothing(1401, [], unexplained=False)

    def test_control_2(self):
        self.expect_nothing(1402, [], unexplained=False)

    def test_force_factor(self):
        self.expect_named(1403, ["--effect", "force_factor=-5e4", "--set", "b1=-10"],
                          {"force_factor": {"b1": -10.0, "b2": -5e4}})

    def test_quadratic_damping(self):
        self.expect_named(1404, ["--effect", "quadratic_damping=1"], {"quadratic_damping": {"c2": 1.0}})

    # Open (issue 13), as of 2026-11-26: the pair's fit lowers the fit records' chi-square (held-out gain
    # over the base 72,030 against k3 alone's 58,911 in their own variances) but not the held-out
    # records' (by -7.4 variances over k3 alone): cubic_stiffness is named, with "more is missing" (1.26
    # x noise). Which records are held out decides whether the contact's law can be seen there.
    @unittest.expectedFailure
    def test_cubic_stiffness_and_hertzian_contact(self):
        self.expect_named(1405, ["--effect", "cubic_stiffness=1.5e7", "--effect", "hertzian_contact=1.5e7"],
                          {"cubic_stiffness": {"k3": 1.5e7}, "hertzian_contact": {"k_s": 1.5e7}})

    def test_quadratic_damping_and_cubic_stiffness(self):
        self.expect_named(1406, ["--effect", "quadratic_damping=1", "--effect", "cubic_stiffness=1.5e7"],
                          {"quadratic_damping": {"c2": 1.0}, "cubic_stiffness": {"k3": 1.5e7}})

    # Nothing was named at 0.24.0 ("unexplained" at 8.05 x noise); the selection's look-ahead (0.25.0)
    # names the pair.
    def test_force_factor_and_dry_friction(self):
        self.expect_named(1407, ["--effect", "force_factor=-5e4", "--set", "b1=-10", "--effect", "dry_friction=0.003"],
                          {"force_factor": {"b1": -10.0, "b2": -5e4}, "dry_friction": {"friction_n": 0.003}})

    # By default the coil's inductance is tried only where the other effects leave the misfit
    # unexplained (its fits are slow, diagnose.h): here they do, and it is named.
    def test_coil_inductance_tried_where_unexplained(self):
        self.expect_named(1408, ["--effect", "coil_inductance=2e-3"], {"coil_inductance": {"tau_e": 2e-3 / 3.0}})

    # Never tried: it must then stay unexplained, and nothing be named for it.
    def test_coil_inductance_never_tried(self):
        self.expect_nothing(1412, ["--effect", "coil_inductance=2e-3"], unexplained=True,
                            options=["--no-coil-when-unexplained"])

    # On request: named, tau_e = L / R with gen2's coil resistance of 3 Ohm.
    def test_coil_inductance_on_request(self):
        self.expect_named(1410, ["--effect", "coil_inductance=2e-3"], {"coil_inductance": {"tau_e": 2e-3 / 3.0}},
                          ["--coil-inductance"])

    # An expected failure until 0.32.0: contact_damping + cubic_stiffness was named beside "unexplained"
    # (8.78 x noise), as a partial explanation; with standard errors scaled by the misfit, neither stands.
    def test_position_damping_in_no_library(self):
        self.expect_nothing(1409, ["--effect", "position_damping=2e5"], unexplained=True)

    # A second stop behind a hard first one, through an acceleration channel at 44.1 kHz (1.5 s records,
    # 60 Hz hum; the actuator of seed 9708): without it the base fit ends with k_s on its bound, a
    # thirtieth of what the contact times say, and the second stop's fit from there stayed below the
    # stop ("unexplained" at 1.2e3 x noise, nothing named). The single effects now start from the
    # staged estimates as well.
    def test_second_stop_behind_a_base_fit_on_its_bound(self):
        self.expect_named(1411, ["--effect", "second_stop=1.45e-3", *ACCELERATION_44K, "--perturb-seed", "9708"],
                          {"second_stop": {"d_upper": 1.45e-3}})


if __name__ == "__main__":
    unittest.main(verbosity=2)
