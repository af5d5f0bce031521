#!/usr/bin/python3
"""The broadband fit's study: how often do the records accept it, and do its standard errors hold the truth?

For each seed of a list fixed and printed before the run, `strokelab synth` writes a broadband campaign
(odd multisines over 2..200 Hz at the given rms levels, 1 s records after 2 s of settling, at
--sample-rate-hz; the paper's model with k_p, c_p, g perturbed by up to 10 %, d by up to 5 % and k_s
by up to 10 %; 0.2 mV noise, a 3 mV offset and 0.5 mV of 50 Hz hum on the force sensor) and
`strokelab fit --json` fits it by its time series (identify/broadband_campaign.h). Per campaign one
JSON line goes to --out: accepted (converged and not rejected by the records), the stop positions
tried, seconds, and per parameter estimate, standard error, truth and z = (estimate - truth) / se.

Printed: the accepted fraction, the rejected and not-converged counts, the largest |z| of any accepted
fit, and per parameter over the accepted fits n, mean z, sd z and the two-sided p-value of the
hypothesis that z has unit variance (chi-square of sum z^2 with n degrees of freedom). A rejected fit is
the fit saying it failed; an accepted fit with a z beyond 5 would be a wrong answer given as right.

With --mixed, each campaign also holds stepped sines of the same actuator (`strokelab synth` with the same
seed and perturbations: 5, 7, 9 and 11 Hz at 0.1, 0.3 and 0.5 V, 3 s of settling, 0.5 mV noise, 51.2 kHz),
and `fit` fits both kinds jointly (identify/mixed_campaign.h).

Seeds: --first-seed .. --first-seed + --seeds - 1 (default 7001-7040). The fit's stop positions and
rejection test were tuned on seeds 6-12, 41-43 and 101 at 8192 Hz; the unit tests use 12, 41-43, 101.

  tests/recordings/broadband_fit_study.py --jobs 2 --out var/broadband_fit_study.jsonl
  tests/recordings/broadband_fit_study.py --levels 0.1,1.0 --seeds 10

Debian's /usr/bin/python3 with python3-scipy; the binary defaults to this checkout's Release build.
A campaign of two 8192-sample records takes 1-4 s (up to ~20 s when every stop position is tried).
"""

import argparse
import concurrent.futures
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

from scipy.stats import chi2

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DEFAULT_BINARY = os.path.join(ROOT, "build", "release", "strokelab")
TRUTH_FIELDS = {"k_p": "stiffness_n_per_m", "c_p": "damping_n_s_per_m", "g": "gain_n_per_v",
                "d": "lower_stop_m", "k_s": "contact_stiffness"}


def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--binary", default=DEFAULT_BINARY)
    parser.add_argument("--seeds", type=int, default=40)
    parser.add_argument("--first-seed", type=int, default=7001)
    parser.add_argument("--levels", default="0.1,0.6", help="rms drive levels [V] (default %(default)s)")
    parser.add_argument("--sample-rate-hz", type=float, default=8192.0)
    parser.add_argument("--mixed", action="store_true", help="add stepped sines: a joint fit")
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--out", default=None, help="JSONL of every campaign (replaced)")
    return parser.parse_args(argv)


PERTURB = "k_p=0.1,c_p=0.1,g=0.1,d=0.05,k_s=0.1"


def add_stepped_sines(binary, campaign, work, seed):
    """Stepped sines of the campaign's actuator (the same seed and perturbations) joined to its manifest."""
    stepped = os.path.join(work, "stepped")
    subprocess.run([binary, "synth", "--out", stepped, "--frequencies-hz", "5,7,9,11", "--amplitudes-v", "0.1,0.3,0.5",
                    "--settle-s", "3", "--noise-rms", "5e-4", "--seed", str(seed), "--perturb", PERTURB],
                   check=True, capture_output=True, text=True)
    with open(os.path.join(stepped, "truth.json")) as f, open(os.path.join(campaign, "truth.json")) as g:
        if json.load(f)["model"] != json.load(g)["model"]:
            raise RuntimeError(f"seed {seed}: the stepped and broadband campaigns simulate different models")
    with open(os.path.join(campaign, "manifest.json")) as f:
        manifest = json.load(f)
    with open(os.path.join(stepped, "manifest.json")) as f:
        other = json.load(f)
    for record in manifest["records"]:
        record["sample_rate_hz"] = manifest["sample_rate_hz"]
    for record in other["records"]:
        name = "stepped_" + record["file"]
        shutil.copy(os.path.join(stepped, record["file"]), os.path.join(campaign, name))
        record["file"] = name
        manifest["records"].append(record)
    manifest["sample_rate_hz"] = other["sample_rate_hz"]
    with open(os.path.join(campaign, "manifest.json"), "w") as f:
        json.dump(manifest, f, indent=1)


def run_one(binary, seed, levels, sample_rate_hz, mixed):
    work = tempfile.mkdtemp(prefix="broadband-study-")
    try:
        campaign = os.path.join(work, "campaign")
        subprocess.run([binary, "synth", "--out", campaign, "--excitation", "multisine", "--levels-v-rms", levels,
                        "--duration-s", "1", "--settle-s", "2", "--sample-rate-hz", str(sample_rate_hz),
                        "--noise-rms", "2e-4", "--offset-v", "3e-3", "--hum-v", "5e-4", "--seed", str(seed),
                        "--perturb", PERTURB],
                       check=True, capture_output=True, text=True)
        if mixed:
            add_stepped_sines(binary, campaign, work, seed)
        start = time.time()
        fit = subprocess.run([binary, "fit", "--json", "--data", campaign], check=True, capture_output=True, text=True)
        wall = time.time() - start
        result = json.loads(fit.stdout)
        with open(os.path.join(campaign, "truth.json")) as f:
            truth = json.load(f)["model"]
        line = {"seed": seed, "accepted": result["converged"] and not result["rejected"],
                "converged": result["converged"], "rejected": result["rejected"],
                "starts_tried": result.get("starts_tried", 1), "seconds": wall, "parameters": {}}
        for name, p in result["parameters"].items():
            value, se, true = p["value"], p["standard_error"], truth[TRUTH_FIELDS[name]]
            z = (value - true) / se if se else None
            line["parameters"][name] = {"value": value, "standard_error": se, "truth": true, "z": z}
        return line
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main(argv):
    args = parse_args(argv)
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    print(f"seeds {seeds[0]}-{seeds[-1]}, levels {args.levels} V rms, {args.sample_rate_hz:g} Hz"
          f"{', with stepped sines (a joint fit)' if args.mixed else ''}", flush=True)
    lines = []
    out = open(args.out, "w") if args.out else None
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        futures = [pool.submit(run_one, args.binary, s, args.levels, args.sample_rate_hz, args.mixed) for s in seeds]
        for future in concurrent.futures.as_completed(futures):
            line = future.result()
            lines.append(line)
            if out:
                out.write(json.dumps(line) + "\n")
                out.flush()
    accepted = [x for x in lines if x["accepted"]]
    rejected = sum(1 for x in lines if x["rejected"])
    unconverged = sum(1 for x in lines if not x["converged"])
    seconds = sorted(x["seconds"] for x in lines)
    print(f"accepted {len(accepted)}/{len(lines)}; rejected by the records {rejected}, not converged {unconverged}; "
          f"seconds median {seconds[len(seconds) // 2]:.1f}, max {seconds[-1]:.1f}")
    worst = 0.0
    for name in TRUTH_FIELDS:
        z = [x["parameters"][name]["z"] for x in accepted if name in x["parameters"]]
        z = [v for v in z if v is not None and math.isfinite(v)]
        if not z:
            continue
        n, s = len(z), sum(v * v for v in z)
        mean = sum(z) / n
        sd = math.sqrt(sum((v - mean) ** 2 for v in z) / max(n - 1, 1))
        p = chi2.cdf(s, n)
        worst = max(worst, max(abs(v) for v in z))
        print(f"  {name:4s} n {n:3d}  mean z {mean:+.2f}  sd z {sd:.2f}  max |z| {max(abs(v) for v in z):.2f}  "
              f"p(unit variance) {2 * min(p, 1 - p):.3f}")
    print(f"largest |z| of an accepted fit: {worst:.2f}")
    return 0 if worst < 5.0 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
