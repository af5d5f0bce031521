#!/usr/bin/python3
"""The extended fit's z-score study: do its standard errors hold the truth? (issue 12, "Fits").

For each effect and each seed of a list fixed and printed before the run, the driver `fit_study`
(tests/diagnose/fit_study.cc) synthesises the diagnosis tests' concealed-effect campaign
(concealed_effects.h: the paper's model plus the effect at the tests' size, k_p, c_p, g, d and k_s
perturbed by up to 10 %, 0.5 mV noise, offset and hum, 6 frequencies x 4 amplitudes, 1 s records at
51.2 kHz), fits the diagnosis's candidate with that effect on every record (diagnose.h FitCandidate:
the base fit, then the extended fit on exact Jacobians) and prints one JSON line with every fitted
parameter's estimate, standard error, truth and z = (estimate - truth) / standard error.

This script runs the driver over effects x seeds in a pool of --jobs processes, writes every line
to --out (JSONL; an existing file is replaced) as it arrives, and prints per effect the converged fraction and per parameter:
n (converged fits with a finite z), mean z, sd z, max |z|, the chi-square statistic S = sum z^2,
P = P(chi2(n) <= S) and the two-sided p-value 2 min(P, 1 - P) of the hypothesis that z has unit
variance (and mean 0). A parameter PASSes at the 1 % level when 0.005 < P < 0.995; the z-scores of
fits that did not converge are left out of it (their standard errors describe where the fit
stopped) and counted against the converged fraction instead; a converged fit without a finite
standard error for a parameter fails that parameter.

Exit status 0 when every fit converged, every variance test passed (unless --no-variance-test) and,
with --max-abs-z Z, every |z| < Z; 1 otherwise; 2 for bad arguments.

Seeds: --first-seed .. --first-seed + --seeds-per-effect - 1, the same for every effect (default
5001-5128; the diagnosis tests use 1001-1008, tuned on 21-28, and fit_test's calibration 1001-1064).
Each driver runs its records side by side on every core (the library's ParallelFor), so --jobs above
1 shares the cores between campaigns.

  tests/diagnose/fit_zscore_study.py --jobs 2 --out var/fit_zscore_study.jsonl
  tests/diagnose/fit_zscore_study.py --effects cubic_stiffness --seeds-per-effect 8

Debian's /usr/bin/python3 with python3-scipy (deploy/local.sh installs it), from any directory; the
driver defaults to this checkout's Release build, build/release/tests/diagnose/fit_study (build the
target fit_study). A campaign took 3-6 s on one core (13 s for a fit that failed), so the whole
study, 4 x 128 campaigns, should take about 20 minutes with --jobs 2 on 2 cores.
"""

import argparse
import concurrent.futures
import json
import math
import os
import subprocess
import sys
import time

from scipy.stats import chi2

SMOOTH_EFFECTS = ["quadratic_stiffness", "cubic_stiffness", "dry_friction", "hertzian_contact"]
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DEFAULT_DRIVER = os.path.join(ROOT, "build", "release", "tests", "diagnose", "fit_study")
LEVEL = 0.01  # two-sided: pass when LEVEL / 2 < P(chi2(n) <= S) < 1 - LEVEL / 2


def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--effects", default=",".join(SMOOTH_EFFECTS),
                        help="comma-separated effect ids (default: the four smooth ones, %(default)s)")
    parser.add_argument("--seeds-per-effect", type=int, default=128, help="campaigns per effect (default 128)")
    parser.add_argument("--first-seed", type=int, default=5001, help="first seed (default 5001)")
    parser.add_argument("--jobs", type=int, default=1, help="drivers run side by side (default 1)")
    parser.add_argument("--out", default="fit_zscore_study.jsonl", help="JSONL file of the driver's lines "
                        "(default %(default)s; replaced)")
    parser.add_argument("--driver", default=DEFAULT_DRIVER, help="the fit_study program (default %(default)s)")
    parser.add_argument("--timeout-s", type=float, default=900.0,
                        help="a campaign still running after this long counts as a failed fit (default 900)")
    parser.add_argument("--max-abs-z", type=float, default=None,
                        help="also fail when any converged fit has |z| >= this (default: no bound)")
    parser.add_argument("--no-variance-test", action="store_true",
                        help="leave the chi-square verdicts out of the exit status (for a few campaigns)")
    args = parser.parse_args(argv)
    if args.seeds_per_effect < 1:
        parser.error("--seeds-per-effect: must be >= 1")
    if args.first_seed < 0:
        parser.error("--first-seed: must be >= 0")
    if args.jobs < 1:
        parser.error("--jobs: must be >= 1")
    if not args.timeout_s > 0:
        parser.error("--timeout-s: must be > 0")
    if args.max_abs_z is not None and not args.max_abs_z > 0:
        parser.error("--max-abs-z: must be > 0")
    if not os.access(args.driver, os.X_OK):
        parser.error(f"--driver: {args.driver} is not an executable (build the target fit_study)")
    listed = subprocess.run([args.driver, "--list"], capture_output=True, text=True)
    if listed.returncode != 0:
        parser.error(f"--driver: {args.driver} --list failed: {listed.stderr.strip()}")
    known = listed.stdout.split()
    args.effects = [e for e in args.effects.split(",") if e]
    for effect in args.effects:
        if effect not in known:
            parser.error(f"--effects: unknown effect '{effect}' (known: {', '.join(known)})")
    if not args.effects or len(set(args.effects)) != len(args.effects):
        parser.error("--effects: give one or more effect ids, each once")
    return args


def run_campaign(driver, effect, seed, timeout_s):
    """The driver's JSON line for one campaign, or a failed line saying what went wrong."""
    failed = {"effect": effect, "seed": seed, "fitted": False, "converged": False}
    try:
        done = subprocess.run([driver, "--effect", effect, "--seed", str(seed)], capture_output=True, text=True,
                              timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return dict(failed, error=f"timed out after {timeout_s:g} s")
    if done.returncode != 0:
        return dict(failed, error=f"driver exit code {done.returncode}: {done.stderr.strip()[-500:]}")
    try:
        return json.loads(done.stdout)
    except json.JSONDecodeError:
        return dict(failed, error=f"driver printed no JSON line: {done.stdout.strip()[-500:]}")


def finite_z(parameter):
    z = parameter.get("z")
    return z if isinstance(z, (int, float)) and math.isfinite(z) else None


def summarise(lines, effects):
    """Rows per effect: (effect, campaigns, converged, [per-parameter dicts])."""
    table = []
    for effect in effects:
        runs = [line for line in lines if line["effect"] == effect]
        converged = [line for line in runs if line.get("converged")]
        names = []
        for line in converged:
            for p in line.get("parameters", []):
                if p["name"] not in names:
                    names.append(p["name"])
        rows = []
        for name in names:
            zs, missing = [], 0
            for line in converged:
                z = next((finite_z(p) for p in line["parameters"] if p["name"] == name), None)
                if z is None:
                    missing += 1
                else:
                    zs.append(z)
            n = len(zs)
            row = {"name": name, "n": n, "missing": missing}
            if n:
                mean = sum(zs) / n
                row.update(mean=mean, sd=math.sqrt(sum((z - mean) ** 2 for z in zs) / (n - 1)) if n > 1 else math.nan,
                           max_abs=max(abs(z) for z in zs), s=sum(z * z for z in zs))
                row["cdf"] = chi2.cdf(row["s"], n)
                row["p"] = 2 * min(row["cdf"], chi2.sf(row["s"], n))
                row["passed"] = LEVEL / 2 < row["cdf"] < 1 - LEVEL / 2 and missing == 0
            else:
                row.update(mean=math.nan, sd=math.nan, max_abs=math.nan, s=math.nan, cdf=math.nan, p=math.nan,
                           passed=False)
            rows.append(row)
        table.append((effect, len(runs), len(converged), rows))
    return table


def print_table(table):
    print(f"{'effect':<20} {'parameter':<11} {'n':>4} {'converged':>9} {'mean z':>7} {'sd z':>6} {'max|z|':>7} "
          f"{'sum z^2':>9} {'P(chi2<=S)':>10} {'p 2-sided':>9}  verdict")
    for effect, campaigns, converged, rows in table:
        fraction = f"{converged}/{campaigns}"
        if not rows:
            print(f"{effect:<20} {'-':<11} {0:>4} {fraction:>9}  (no converged fit)  FAIL")
        for row in rows:
            verdict = "PASS" if row["passed"] else "FAIL"
            if row["missing"]:
                verdict += f" ({row['missing']} without a standard error)"
            print(f"{effect:<20} {row['name']:<11} {row['n']:>4} {fraction:>9} {row['mean']:>7.3f} {row['sd']:>6.3f} "
                  f"{row['max_abs']:>7.2f} {row['s']:>9.2f} {row['cdf']:>10.4f} {row['p']:>9.4f}  {verdict}")


def main(argv):
    args = parse_args(argv)
    seeds = list(range(args.first_seed, args.first_seed + args.seeds_per_effect))
    print(f"effects: {', '.join(args.effects)}")
    print(f"seeds ({len(seeds)} per effect, the same for each): {' '.join(map(str, seeds))}")
    print(f"driver: {args.driver}; {args.jobs} job(s); lines to {args.out}", flush=True)
    work = [(effect, seed) for seed in seeds for effect in args.effects]
    lines = []
    start = time.monotonic()
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w") as out, concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        futures = [pool.submit(run_campaign, args.driver, effect, seed, args.timeout_s) for effect, seed in work]
        for done, future in enumerate(concurrent.futures.as_completed(futures), start=1):
            line = future.result()
            lines.append(line)
            out.write(json.dumps(line) + "\n")
            out.flush()
            state = "converged" if line.get("converged") else "NOT CONVERGED" + (
                f" ({line['error']})" if "error" in line else "")
            seconds = line.get("seconds")
            took = f"{seconds:.1f} s" if isinstance(seconds, (int, float)) else "-"
            print(f"[{done}/{len(work)}] {line['effect']} seed {line['seed']}: {state}, {took}", flush=True)
    print(f"{len(work)} campaigns in {time.monotonic() - start:.0f} s")
    for effect in args.effects:
        times = [line["seconds"] for line in lines if line["effect"] == effect and "seconds" in line]
        if times:
            print(f"{effect}: {sum(times) / len(times):.1f} s per campaign (mean), {max(times):.1f} s at most")
    table = summarise(lines, args.effects)
    print()
    print_table(table)

    ok = all(converged == campaigns for _, campaigns, converged, _ in table)
    if not args.no_variance_test:
        ok = ok and all(rows and all(row["passed"] for row in rows) for _, _, _, rows in table)
    if args.max_abs_z is not None:
        worst = [(line["effect"], line["seed"], p["name"], finite_z(p)) for line in lines if line.get("converged")
                 for p in line.get("parameters", []) if finite_z(p) is None or abs(finite_z(p)) >= args.max_abs_z]
        for effect, seed, name, z in worst:
            print(f"|z| bound {args.max_abs_z:g} broken: {effect} seed {seed} {name} z = {z}")
        ok = ok and not worst
    print("study:", "PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
