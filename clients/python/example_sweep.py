#!/usr/bin/env python3
"""Submits a sweep of the paper's actuator model, shows its progress, and prints the saturation
threshold per frequency and the jump (bistable) intervals per amplitude.

    strokelab serve --port 8080 --db var/strokelab.db &
    python3 clients/python/example_sweep.py --server http://127.0.0.1:8080 [--token T]

The grid is paper Eq. 1 (f_n = 5 Hz x 1.02^(n-1), 117 frequencies up to 49.6 Hz) x 26 amplitudes
0.1 .. 0.6 V unless --frequency-points / --amplitude-points say otherwise.
"""

import argparse
import math
import sys

from strokelab_client import Client, StrokelabError


def progress_printer():
    """A progress callback: a bar redrawn in place on a terminal, one line per change otherwise."""
    last = [None]
    tty = sys.stderr.isatty()

    def show(job):
        done, total = job["progress"]["done"], job["progress"]["total"]
        state = (job["status"], done)
        if state == last[0]:
            return
        last[0] = state
        filled = 30 * done // total if total else 0
        line = f"job {job['id']} [{'#' * filled}{'.' * (30 - filled)}] {done}/{total} tasks, {job['status']}"
        if tty:
            end = "\n" if job["status"] in ("succeeded", "failed", "cancelled") else ""
            print("\r" + line, end=end, file=sys.stderr, flush=True)
        else:
            print(line, file=sys.stderr, flush=True)

    return show


def volts(value):
    return f"{value:.4f}" if isinstance(value, (int, float)) and math.isfinite(value) else "-"


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--server", default="http://127.0.0.1:8080")
    parser.add_argument("--token", default=None, help="bearer token (default: $STROKELAB_TOKEN)")
    parser.add_argument("--frequency-points", type=int, default=117, help="Eq. 1 frequencies from 5 Hz")
    parser.add_argument("--amplitude-points", type=int, default=26, help="amplitudes 0.1 .. 0.6 V")
    args = parser.parse_args()

    client = Client(args.server, token=args.token)
    job = {
        "kind": "sweep",
        "name": "example_sweep.py: paper model, Eq. 1 grid",
        "model": "paper",
        "grid": {
            # Eq. 1 fixes the last frequency: "to" is left out.
            "frequency_hz": {"from": 5, "points": args.frequency_points, "spacing": "eq1"},
            "amplitude_v": {"from": 0.1, "to": 0.6, "points": args.amplitude_points},
        },
    }
    try:
        job_id = client.submit(job)
        print(f"submitted job {job_id}; the web page shows it at {client.server}/?job={job_id}", file=sys.stderr)
        final = client.wait(job_id, progress=progress_printer())
        if final["status"] != "succeeded":
            print(f"job {job_id} {final['status']}: {final.get('error', '')}", file=sys.stderr)
            return 1
        result = client.saturation_map(job_id)
    except StrokelabError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1

    print(f"Saturation threshold of the paper model (job {job_id}, {final.get('elapsed_s', 0):.1f} s)")
    print("  grazing: the amplitude where the stop-free response first touches the stop;")
    print("  lowest contacting: the lowest amplitude with a stable response that hits the stop;")
    print("  in between, both responses are stable (bistable in amplitude).")
    print(f"{'frequency [Hz]':>15} {'grazing [V]':>12} {'lowest contacting [V]':>22}")
    for t in result["saturation_threshold"]:
        print(f"{t['frequency_hz']:15.3f} {volts(t['grazing_amplitude_v']):>12} "
              f"{volts(t['lowest_contact_amplitude_v']):>22}")

    jumps = result["jump"]
    print()
    if not jumps:
        print("No jump (bistable) interval on this grid.")
    else:
        print("Jump (bistable) intervals: both the up-sweep and the down-sweep orbit are stable")
        print(f"{'amplitude [V]':>14} {'from [Hz]':>10} {'to [Hz]':>10}  bounded by")
        for j in jumps:
            print(f"{j['amplitude_v']:14.3f} {j['bistable_from_hz']:10.3f} {j['bistable_to_hz']:10.3f}  "
                  f"{j.get('from_kind', '')} .. {j.get('to_kind', '')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
