#!/usr/bin/python3
"""Times strokelab's engines against scipy's solve_ivp on the paper's record and checks accuracy.

The record: paper model (Table 2), 8 Hz / 0.5 V (saturating, one contact per period), 10 s at
51.2 kHz from rest, 512,000 samples. Every method is compared with the exact engine's series
(read from `strokelab simulate --out`).

scipy integrates the continuous form of paper Eq. 2 (shared/docs/paper-notes.md),

    m x'' = g V sin(w t) - k_p x - c_p x' + (x < d ? k_s (d - x) : 0),

one linear region at a time: a terminal event at x = d ends the region and the integration restarts
in the other one, so no step straddles the kink. The blocked force is f = m x'' from that right-hand
side at each sample.

Usage: /usr/bin/python3 tests/bench/compare_scipy.py [--strokelab build/release/strokelab] [--repeats 5]
Uses numpy, scipy and the standard library only.
"""
import argparse
import json
import math
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.integrate import solve_ivp

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]
FREQUENCY_HZ = 8.0
AMPLITUDE_V = 0.5
DURATION_S = 10.0
SAMPLE_RATE_HZ = 51200.0


def simulate_args(binary, method):
    return [str(binary), "simulate", "--model", "paper", "--frequency-hz", str(FREQUENCY_HZ),
            "--amplitude-v", str(AMPLITUDE_V), "--duration-s", str(DURATION_S),
            "--sample-rate-hz", str(SAMPLE_RATE_HZ), "--method", method, "--json"]


def run_cli(args):
    """Runs the CLI once; returns (parsed JSON, whole-process wall time [s])."""
    start = time.perf_counter()
    done = subprocess.run(args, capture_output=True, text=True)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        sys.exit(f"compare_scipy: '{' '.join(args)}' failed ({done.returncode}): {done.stderr.strip()}")
    return json.loads(done.stdout), elapsed


def time_cli(binary, method, repeats, csv_path):
    """Simulation time (the CLI's wall_time_s) and process time over `repeats` runs, then one run
    with --out for the series (not timed: writing the CSV dominates it)."""
    sim_s, process_s = [], []
    summary = None
    for _ in range(repeats):
        summary, elapsed = run_cli(simulate_args(binary, method))
        sim_s.append(summary["wall_time_s"])
        process_s.append(elapsed)
    run_cli(simulate_args(binary, method) + ["--out", str(csv_path)])
    series = np.loadtxt(csv_path, delimiter=",", skiprows=1)
    return {"sim_s": sim_s, "process_s": process_s, "summary": summary,
            "x": series[:, 2], "force": series[:, 4]}


def first_harmonic(force, sample_rate_hz, frequency_hz, span_s=1.0):
    """|C_1| over the last whole drive periods within span_s, by least squares on [1, cos, sin] in
    absolute time: the same definition as strokelab's HarmonicAmplitudes / RecordSummary."""
    periods = max(1, math.floor(span_s * frequency_hz + 1e-9))
    count = int(round(periods * sample_rate_hz / frequency_hz))
    n = np.arange(force.size - count, force.size)
    wt = 2 * np.pi * frequency_hz * n / sample_rate_hz
    basis = np.column_stack([np.ones_like(wt), np.cos(wt), np.sin(wt)])
    coef, *_ = np.linalg.lstsq(basis, force[-count:], rcond=None)
    return math.hypot(coef[1], coef[2])


class PiecewiseModel:
    """The two linear regions of the paper model, parameters from the CLI's JSON (one source)."""

    def __init__(self, model_json):
        self.m = model_json["mass_kg"]
        self.c = model_json["damping_n_s_per_m"]
        self.k = model_json["stiffness_n_per_m"]
        self.ks = model_json["contact_stiffness"]
        self.g = model_json["gain_n_per_v"]
        self.d = model_json["lower_stop_m"]
        self.w = 2 * np.pi * FREQUENCY_HZ

    def force(self, t, x, v, contact):
        """Blocked force m x'' [N]; works on scalars and arrays."""
        return (self.g * AMPLITUDE_V * np.sin(self.w * t) - self.k * x - self.c * v
                + np.where(contact, self.ks * (self.d - x), 0.0))

    def rhs(self, contact):
        stiffness = self.k + self.ks if contact else self.k
        offset = self.ks * self.d if contact else 0.0
        gv, w, c, m = self.g * AMPLITUDE_V, self.w, self.c, self.m

        def f(t, y):
            return [y[1], (gv * math.sin(w * t) - stiffness * y[0] + offset - c * y[1]) / m]
        return f

    def jacobian(self, contact):
        stiffness = self.k + self.ks if contact else self.k
        jac = np.array([[0.0, 1.0], [-stiffness / self.m, -self.c / self.m]])
        return lambda t, y: jac


def solve_scipy(model, method, rtol, atol, use_dense):
    """Region-by-region solve_ivp over the sample grid. Output by t_eval (scipy interpolates inside
    each step) or by dense_output evaluated afterwards. Returns (force, x, regions)."""
    n_samples = int(round(DURATION_S * SAMPLE_RATE_HZ))
    t = np.arange(n_samples) / SAMPLE_RATE_HZ
    x = np.empty(n_samples)
    v = np.empty(n_samples)
    contact_at = np.zeros(n_samples, dtype=bool)
    t0, y0, contact, i, regions = 0.0, [0.0, 0.0], False, 0, 0
    while i < n_samples:
        def hit_stop(_, y):
            return y[0] - model.d
        hit_stop.terminal = True
        hit_stop.direction = 1.0 if contact else -1.0  # leaving the stop / reaching it
        common = dict(method=method, rtol=rtol, atol=atol, events=hit_stop)
        if method in ("LSODA", "Radau", "BDF"):
            common["jac"] = model.jacobian(contact)
        if use_dense:
            sol = solve_ivp(model.rhs(contact), (t0, t[-1]), y0, dense_output=True, **common)
            # Samples strictly before the event belong to this region.
            j = int(np.searchsorted(t, sol.t_events[0][0])) if sol.status == 1 else n_samples
            if j > i:
                x[i:j], v[i:j] = sol.sol(t[i:j])
        else:
            sol = solve_ivp(model.rhs(contact), (t0, t[-1]), y0, t_eval=t[i:], **common)
            j = i + sol.t.size
            x[i:j], v[i:j] = sol.y
        if sol.status < 0:
            sys.exit(f"compare_scipy: solve_ivp {method} failed: {sol.message}")
        contact_at[i:j] = contact
        i, regions = j, regions + 1
        if sol.status != 1:
            break
        t0 = sol.t_events[0][0]
        y0 = [model.d, sol.y_events[0][0][1]]  # on the surface exactly, so the new region starts clean
        contact = not contact
    return model.force(t, x, v, contact_at), x, regions


def time_scipy(model, method, rtol, atol, use_dense, repeats):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        force, x, regions = solve_scipy(model, method, rtol, atol, use_dense)
        times.append(time.perf_counter() - start)
    return {"sim_s": times, "force": force, "x": x, "regions": regions}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--strokelab", type=pathlib.Path, default=REPO_ROOT / "build/release/strokelab",
                        help="the strokelab binary (default: build/release/strokelab under the repo root)")
    parser.add_argument("--repeats", type=int, default=5, help="CLI runs per engine (default 5)")
    parser.add_argument("--scipy-repeats", type=int, default=2, help="runs per LSODA output mode (default 2)")
    parser.add_argument("--rtol", type=float, default=1e-8, help="LSODA/Radau rtol (default 1e-8)")
    parser.add_argument("--atol", type=float, default=1e-12, help="LSODA/Radau atol on x [m] and v [m/s] (default 1e-12)")
    parser.add_argument("--tight-rtol", type=float, default=1e-12, help="rtol of the tight LSODA row (default 1e-12; atol = rtol*1e-4)")
    parser.add_argument("--no-radau", action="store_true", help="skip the Radau row (~6 s)")
    args = parser.parse_args()
    if args.repeats < 1 or args.scipy_repeats < 1:
        sys.exit("compare_scipy: --repeats and --scipy-repeats must be >= 1")
    binary = args.strokelab if args.strokelab.is_absolute() else pathlib.Path.cwd() / args.strokelab
    if not binary.is_file():
        sys.exit(f"compare_scipy: strokelab binary not found at {binary}\n"
                 f"  build it (cmake -S . -B build/release -DCMAKE_BUILD_TYPE=Release && "
                 f"cmake --build build/release) or pass --strokelab PATH")

    with tempfile.TemporaryDirectory() as tmp:
        cli = {m: time_cli(binary, m, args.repeats, pathlib.Path(tmp) / f"{m}.csv")
               for m in ("exact", "cvode", "ode3")}
    reference = cli["exact"]
    f1_reference = first_harmonic(reference["force"], SAMPLE_RATE_HZ, FREQUENCY_HZ)
    # The fit here must agree with the CLI's own |F1|, or the |F1| column means nothing.
    f1_cli = reference["summary"]["first_harmonic_force_n"]
    if abs(f1_reference - f1_cli) > 1e-9 * f1_cli:
        sys.exit(f"compare_scipy: |F1| fit {f1_reference!r} disagrees with the CLI's {f1_cli!r}")

    model = PiecewiseModel(reference["summary"]["model"])
    by_teval = time_scipy(model, "LSODA", args.rtol, args.atol, False, args.scipy_repeats)
    by_dense = time_scipy(model, "LSODA", args.rtol, args.atol, True, args.scipy_repeats)
    use_dense = min(by_dense["sim_s"]) < min(by_teval["sim_s"])
    lsoda = by_dense if use_dense else by_teval
    output_mode = "dense_output" if use_dense else "t_eval"
    tight_atol = args.tight_rtol * 1e-4
    rows = [
        ("strokelab exact", cli["exact"]),
        ("strokelab cvode", cli["cvode"]),
        ("strokelab ode3", cli["ode3"]),
        (f"scipy LSODA rtol {args.rtol:g} atol {args.atol:g}", lsoda),
        (f"scipy LSODA rtol {args.tight_rtol:g} atol {tight_atol:g}",
         time_scipy(model, "LSODA", args.tight_rtol, tight_atol, use_dense, 1)),
    ]
    if not args.no_radau:
        rows.append((f"scipy Radau rtol {args.rtol:g} atol {args.atol:g}",
                     time_scipy(model, "Radau", args.rtol, args.atol, use_dense, 1)))

    lsoda_s = statistics.median(lsoda["sim_s"])
    print(f"10 s record, paper model, {FREQUENCY_HZ:g} Hz / {AMPLITUDE_V:g} V, {SAMPLE_RATE_HZ:g} Hz "
          f"({reference['force'].size} samples), |F1| = {f1_reference:.9g} N (exact engine)")
    print("errors against the exact engine's series; strokelab wall = its wall_time_s (simulation only, "
          f"{args.repeats} runs),\nprocess = median whole `strokelab simulate --json` run; LSODA/x = median "
          f"wall of the first LSODA row / this row's")
    print(f"scipy output via {output_mode}: LSODA t_eval {min(by_teval['sim_s']):.3f} s, "
          f"dense_output {min(by_dense['sim_s']):.3f} s (min of {args.scipy_repeats}); "
          f"{lsoda['regions']} regions (free/contact) integrated")
    print(f"load average: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print()
    header = (f"{'method':<38} {'wall med [s]':>12} {'wall min [s]':>12} {'process [s]':>11} {'LSODA/x':>8} "
              f"{'max|dF| [N]':>11} {'|F1| rel err':>12}")
    print(header)
    print("-" * len(header))
    for name, result in rows:
        wall = statistics.median(result["sim_s"])
        process = f"{statistics.median(result['process_s']):.4f}" if "process_s" in result else "-"
        if result is reference:
            error, f1_error = "reference", "reference"
        else:
            error = f"{np.max(np.abs(result['force'] - reference['force'])):.3g}"
            f1 = first_harmonic(result["force"], SAMPLE_RATE_HZ, FREQUENCY_HZ)
            f1_error = f"{abs(f1 - f1_reference) / f1_reference:.3g}"
        print(f"{name:<38} {wall:>12.4g} {min(result['sim_s']):>12.4g} {process:>11} "
              f"{lsoda_s / wall:>8.1f} {error:>11} {f1_error:>12}")
    print()
    print("The exact engine has no tighter reference here: its difference from cvode (rtol 1e-10) and")
    print("from the tight scipy rows bounds its own error.")


if __name__ == "__main__":
    main()
