#!/usr/bin/python3
"""An effect's size in noise units: two noiseless campaigns (with and without the effect, same seed,
written by synth_campaign.py --clean-out) and the noise of the real one.

    effect_size.py --with DIR --without DIR --noise-rms V [--harmonics 5] [--out FILE.json]

Per record and harmonic h = 1..H, the complex amplitude A_h of the response channel [sensor V] over the
record's whole periods; the noise's standard error of each of its parts is sigma sqrt(2/n) for n samples
of white noise of rms sigma. z = |A_h(with) - A_h(without)| / (sigma sqrt(2/n)). Reported: the largest z
(and where), the largest per harmonic, and the count of z > 3 out of all. Also the whole waveform's
matched-filter signal-to-noise ratio ||with - without||_2 / sigma, per record (largest) and over the
campaign: the size of the difference for a detector that knows its shape (it sees ringing that the first
harmonics miss).
"""
import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from campaign_io import harmonics, read_campaign, whole_periods_samples  # noqa: E402


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--with", dest="with_dir", required=True)
    p.add_argument("--without", required=True)
    p.add_argument("--noise-rms", type=float, required=True, help="response channel noise [sensor V rms]")
    p.add_argument("--harmonics", type=int, default=5)
    p.add_argument("--out", default="")
    a = p.parse_args()
    rows = []
    for (entry, _, x, _, fs), (_, _, y, _, _) in zip(read_campaign(a.with_dir), read_campaign(a.without)):
        f = entry["drive_frequency_hz"]
        n = whole_periods_samples(len(x), f, fs)
        ax, ay = harmonics(x[:, 2], f, fs, a.harmonics), harmonics(y[:, 2], f, fs, a.harmonics)
        se = a.noise_rms * math.sqrt(2.0 / n)
        rows.append({"file": entry["file"], "frequency_hz": f, "amplitude_v": entry["drive_amplitude_v"],
                     "z": [abs(d) / se for d in ax - ay],
                     "snr": float(np.linalg.norm(x[:, 2] - y[:, 2]) / a.noise_rms)})
    z = np.array([r["z"] for r in rows])
    worst = np.unravel_index(np.argmax(z), z.shape)
    summary = {
        "max_z": float(z.max()),
        "max_at": {"file": rows[worst[0]]["file"], "frequency_hz": rows[worst[0]]["frequency_hz"],
                   "amplitude_v": rows[worst[0]]["amplitude_v"], "harmonic": int(worst[1]) + 1},
        "max_z_per_harmonic": [float(v) for v in z.max(axis=0)],
        "over_3": int((z > 3).sum()),
        "of": int(z.size),
        "max_record_snr": max(r["snr"] for r in rows),
        "campaign_snr": float(math.sqrt(sum(r["snr"] ** 2 for r in rows))),
        "records": rows,
    }
    text = json.dumps(summary, indent=1)
    if a.out:
        with open(a.out, "w") as f:
            f.write(text + "\n")
    print(f"max z = {summary['max_z']:.1f} at {summary['max_at']}; per harmonic "
          + ", ".join(f"{v:.1f}" for v in summary["max_z_per_harmonic"]) + f"; z > 3 in {summary['over_3']}/{summary['of']}; waveform SNR: record max "
          + f"{summary['max_record_snr']:.1f}, campaign {summary['campaign_snr']:.1f}")


if __name__ == "__main__":
    main()
