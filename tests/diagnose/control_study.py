#!/usr/bin/env python3
"""Control-campaign study of the diagnosis (issue 13): how often it names an effect or flags an
unexplained misfit on campaigns where the base model is right.

Each campaign is `strokelab synth` of the paper's model (k_p, c_p, g, d, k_s perturbed by up to
10 %) with noise, hum and offset drawn per seed (below), then `strokelab diagnose --json`. The rate
of campaigns with anything named or flagged, with its Clopper-Pearson one-sided 95 % upper bound,
must stay below 1 in 10 (issue 13); the open-world test's own size is meant to keep the flagged
rate below 1 in 20.

Seeds: 3001-3016 were looked at while choosing the open-world test (kUnexplainedP, open_world.h);
the study's seeds are 4001 onwards, looked at only through this script's summary. --generator gen2
makes campaigns of the same design by the second, independent generator (tools/gen2); 4161-4260 were
run once by each at 0.41.0.

    tests/diagnose/control_study.py --strokelab build/release/strokelab --count 100 --jobs 2 --out controls.jsonl
"""
import argparse
import concurrent.futures
import json
import os
import random
import subprocess
import sys
import tempfile

from scipy.stats import beta

FREQUENCIES_HZ = "5,6,7,8,9,11"
AMPLITUDES_V = "0.1,0.3,0.4,0.5"


def campaign_options(seed):
    """Noise, hum and offset of one control campaign, drawn from its seed [sensor V]."""
    rng = random.Random(seed)
    return {
        "noise_rms": rng.uniform(0.2e-3, 1.0e-3),
        "hum": rng.uniform(0.0, 2.0e-3),
        "hum_hz": rng.choice([50, 60]),
        "offset": rng.uniform(-0.02, 0.02),
    }


GEN2 = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tools", "gen2", "synth_campaign.py")


def synthesise(strokelab, seed, data, frequencies_hz=FREQUENCIES_HZ, generator="synth", jobs=1):
    """One control campaign into `data`, by `strokelab synth` or by the second generator (tools/gen2:
    scipy's integrator, its own event handling and its own draws from the seed; `jobs` processes)."""
    o = campaign_options(seed)
    # The offset as --offset-v=V: gen2's argparse reads a negative number in exponent form (-9e-05) as an option.
    common = ["--out", data, "--frequencies-hz", frequencies_hz, "--amplitudes-v", AMPLITUDES_V, "--settle-s", "5",
              "--noise-rms", str(o["noise_rms"]), "--hum-v", str(o["hum"]), "--hum-hz", str(o["hum_hz"]),
              f"--offset-v={o['offset']}", "--perturb", "k_p=0.1,c_p=0.1,g=0.1,d=0.1,k_s=0.1", "--seed", str(seed)]
    command = ([sys.executable, GEN2] + common + ["--jobs", str(jobs)] if generator == "gen2"
               else [strokelab, "synth"] + common + ["--threads", "1"])
    subprocess.run(command, check=True, capture_output=True)


def run(strokelab, seed, workdir, generator):
    o = campaign_options(seed)
    data = os.path.join(workdir, f"control_{seed}")
    synthesise(strokelab, seed, data, generator=generator)
    out = subprocess.run([strokelab, "diagnose", "--data", data, "--json", "--map-frequency-points", "0"],
                         check=True, capture_output=True, text=True)
    d = json.loads(out.stdout)
    u = d.get("unexplained")
    return {"seed": seed, **o,
            "named": [m["effect"] for m in d["missing_physics"]],
            "unexplained": u is not None,
            "heldout_chi2": d["fit_after"]["heldout_chi2"],
            "p_value": u["p_value"] if u else None,
            "conclusion": d["conclusion"], "seconds": d["seconds"]}


def clopper_pearson_upper(k, n, confidence=0.95):
    return 1.0 if k == n else float(beta.ppf(confidence, k + 1, n - k))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--strokelab", required=True)
    ap.add_argument("--first-seed", type=int, default=4001)
    ap.add_argument("--count", type=int, default=100)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", required=True, help="one JSON line per campaign")
    ap.add_argument("--generator", choices=["synth", "gen2"], default="synth",
                    help="who makes the campaigns: `strokelab synth` or tools/gen2/synth_campaign.py")
    ap.add_argument("--max-rate", type=float, default=None,
                    help="fail (exit 1) when the upper bound of the any-verdict rate reaches this")
    args = ap.parse_args()
    seeds = list(range(args.first_seed, args.first_seed + args.count))
    rows = []
    with tempfile.TemporaryDirectory(prefix="strokelab_controls_") as work, open(args.out, "w") as out, \
            concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        for row in pool.map(lambda s: run(args.strokelab, s, work, args.generator), seeds):
            rows.append(row)
            out.write(json.dumps(row) + "\n")
            out.flush()
            print(f"seed {row['seed']}: {'named ' + '+'.join(row['named']) if row['named'] else 'nothing named'}"
                  f"{', unexplained' if row['unexplained'] else ''} ({row['seconds']:.1f} s)", flush=True)
    n = len(rows)
    for label, hit in (("named", lambda r: bool(r["named"])), ("unexplained", lambda r: r["unexplained"]),
                       ("anything", lambda r: bool(r["named"]) or r["unexplained"])):
        k = sum(1 for r in rows if hit(r))
        print(f"{label}: {k} of {n} ({100 * k / n:.1f} %), Clopper-Pearson 95 % upper bound "
              f"{100 * clopper_pearson_upper(k, n):.1f} %")
    if args.max_rate is not None:
        k = sum(1 for r in rows if r["named"] or r["unexplained"])
        if clopper_pearson_upper(k, n) >= args.max_rate:
            sys.exit(1)


if __name__ == "__main__":
    main()
