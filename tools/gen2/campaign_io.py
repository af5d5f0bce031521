"""Reading a campaign in the recordings format and the complex amplitudes of its harmonics (shared by
test_gen2.py and effect_size.py)."""
import csv
import json
import math
import os

import numpy as np


def read_campaign(directory):
    with open(os.path.join(directory, "manifest.json")) as f:
        manifest = json.load(f)
    channel = next(v for k, v in manifest["channels"].items() if k != "voltage")
    sensitivity = next(v for k, v in channel.items() if k.startswith("sensitivity_"))
    records = []
    for entry in manifest["records"]:
        with open(os.path.join(directory, entry["file"])) as f:
            header = next(csv.reader(f))
        data = np.loadtxt(os.path.join(directory, entry["file"]), delimiter=",", skiprows=1)
        records.append((entry, header, data, sensitivity, manifest["sample_rate_hz"]))
    return records


def whole_periods_samples(samples, frequency_hz, sample_rate_hz):
    """How many samples from the start hold the record's whole periods."""
    periods = math.floor(samples * frequency_hz / sample_rate_hz + 1e-9)
    return round(periods * sample_rate_hz / frequency_hz)


def harmonics(signal, frequency_hz, sample_rate_hz, count=5):
    """Complex amplitudes of harmonics 1..count over the record's whole periods (from its start)."""
    n = whole_periods_samples(len(signal), frequency_hz, sample_rate_hz)
    t = np.arange(n) / sample_rate_hz
    return np.array([2.0 / n * np.sum(signal[:n] * np.exp(-2j * math.pi * h * frequency_hz * t))
                     for h in range(1, count + 1)])
