#!/usr/bin/python3
"""Times strokelab against scipy's solve_ivp on the paper's record and on steady states; checks accuracy.

Three sections, all run by default (--no-record / --no-sweep / --no-smooth skip one; --sweep or
--smooth runs that section alone).

Record section.

The record: paper model (Table 2), 8 Hz / 0.5 V (saturating, one contact per period), 10 s at
51.2 kHz from rest, 512,000 samples. Every method is compared with the exact engine's series
(read from `strokelab simulate --out`).

scipy integrates Eq. 2 of "Nonlinear vibrations of a stroke-saturated inertial actuator"
in its continuous form (its slip at contact corrected: the suspension keeps acting in contact),

    m x'' = g V sin(w t) - k_p x - c_p x' + (x < d ? k_s (d - x) : 0),

one linear region at a time: a terminal event at x = d ends the region and the integration restarts
in the other one, so no step straddles the kink. The blocked force is f = m x'' from that right-hand
side at each sample.

Sweep section. `strokelab sweep --json --no-thresholds --threads 1` on a linear grid (default 46
frequencies 5 .. 50 Hz, i.e. 1 Hz steps, x 6 amplitudes 0.1 .. 0.6 V; that grid has bistable points
at 14 Hz / 0.5 V and 15 Hz / 0.6 V when written), timed by its wall_time_s. Then the same steady
states by brute force for a random subset of the grid points (fixed seed), plus every bistable grid
point: scipy LSODA, region by region as above, integrated period after period from rest (x = x' = 0
at t = 0) until the Poincare section at drive phase 0 repeats, |P^p(y) - y| < tol with the scaling
the sweep uses (x / |d|, x' / (w |d|)) and p = 1 or 2, or a fixed number of periods. Over the last p
periods: C1(x) = (2 / pT) int x e^{-jwt} dt by Gauss-Legendre on each LSODA step of the dense
output, so |F1| = m w^2 |C1(x)| as the sweep computes it (steady_state.h: the exact continuous first
harmonic of f = m x'', not a fit to sampled force); min x at the x' = 0 events. At a bistable point
scipy's from-rest run lands on one branch: the table compares with the up branch and says which
branch it reached; a short stepped sine from the nearest monostable grid frequency below (above) is
run too and compared with the up (down) branch. (The brute force is scipy_steady.py's, shared with
the smooth section.)

Smooth section (scipy_smooth.py says it in full). The same comparison on a model that is not
piecewise linear: the paper's with k3 = 4e7 N/m^3 by default (--smooth-set KEY=VALUE, repeatable,
goes to `strokelab sweep --set`), default 20 frequencies 5 .. 20 Hz x 6 amplitudes 0.1 .. 0.6 V,
grid points per second per core against scipy's seconds per point on a random subset, every timed
|F1| (strokelab's and scipy's) checked against a DOP853 reference at rtol 1e-12 from scipy's
converged state.

Usage: /usr/bin/python3 tests/bench/compare_scipy.py [--strokelab build/release/strokelab] [--repeats 5]
                        [--no-record | --no-sweep | --no-smooth | --sweep | --smooth]
                        [--sweep-samples 12] [--smooth-samples 12] [--smooth-set k3=4e7] [--seed 1]
Uses numpy, scipy and the standard library only. The record and sweep sections take ~17 s on a
2-core machine (the sweep section ~3.5 s); the smooth section took ~50 s (its two sweeps ~45 s) with
the CVODE period map of the code before issue 12.
"""
import argparse
import math
import os
import pathlib
import random
import statistics
import sys
import tempfile
import time

import numpy as np
from scipy.integrate import solve_ivp

import scipy_smooth
from scipy_steady import relative, run_cli, settle, timed_sweep

REPO_ROOT = pathlib.Path(__file__).resolve().parents[2]
FREQUENCY_HZ = 8.0
AMPLITUDE_V = 0.5
DURATION_S = 10.0
SAMPLE_RATE_HZ = 51200.0


def simulate_args(binary, method):
    return [str(binary), "simulate", "--model", "paper", "--frequency-hz", str(FREQUENCY_HZ),
            "--amplitude-v", str(AMPLITUDE_V), "--duration-s", str(DURATION_S),
            "--sample-rate-hz", str(SAMPLE_RATE_HZ), "--method", method, "--json"]


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

    def __init__(self, model_json, frequency_hz=FREQUENCY_HZ, amplitude_v=AMPLITUDE_V):
        self.m = model_json["mass_kg"]
        self.c = model_json["damping_n_s_per_m"]
        self.k = model_json["stiffness_n_per_m"]
        self.ks = model_json["contact_stiffness"]
        self.g = model_json["gain_n_per_v"]
        self.d = model_json["lower_stop_m"]
        self.frequency_hz = frequency_hz
        self.amplitude_v = amplitude_v
        self.w = 2 * np.pi * frequency_hz

    def force(self, t, x, v, contact):
        """Blocked force m x'' [N]; works on scalars and arrays."""
        return (self.g * self.amplitude_v * np.sin(self.w * t) - self.k * x - self.c * v
                + np.where(contact, self.ks * (self.d - x), 0.0))

    def rhs(self, contact):
        stiffness = self.k + self.ks if contact else self.k
        offset = self.ks * self.d if contact else 0.0
        gv, w, c, m = self.g * self.amplitude_v, self.w, self.c, self.m

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


def record_section(args, binary):
    """The 10 s record: strokelab's three engines against LSODA (and Radau)."""
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


# ---- sweep section --------------------------------------------------------------------------------

SWEEP_FREQUENCY_HZ = (5.0, 50.0)
SWEEP_AMPLITUDE_V = (0.1, 0.6)


def sweep_args(binary, frequency_points, amplitude_points):
    return [str(binary), "sweep", "--model", "paper",
            "--frequency-hz", f"{SWEEP_FREQUENCY_HZ[0]:g}:{SWEEP_FREQUENCY_HZ[1]:g}",
            "--frequency-points", str(frequency_points),
            "--amplitude-v", f"{SWEEP_AMPLITUDE_V[0]:g}:{SWEEP_AMPLITUDE_V[1]:g}",
            "--amplitude-points", str(amplitude_points), "--no-thresholds", "--threads", "1", "--json"]


def check_plain_piecewise(model_json):
    """The scipy side integrates only the paper's two linear regions: refuse anything else."""
    plain = {"contact_damping_n_s_per_m": 0.0, "upper_stop_m": None, "cubic_stiffness_n_per_m3": 0.0,
             "quadratic_stiffness_n_per_m2": 0.0, "friction_force_n": 0.0, "amplifier_limit_v": None,
             "contact_law": "linear"}
    for key, value in plain.items():
        if key in model_json and model_json[key] != value:
            sys.exit(f"compare_scipy: the sweep's model has {key} = {model_json[key]!r}; the scipy side "
                     f"only integrates the plain piecewise-linear paper model")
    if model_json.get("lower_stop_m") is None:
        sys.exit("compare_scipy: the sweep's model has no lower stop")


def steady_from_rest(model_json, f_hz, amplitude_v, args):
    start = time.perf_counter()
    model = PiecewiseModel(model_json, f_hz, amplitude_v)
    figures, _, _ = settle(model, [0.0, 0.0], False, args)
    figures["time_s"] = time.perf_counter() - start
    return figures


def stepped(model_json, frequencies_hz, amplitude_v, args):
    """A stepped sine over `frequencies_hz` at one amplitude: the first from rest, each next one from
    the previous steady state (the state at drive phase 0 carries over; the drive restarts at phase 0).
    Returns the figures at the last frequency, with the whole run's time and periods."""
    start = time.perf_counter()
    y, contact, total_periods = [0.0, 0.0], False, 0
    for f_hz in frequencies_hz:
        figures, y, contact = settle(PiecewiseModel(model_json, f_hz, amplitude_v), y, contact, args)
        total_periods += figures["periods"]
    figures["time_s"] = time.perf_counter() - start
    figures["periods"] = total_periods
    return figures


def is_bistable(branches):
    up, down = branches["up"][0], branches["down"][0]
    return abs(up["first_harmonic_force_n"] - down["first_harmonic_force_n"]) > 1e-9 * up["first_harmonic_force_n"]


def landed_on(figures, branches):
    """Which stable branch scipy's run reached, by |F1|: 'only' (one stable response), 'up', 'down' or
    'neither' (off both by more than 1e-5)."""
    if not is_bistable(branches):
        return "only"
    errors = {b: relative(figures["f1"], branches[b][0]["first_harmonic_force_n"]) for b in ("up", "down")}
    best = min(errors, key=errors.get)
    return best if errors[best] < 1e-5 else "neither"


def sweep_section(args, binary):
    cli_args = sweep_args(binary, args.sweep_frequency_points, args.sweep_amplitude_points)
    result, sim_s, process_s, table = timed_sweep(cli_args, args.sweep_repeats)
    model_json = result["model"]
    check_plain_piecewise(model_json)
    freqs, amps = result["grid"]["frequency_hz"], result["grid"]["amplitude_v"]
    grid_points = len(freqs) * len(amps)

    rng = random.Random(args.seed)
    keys = sorted(table)
    sample = sorted(rng.sample(keys, min(args.sweep_samples, len(keys))))
    bistable = [key for key in keys if is_bistable(table[key])]

    rows = []  # (kind, key, start description, figures, compared branch)
    for key in sample:
        rows.append(("random", key, "rest", steady_from_rest(model_json, freqs[key[0]], amps[key[1]], args), "up"))
    for key in bistable:
        i, j = key
        if key not in sample:
            rows.append(("bistable", key, "rest", steady_from_rest(model_json, freqs[i], amps[j], args), "up"))
        below = [n for n in range(i - 1, -1, -1) if not is_bistable(table[(n, j)])]
        above = [n for n in range(i + 1, len(freqs)) if not is_bistable(table[(n, j)])]
        if below:
            rows.append(("bistable", key, f"up from {freqs[below[0]]:g}",
                         stepped(model_json, freqs[below[0]:i + 1], amps[j], args), "up"))
        if above:
            rows.append(("bistable", key, f"down from {freqs[above[0]]:g}",
                         stepped(model_json, freqs[above[0]:i - 1 if i else None:-1], amps[j], args), "down"))

    sl_wall = statistics.median(sim_s)
    sl_per_point = sl_wall / grid_points
    random_times = [r[3]["time_s"] for r in rows if r[0] == "random"]
    print(f"steady states, paper model: `strokelab sweep --json --no-thresholds --threads 1` on "
          f"{len(freqs)} x {len(amps)} = {grid_points} grid points ({freqs[0]:g} .. {freqs[-1]:g} Hz linear x "
          f"{amps[0]:g} .. {amps[-1]:g} V; up, down and unstable branches, {len(result['points'])} steady states, "
          f"{len(bistable)} bistable grid points)")
    print(f"  wall_time_s median {sl_wall:.4g} s, min {min(sim_s):.4g} s over {args.sweep_repeats} runs; "
          f"process median {statistics.median(process_s):.4g} s")
    print(f"  {grid_points / sl_wall:.4g} grid points/s, {1e3 * sl_per_point:.4g} ms per point")
    print(f"scipy LSODA rtol {args.sweep_rtol:g} atol {args.sweep_atol:g}, region by region, period after period "
          f"until |P^p(y) - y| < {args.sweep_tol:g} (p = 1, 2; x / |d|, x' / (w |d|)) or "
          f"{args.sweep_max_periods} periods, then p periods measured")
    print(f"  {len(sample)} random grid points (seed {args.seed}) from rest, plus the bistable grid points "
          f"from rest and by stepped sine from the nearest monostable frequency below (up) and above (down)")
    print(f"load average: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print()
    header = (f"{'f [Hz]':>7} {'V [V]':>5} {'point':>8} {'start':>14} {'periods':>7} {'p sc/sl':>7} "
              f"{'time [s]':>8} {'|F1| scipy [N]':>15} {'branch':>6} {'|F1| rel err':>12} {'min x rel err':>13} "
              f"{'contacts/T':>10} {'landed on':>9}")
    print(header)
    print("-" * len(header))
    agree = []
    for kind, key, start, fig, branch in rows:
        reference = table[key][branch][0]
        period_sl = reference["period"] if reference["period"] != "aperiodic" else 0
        f1_err = relative(fig["f1"], reference["first_harmonic_force_n"])
        x_err = relative(fig["x_min"], reference["min_displacement_m"])
        landed = landed_on(fig, table[key])
        if landed in ("only", branch):
            agree.append((f1_err, x_err))
        p_scipy = str(fig["period"]) if fig["converged"] else "-"
        contacts = f"{fig['contacts_per_period']:g}/{reference['contacts_per_period']:g}"
        print(f"{freqs[key[0]]:>7.4g} {amps[key[1]]:>5.3g} {kind:>8} {start:>14} {fig['periods']:>7} "
              f"{p_scipy + '/' + str(period_sl):>7} {fig['time_s']:>8.3f} {fig['f1']:>15.10g} {branch:>6} "
              f"{f1_err:>12.3g} {x_err:>13.3g} {contacts:>10} {landed:>9}")
        if not fig["converged"]:
            print(f"{'':>7} not converged after {fig['periods']} periods: residual {fig['residual']:.3g}")
    print()
    if random_times:
        mean_s = statistics.fmean(random_times)
        print(f"strokelab: {grid_points / sl_wall:.4g} points/s ({1e3 * sl_per_point:.3g} ms per point, "
              f"the whole sweep's wall_time_s / grid points)")
        print(f"scipy (random points from rest): {mean_s:.3g} s per point mean, "
              f"{statistics.median(random_times):.3g} s median, {min(random_times):.3g} .. {max(random_times):.3g} s")
        print(f"ratio scipy / strokelab time per point: {mean_s / sl_per_point:.4g} (mean), "
              f"{statistics.median(random_times) / sl_per_point:.4g} (median)")
    if agree:
        print(f"agreement where scipy reached the compared branch ({len(agree)} of {len(rows)} runs): "
              f"max |F1| rel err {max(a[0] for a in agree):.3g}, max min-x rel err {max(a[1] for a in agree):.3g}")
    print("|F1| rel err and min x rel err are against the branch in the 'branch' column; 'landed on' says which")
    print("stable branch scipy's run reached ('only': the point has one stable response). p sc/sl: period")
    print("of the orbit in drive periods, scipy / strokelab; contacts/T likewise. Whose error the differences")
    print("are: rerun with e.g. --sweep-rtol 1e-12 --sweep-atol 1e-16 --sweep-tol 1e-11 (slower) and see them shrink.")

def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--strokelab", type=pathlib.Path, default=REPO_ROOT / "build/release/strokelab",
                        help="the strokelab binary (default: build/release/strokelab under the repo root)")
    parser.add_argument("--no-record", action="store_true", help="skip the record section")
    parser.add_argument("--no-sweep", action="store_true", help="skip the sweep section")
    parser.add_argument("--no-smooth", action="store_true", help="skip the smooth section")
    parser.add_argument("--sweep", action="store_true", help="only the sweep section")
    parser.add_argument("--smooth", action="store_true", help="only the smooth section")
    record = parser.add_argument_group("record section")
    record.add_argument("--repeats", type=int, default=5, help="CLI runs per engine (default 5)")
    record.add_argument("--scipy-repeats", type=int, default=2, help="runs per LSODA output mode (default 2)")
    record.add_argument("--rtol", type=float, default=1e-8, help="LSODA/Radau rtol (default 1e-8)")
    record.add_argument("--atol", type=float, default=1e-12, help="LSODA/Radau atol on x [m] and v [m/s] (default 1e-12)")
    record.add_argument("--tight-rtol", type=float, default=1e-12, help="rtol of the tight LSODA row (default 1e-12; atol = rtol*1e-4)")
    record.add_argument("--no-radau", action="store_true", help="skip the Radau row (~6 s)")
    sweep = parser.add_argument_group("sweep section")
    sweep.add_argument("--sweep-frequency-points", type=int, default=46,
                       help="grid frequencies, linear 5 .. 50 Hz (default 46: 1 Hz steps)")
    sweep.add_argument("--sweep-amplitude-points", type=int, default=6,
                       help="grid amplitudes, linear 0.1 .. 0.6 V (default 6: 0.1 V steps)")
    sweep.add_argument("--sweep-repeats", type=int, default=5, help="strokelab sweep runs (default 5)")
    sweep.add_argument("--sweep-samples", type=int, default=12,
                       help="random grid points integrated by scipy (default 12; bistable points are added)")
    sweep.add_argument("--seed", type=int, default=1, help="seed of the random subset (default 1)")
    sweep.add_argument("--sweep-rtol", type=float, default=1e-10, help="LSODA rtol (default 1e-10)")
    sweep.add_argument("--sweep-atol", type=float, default=1e-14, help="LSODA atol (default 1e-14)")
    sweep.add_argument("--sweep-tol", type=float, default=1e-9,
                       help="convergence of the Poincare section, scaled |P^p(y) - y| (default 1e-9)")
    sweep.add_argument("--sweep-max-periods", type=int, default=2000,
                       help="give up converging after this many periods (default 2000)")
    scipy_smooth.add_arguments(parser)
    args = parser.parse_args()
    if args.sweep and args.smooth:
        sys.exit("compare_scipy: --sweep and --smooth each run one section alone; give one")
    if args.sweep or args.smooth:
        args.no_record, args.no_sweep, args.no_smooth = True, not args.sweep, not args.smooth
    if args.no_record and args.no_sweep and args.no_smooth:
        sys.exit("compare_scipy: --no-record, --no-sweep and --no-smooth leave nothing to do")
    scipy_smooth.check_arguments(args)
    if args.repeats < 1 or args.scipy_repeats < 1 or args.sweep_repeats < 1:
        sys.exit("compare_scipy: --repeats, --scipy-repeats and --sweep-repeats must be >= 1")
    if args.sweep_frequency_points < 2 or args.sweep_amplitude_points < 1 or args.sweep_samples < 0:
        sys.exit("compare_scipy: --sweep-frequency-points must be >= 2, --sweep-amplitude-points >= 1, "
                 "--sweep-samples >= 0")
    binary = args.strokelab if args.strokelab.is_absolute() else pathlib.Path.cwd() / args.strokelab
    if not binary.is_file():
        sys.exit(f"compare_scipy: strokelab binary not found at {binary}\n"
                 f"  build it (cmake -S . -B build/release -DCMAKE_BUILD_TYPE=Release && "
                 f"cmake --build build/release) or pass --strokelab PATH")

    sections = [(args.no_record, record_section), (args.no_sweep, sweep_section),
                 (args.no_smooth, scipy_smooth.smooth_section)]
    for n, run in enumerate([run for skip, run in sections if not skip]):
        if n:
            print()
            print("=" * 110)
            print()
        run(args, binary)


if __name__ == "__main__":
    main()
