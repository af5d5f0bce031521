"""The smooth section of compare_scipy.py: steady states of a model that is not piecewise linear.

Model: the paper's (Table 2) with the overrides of --smooth-set (default k3=4e7 N/m^3, cubic
stiffening), passed to `strokelab sweep --set`; the scipy side reads the model from the sweep's JSON.
It integrates

    m x'' = g V sin(w t) - k_p x - k2 x^2 - k3 x^3 - c_p x' + (x < d ? k_s (d - x)^n : 0),

n = 1 (linear stop) or 3/2 (Hertzian), and refuses any other term (upper stop, contact damping,
friction, clipping).

`strokelab sweep --json --no-thresholds --threads 1` on a linear grid (default 20 frequencies
5 .. 20 Hz x 6 amplitudes 0.1 .. 0.6 V), timed by its wall_time_s: grid points per second on one
core. Then scipy's brute force on a random subset of the grid points (fixed seed, listed): LSODA from
rest, region by region, period after period until the Poincare section repeats (the sweep section's
settings: --sweep-rtol, --sweep-atol, --sweep-tol, --sweep-max-periods), |F1| = m w^2 |C1(x)| over
the last p periods as the sweep section computes it; time per point.

Each timed result is checked against a reference computed once per point, untimed: DOP853 at
--reference-rtol (1e-12) and --reference-atol (1e-16 on x [m] and x' [m/s]) from scipy's converged
state, p periods at a time until its own section residual is below --reference-tol (1e-11; scipy's
converged state is up to a few 1e-9 off DOP853's orbit), then |F1| over p more periods. The table
gives the reference's section residual |P^p(y) - y| over the measured periods (scaled as above: how
close to the orbit it started) and the periods it settled, scipy's and strokelab's relative |F1|
deviation from it (strokelab: its stable branch nearest the reference, named; at a bistable point
scipy's run from rest lands on one branch), and the summary the largest deviation of each and the
ratio scipy seconds per point / strokelab seconds per point.
"""
import math
import os
import random
import statistics
import sys
import time

import numpy as np

from scipy_steady import advance_periods, relative, section_residual, settle, timed_sweep

SMOOTH_FREQUENCY_HZ = (5.0, 20.0)
SMOOTH_AMPLITUDE_V = (0.1, 0.6)


class SmoothModel:
    """The paper model with polynomial stiffness and a linear or Hertzian lower stop, parameters from
    the CLI's JSON (one source). The same interface as compare_scipy.PiecewiseModel."""

    def __init__(self, model_json, frequency_hz, amplitude_v):
        self.m = model_json["mass_kg"]
        self.c = model_json["damping_n_s_per_m"]
        self.k = model_json["stiffness_n_per_m"]
        self.k2 = model_json["quadratic_stiffness_n_per_m2"]
        self.k3 = model_json["cubic_stiffness_n_per_m3"]
        self.ks = model_json["contact_stiffness"]
        self.exponent = 1.5 if model_json["contact_law"] == "hertzian" else 1.0
        self.g = model_json["gain_n_per_v"]
        self.d = model_json["lower_stop_m"]
        self.frequency_hz = frequency_hz
        self.amplitude_v = amplitude_v
        self.w = 2 * np.pi * frequency_hz

    def rhs(self, contact):
        gv, w, c, m, k, k2, k3 = self.g * self.amplitude_v, self.w, self.c, self.m, self.k, self.k2, self.k3
        ks, d, n = (self.ks if contact else 0.0), self.d, self.exponent

        def f(t, y):
            x = y[0]
            stop = ks * max(d - x, 0.0) ** n
            return [y[1], (gv * math.sin(w * t) - ((k3 * x + k2) * x + k) * x - c * y[1] + stop) / m]
        return f

    def jacobian(self, contact):
        m, k, k2, k3, c = self.m, self.k, self.k2, self.k3, self.c
        ks, d, n = (self.ks if contact else 0.0), self.d, self.exponent

        def jac(_, y):
            x = y[0]
            stop_slope = ks * n * max(d - x, 0.0) ** (n - 1) if ks else 0.0  # d(stop force)/d(-x)
            return np.array([[0.0, 1.0], [-(k + 2 * k2 * x + 3 * k3 * x * x + stop_slope) / m, -c / m]])
        return jac


def check_smooth_model(model_json):
    """The scipy side integrates polynomial stiffness and one stop without damping: refuse the rest."""
    absent = {"contact_damping_n_s_per_m": 0.0, "upper_stop_m": None, "friction_force_n": 0.0,
              "amplifier_limit_v": None}
    for key, value in absent.items():
        if model_json.get(key, value) != value:
            sys.exit(f"compare_scipy: the smooth section's model has {key} = {model_json[key]!r}; its scipy "
                     f"side integrates k2, k3 and a linear or Hertzian lower stop only")
    if model_json.get("lower_stop_m") is None:
        sys.exit("compare_scipy: the smooth section's model has no lower stop")


def smooth_sweep_args(binary, args):
    overrides = [arg for assignment in args.smooth_set for arg in ("--set", assignment)]
    return [str(binary), "sweep", "--model", "paper", *overrides,
            "--frequency-hz", f"{SMOOTH_FREQUENCY_HZ[0]:g}:{SMOOTH_FREQUENCY_HZ[1]:g}",
            "--frequency-points", str(args.smooth_frequency_points),
            "--amplitude-v", f"{SMOOTH_AMPLITUDE_V[0]:g}:{SMOOTH_AMPLITUDE_V[1]:g}",
            "--amplitude-points", str(args.smooth_amplitude_points), "--no-thresholds", "--threads", "1", "--json"]


def brute_force(model_json, f_hz, amplitude_v, args):
    """scipy's timed steady state from rest, then the untimed reference from its converged state:
    DOP853 over p periods at a time until its own section residual is below --reference-tol (or
    --reference-max-periods), then |F1| over p more."""
    start = time.perf_counter()
    model = SmoothModel(model_json, f_hz, amplitude_v)
    figures, y, contact = settle(model, [0.0, 0.0], False, args)
    figures["time_s"] = time.perf_counter() - start
    p = figures["period"] or 1
    tolerances = (args.reference_rtol, args.reference_atol)
    settled = 0
    while settled < args.reference_max_periods:
        y_next, contact, _ = advance_periods(model, 0.0, y, contact, p, *tolerances, False, method="DOP853")
        settled += p
        y, residual = y_next, section_residual(model, y_next, y)
        if residual < args.reference_tol:
            break
    y_end, _, reference = advance_periods(model, 0.0, y, contact, p, *tolerances, True, method="DOP853")
    reference.update(residual=section_residual(model, y_end, y), settle_periods=settled)
    return figures, reference


def nearest_stable(branches, f1):
    """strokelab's stable branch ('up' or 'down') whose |F1| is nearest f1: (name, point)."""
    stable = [(name, points[0]) for name, points in branches.items() if name != "unstable" and points[0]["stable"]]
    if not stable:
        return "-", None
    return min(stable, key=lambda item: relative(item[1]["first_harmonic_force_n"], f1))


def smooth_section(args, binary):
    result, sim_s, _, table = timed_sweep(smooth_sweep_args(binary, args), args.smooth_repeats)
    model_json = result["model"]
    check_smooth_model(model_json)
    freqs, amps = result["grid"]["frequency_hz"], result["grid"]["amplitude_v"]
    grid_points = len(freqs) * len(amps)
    rng = random.Random(args.seed)
    sample = sorted(rng.sample(sorted(table), min(args.smooth_samples, grid_points)))

    sl_wall = statistics.median(sim_s)
    sl_per_point = sl_wall / grid_points
    print(f"steady states, smooth model (paper + {', '.join(args.smooth_set)}): `strokelab sweep --json "
          f"--no-thresholds --threads 1` on {len(freqs)} x {len(amps)} = {grid_points} grid points "
          f"({freqs[0]:g} .. {freqs[-1]:g} Hz linear x {amps[0]:g} .. {amps[-1]:g} V; "
          f"{len(result['points'])} steady states)")
    print(f"  wall_time_s median {sl_wall:.4g} s, min {min(sim_s):.4g} s over {args.smooth_repeats} runs: "
          f"{grid_points / sl_wall:.4g} grid points/s per core, {1e3 * sl_per_point:.4g} ms per point")
    print(f"scipy LSODA rtol {args.sweep_rtol:g} atol {args.sweep_atol:g} from rest, region by region, period "
          f"after period until |P^p(y) - y| < {args.sweep_tol:g} (p = 1, 2) or {args.sweep_max_periods} periods")
    print(f"  {len(sample)} random grid points (seed {args.seed}): "
          f"{', '.join(f'{freqs[i]:.4g} Hz / {amps[j]:.3g} V' for i, j in sample)}")
    print(f"reference per point, untimed: DOP853 rtol {args.reference_rtol:g} atol {args.reference_atol:g} "
          f"from scipy's converged state, settled to |P^p(y) - y| < {args.reference_tol:g} "
          f"(at most {args.reference_max_periods} periods), then p periods measured")
    print(f"load average: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print()
    header = (f"{'f [Hz]':>7} {'V [V]':>5} {'periods':>7} {'p':>3} {'time [s]':>8} {'|F1| ref [N]':>15} "
              f"{'ref resid':>9} {'settled':>7} {'scipy dev':>9} {'sl branch':>9} {'sl dev':>9} {'contacts/T':>10}")
    print(header)
    print("-" * len(header))
    scipy_dev, sl_dev, times = [], [], []
    for key in sample:
        fig, ref = brute_force(model_json, freqs[key[0]], amps[key[1]], args)
        branch, point = nearest_stable(table[key], ref["f1"])
        times.append(fig["time_s"])
        scipy_dev.append(relative(fig["f1"], ref["f1"]))
        sl = relative(point["first_harmonic_force_n"], ref["f1"]) if point else math.inf
        sl_dev.append(sl)
        p = str(fig["period"]) if fig["converged"] else "-"
        contacts = f"{fig['contacts_per_period']:g}/{point['contacts_per_period']:g}" if point else "-"
        print(f"{freqs[key[0]]:>7.4g} {amps[key[1]]:>5.3g} {fig['periods']:>7} {p:>3} {fig['time_s']:>8.3f} "
              f"{ref['f1']:>15.10g} {ref['residual']:>9.2g} {ref['settle_periods']:>7} {scipy_dev[-1]:>9.2g} "
              f"{branch:>9} {sl:>9.2g} "
              f"{contacts:>10}")
        if not fig["converged"]:
            print(f"{'':>7} not converged after {fig['periods']} periods: residual {fig['residual']:.3g}")
    print()
    if not sample:
        return
    mean_s = statistics.fmean(times)
    print(f"strokelab: {grid_points / sl_wall:.4g} grid points/s per core ({1e3 * sl_per_point:.3g} ms per point, "
          f"the sweep's wall_time_s / grid points)")
    print(f"scipy (random points from rest): {mean_s:.3g} s per point mean, {statistics.median(times):.3g} s median, "
          f"{min(times):.3g} .. {max(times):.3g} s")
    print(f"ratio scipy / strokelab seconds per point: {mean_s / sl_per_point:.4g} (mean), "
          f"{statistics.median(times) / sl_per_point:.4g} (median)")
    print(f"max |F1| rel deviation from the reference: scipy {max(scipy_dev):.3g}, strokelab {max(sl_dev):.3g}")
    print("contacts/T: contacts per drive period, scipy / strokelab. ref resid: the reference's own scaled")
    print("|P^p(y) - y| over the measured periods, which bounds how far its start was from the orbit;")
    print("settled: the DOP853 periods run before them.")


def add_arguments(parser):
    smooth = parser.add_argument_group(
        "smooth section (scipy runs with --sweep-rtol, --sweep-atol, --sweep-tol, --sweep-max-periods)")
    smooth.add_argument("--smooth-set", action="append", metavar="KEY=VALUE",
                        help="model override passed to `strokelab sweep --set` (repeatable; default k3=4e7), "
                             "e.g. --smooth-set k3=2.5e7 --smooth-set contact_law=hertzian --smooth-set k_s=2.65e8")
    smooth.add_argument("--smooth-frequency-points", type=int, default=20,
                        help="grid frequencies, linear 5 .. 20 Hz (default 20)")
    smooth.add_argument("--smooth-amplitude-points", type=int, default=6,
                        help="grid amplitudes, linear 0.1 .. 0.6 V (default 6)")
    smooth.add_argument("--smooth-repeats", type=int, default=2, help="strokelab sweep runs (default 2)")
    smooth.add_argument("--smooth-samples", type=int, default=12,
                        help="random grid points integrated by scipy (default 12; seed: --seed)")
    smooth.add_argument("--reference-rtol", type=float, default=1e-12, help="DOP853 rtol (default 1e-12)")
    smooth.add_argument("--reference-atol", type=float, default=1e-16,
                        help="DOP853 atol on x [m] and x' [m/s] (default 1e-16)")
    smooth.add_argument("--reference-tol", type=float, default=1e-11,
                        help="the reference settles until its scaled |P^p(y) - y| is below this (default 1e-11)")
    smooth.add_argument("--reference-max-periods", type=int, default=60,
                        help="at most this many DOP853 periods of settling (default 60)")


def check_arguments(args):
    if args.smooth_set is None:
        args.smooth_set = ["k3=4e7"]
    if args.smooth_repeats < 1 or args.smooth_frequency_points < 2 or args.smooth_amplitude_points < 1 \
            or args.smooth_samples < 0 or args.reference_max_periods < 0:
        sys.exit("compare_scipy: --smooth-repeats must be >= 1, --smooth-frequency-points >= 2, "
                 "--smooth-amplitude-points >= 1, --smooth-samples >= 0, --reference-max-periods >= 0")
