"""What the sections of compare_scipy.py share: running the strokelab CLI, reading a sweep's points by
grid point, and steady states by brute force with scipy's solve_ivp.

The brute force integrates a model region by region: a terminal event at x = d (the lower stop) ends
each region and the integration restarts in the other one, so no step straddles the switch. A model
here is any object with m [kg], w [rad/s], d [m], frequency_hz, amplitude_v, rhs(contact) and
jacobian(contact) (compare_scipy.PiecewiseModel, scipy_smooth.SmoothModel). It is run period after
period from a state at drive phase 0 until the Poincare section repeats, with the residual scaled as
the sweep scales its own: x / |d|, x' / (w |d|).

Uses numpy, scipy and the standard library only.
"""
import json
import math
import subprocess
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp

GAUSS_NODES, GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(8)  # exact for LSODA's <= 12th-order steps
IMPLICIT_METHODS = ("LSODA", "Radau", "BDF")  # the solve_ivp methods that take a Jacobian


def run_cli(args):
    """Runs the CLI once; returns (parsed JSON, whole-process wall time [s])."""
    start = time.perf_counter()
    done = subprocess.run(args, capture_output=True, text=True)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        sys.exit(f"compare_scipy: '{' '.join(args)}' failed ({done.returncode}): {done.stderr.strip()}")
    return json.loads(done.stdout), elapsed


def advance_periods(model, t0, y0, contact, periods, rtol, atol, measure, method="LSODA"):
    """Integrates `periods` drive periods from (t0, y0) region by region with solve_ivp `method`. With
    `measure`: also C1(x) over them (Gauss-Legendre on every solver step of the dense output), the
    extrema of x (at the x' = 0 events and the ends) and the stop entries. Returns (y, contact, figures)."""
    w = model.w
    t_end = t0 + periods / model.frequency_hz
    integral, x_min, x_max, contacts = 0j, y0[0], y0[0], 0
    t, y = t0, list(y0)

    def extremum(_, yy):
        return yy[1]

    while True:
        def hit_stop(_, yy):
            return yy[0] - model.d
        hit_stop.terminal = True
        hit_stop.direction = 1.0 if contact else -1.0
        jac = {"jac": model.jacobian(contact)} if method in IMPLICIT_METHODS else {}
        sol = solve_ivp(model.rhs(contact), (t, t_end), y, method=method, rtol=rtol, atol=atol,
                        events=[hit_stop, extremum] if measure else hit_stop, dense_output=measure, **jac)
        if sol.status < 0:
            sys.exit(f"compare_scipy: solve_ivp {method} failed at {model.frequency_hz:g} Hz / "
                     f"{model.amplitude_v:g} V: {sol.message}")
        t_stop = sol.t_events[0][0] if sol.status == 1 else t_end
        if measure:
            if sol.y_events[1].size:
                x_min = min(x_min, sol.y_events[1][:, 0].min())
                x_max = max(x_max, sol.y_events[1][:, 0].max())
            edges = sol.t[sol.t <= t_stop]
            if edges[-1] < t_stop:
                edges = np.append(edges, t_stop)
            half, mid = 0.5 * np.diff(edges), 0.5 * (edges[1:] + edges[:-1])
            nodes = (mid[:, None] + half[:, None] * GAUSS_NODES).ravel()
            weights = (half[:, None] * GAUSS_WEIGHTS).ravel()
            integral += np.sum(weights * sol.sol(nodes)[0] * np.exp(-1j * w * nodes))
        if sol.status != 1:
            y = [sol.y[0, -1], sol.y[1, -1]]
            break
        t, y, contact = t_stop, [model.d, sol.y_events[0][0][1]], not contact
        contacts += contact
    if not measure:
        return y, contact, None
    x_min, x_max = min(x_min, y[0]), max(x_max, y[0])
    x1 = 2.0 * integral * model.frequency_hz / periods
    return y, contact, {"f1": model.m * w * w * abs(x1), "x_min": x_min, "x_max": x_max,
                        "contacts_per_period": contacts / periods}


def section_residual(model, y, back):
    """|y - back| on the Poincare section, scaled as the sweep scales it: x / |d|, x' / (w |d|)."""
    length = abs(model.d)
    return math.hypot((y[0] - back[0]) / length, (y[1] - back[1]) / (length * model.w))


def settle(model, y0, contact, args):
    """Brute-force steady state: whole drive periods from y0 at t = 0 (drive phase 0) until the
    Poincare section repeats after p = 1 or 2 periods (scaled as the sweep scales its residual), then
    the figures over p more periods. Period 2 is accepted only where period 1 is clearly not converging
    (its residual > 1000 tol), so a slow alternating approach to a period-1 orbit is not taken for it."""
    history, y, p, periods = [list(y0)], list(y0), 0, 0
    residual = [math.inf, math.inf]
    while periods < args.sweep_max_periods:
        y, contact, _ = advance_periods(model, 0.0, y, contact, 1, args.sweep_rtol, args.sweep_atol, False)
        periods += 1
        history.append(y)
        for lag in (1, 2):
            if len(history) > lag:
                residual[lag - 1] = section_residual(model, y, history[-1 - lag])
        if residual[0] < args.sweep_tol:
            p = 1
        elif residual[1] < args.sweep_tol and residual[0] > 1e3 * args.sweep_tol:
            p = 2
        if p:
            break
        del history[:-3]
    measure_periods = p or (2 if residual[1] < residual[0] else 1)
    y_end, contact_end, figures = advance_periods(model, 0.0, y, contact, measure_periods,
                                                  args.sweep_rtol, args.sweep_atol, True)
    figures.update(periods=periods + measure_periods, period=p, converged=p > 0,
                   residual=min(residual))
    return figures, y_end, contact_end


def index_sweep(result):
    """{(frequency index, amplitude index): {branch: [points]}} on the result's grid."""
    freqs, amps = result["grid"]["frequency_hz"], result["grid"]["amplitude_v"]
    table = {}
    for point in result["points"]:
        i = min(range(len(freqs)), key=lambda n: abs(freqs[n] - point["frequency_hz"]))
        j = min(range(len(amps)), key=lambda n: abs(amps[n] - point["amplitude_v"]))
        if abs(freqs[i] - point["frequency_hz"]) > 1e-9 * freqs[i] or abs(amps[j] - point["amplitude_v"]) > 1e-12:
            sys.exit(f"compare_scipy: sweep point {point['frequency_hz']} Hz / {point['amplitude_v']} V is off the grid")
        table.setdefault((i, j), {}).setdefault(point["branch"], []).append(point)
    return table


def timed_sweep(cli_args, repeats):
    """Runs `strokelab sweep ... --json` `repeats` times. Returns (the last result, wall_time_s of each
    run, whole-process seconds of each run, index_sweep of the result); every grid point must be in it."""
    sim_s, process_s = [], []
    for _ in range(repeats):
        result, elapsed = run_cli(cli_args)
        sim_s.append(result["wall_time_s"])
        process_s.append(elapsed)
    table = index_sweep(result)
    grid_points = len(result["grid"]["frequency_hz"]) * len(result["grid"]["amplitude_v"])
    if len(table) != grid_points:
        sys.exit(f"compare_scipy: the sweep reported {len(table)} of {grid_points} grid points")
    return result, sim_s, process_s, table


def relative(a, b):
    return abs(a - b) / abs(b) if b else abs(a - b)
