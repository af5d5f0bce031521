#!/usr/bin/python3
"""Second, independent generator of stepped-sine and multisine campaigns (issues 13, 14): see README.md.

    synth_campaign.py --out DIR [--model paper|FILE] [--set KEY=VALUE]... [--effect NAME=VALUE]...
                      [--frequencies-hz 6,7,8] [--amplitudes-v 0.1,0.3] [--duration-s 1] [--settle-s 10]
                      [--excitation multisine --levels-v-rms 0.1,0.3 --band-hz 2:200 --grid odd|full]
                      [--sample-rate-hz 51200] [--response force] [--noise-rms V] [--offset-v V]
                      [--hum-v V] [--perturb k_p=0.1,c_p=0.1] [--seed N] [--jobs N]

Writes DIR/manifest.json and DIR/rec_NNN.csv in the recordings format
(/work/shared/docs/recordings-format.md) and the truth to DIR/truth.json (or --truth FILE).
"""
import argparse
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gen2_integrate  # noqa: E402
import gen2_model  # noqa: E402

# Response channel -> (manifest sensitivity key, default sensitivity, simulated quantity, unit).
RESPONSES = {
    "force": ("sensitivity_V_per_N", 0.02248, "f", "N"),  # paper sec. 3: 22.48 mV/N
    "acceleration": ("sensitivity_V_per_m_s2", 0.0102, "a", "m/s^2"),
    "velocity": ("sensitivity_V_per_m_s", 1.0, "v", "m/s"),
    "displacement": ("sensitivity_V_per_m", 1000.0, "x", "m"),
}


def number_list(text, name):
    try:
        values = [float(item) for item in text.split(",") if item.strip()]
    except ValueError:
        raise SystemExit(f"error: --{name}: '{text}' is not a comma-separated list of numbers") from None
    if not values:
        raise SystemExit(f"error: --{name}: needs at least one value")
    return values


def parse_perturb(text):
    """'k_p=0.1,c_p=0.1,sensitivity=0.05' -> [(key, r)], r in [0, 1)."""
    out, seen = [], set()
    for item in (i for i in text.split(",") if i.strip()):
        key, sep, value = item.partition("=")
        key = key.strip()
        try:
            r = float(value)
        except ValueError:
            r = float("nan")
        if not sep or not (0 <= r < 1):
            raise SystemExit(f"error: --perturb '{item}': expected KEY=R with R in [0, 1)")
        if key != "sensitivity":
            key = gen2_model.find_parameter(key)[0]
        if key in seen:
            raise SystemExit(f"error: --perturb: '{key}' is perturbed twice")
        seen.add(key)
        out.append((key, r))
    return out


def parse_args(argv):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="campaign directory to write")
    p.add_argument("--clean-out", default="", help="also write the campaign without noise, offset and hum here")
    p.add_argument("--truth", default="", help="truth file (default DIR/truth.json)")
    p.add_argument("--model", default="paper", help="preset (paper, linear) or a model JSON file")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="set a model parameter")
    p.add_argument("--effect", action="append", default=[], metavar="NAME=VALUE",
                   help="add an effect: " + ", ".join(gen2_model.EFFECTS))
    p.add_argument("--frequencies-hz", default="6,7,8,9,11,13")
    p.add_argument("--amplitudes-v", default="0.1,0.3,0.4,0.5")
    p.add_argument("--excitation", default="stepped-sine", choices=["stepped-sine", "multisine"],
                   help="multisine: one broadband record per --levels-v-rms, its period the kept length")
    p.add_argument("--levels-v-rms", default="0.05,0.15,0.3", help="multisine: drive levels [V rms]")
    p.add_argument("--band-hz", default="2:200", help="multisine: LOW:HIGH [Hz]")
    p.add_argument("--grid", default="odd", choices=["odd", "full"], help="multisine: odd lines only, or all")
    p.add_argument("--duration-s", type=float, default=1.0, help="kept length of each record")
    p.add_argument("--settle-s", type=float, default=10.0, help="simulated from rest before the kept part")
    p.add_argument("--sample-rate-hz", type=float, default=51200.0)
    p.add_argument("--response", default="force", choices=sorted(RESPONSES))
    p.add_argument("--sensitivity", type=float, default=0.0, help="written sensitivity (0: the default)")
    p.add_argument("--nominal", action="store_true", help="the manifest calls the sensitivity nominal")
    p.add_argument("--noise-rms", type=float, default=0.0, help="Gaussian noise, response channel [sensor V]")
    p.add_argument("--voltage-noise-rms", type=float, default=0.0, help="Gaussian noise, voltage channel [V]")
    p.add_argument("--offset-v", type=float, default=0.0, help="DC offset, response channel [sensor V]")
    p.add_argument("--hum-v", type=float, default=0.0, help="mains hum amplitude, response channel [sensor V]")
    p.add_argument("--hum-hz", type=float, default=50.0)
    p.add_argument("--perturb", default="", metavar="KEY=R,...",
                   help="relative perturbations: each value times 1 + R U(-1, 1); KEY may be 'sensitivity'")
    p.add_argument("--random-drive-phase", action="store_true", help="each drive starts at a random phase")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--perturb-seed", type=int, default=None,
                   help="seed of the perturbations alone (default --seed): campaigns that differ only in an "
                        "effect and their noise can share the same actuator")
    p.add_argument("--method", default="DOP853", choices=["DOP853", "Radau"])
    p.add_argument("--rtol", type=float, default=1e-10)
    p.add_argument("--jobs", type=int, default=1, help="records simulated in parallel processes")
    p.add_argument("--actuator", default="inertial actuator, second generator (tools/gen2)")
    a = p.parse_args(argv)
    a.frequencies_hz = number_list(a.frequencies_hz, "frequencies-hz")
    a.amplitudes_v = number_list(a.amplitudes_v, "amplitudes-v")
    a.levels_v_rms = number_list(a.levels_v_rms, "levels-v-rms")
    band = a.band_hz.split(":")
    a.band_hz = number_list(",".join(band), "band-hz") if len(band) == 2 else []
    a.perturb = parse_perturb(a.perturb)
    nyquist = a.sample_rate_hz / 2
    checks = [
        (a.sample_rate_hz > 0 and math.isfinite(a.sample_rate_hz), "--sample-rate-hz must be > 0"),
        (all(0 < f < nyquist for f in a.frequencies_hz), f"--frequencies-hz must lie in (0, {nyquist})"),
        (all(v >= 0 and math.isfinite(v) for v in a.amplitudes_v), "--amplitudes-v must be >= 0"),
        (all(v > 0 and math.isfinite(v) for v in a.levels_v_rms), "--levels-v-rms must be > 0"),
        (len(a.band_hz) == 2 and 0 < a.band_hz[0] < a.band_hz[1] < nyquist,
         f"--band-hz must be LOW:HIGH with 0 < LOW < HIGH < {nyquist}"),
        (a.duration_s > 0 and round(a.duration_s * a.sample_rate_hz) >= 2, "--duration-s must hold 2 samples"),
        (a.excitation != "multisine" or len(a.band_hz) != 2 or
         gen2_integrate.multisine_lines(a.band_hz[0], a.band_hz[1], a.duration_s, a.grid == "odd"),
         "--band-hz holds no multisine line k / duration (odd k on the odd grid)"),
        (a.settle_s >= 0, "--settle-s must be >= 0"),
        (min(a.noise_rms, a.voltage_noise_rms, a.hum_v) >= 0, "noise and hum must be >= 0"),
        (a.jobs >= 1, "--jobs must be >= 1"),
        (0 < a.rtol < 1e-3, "--rtol must be in (0, 1e-3)"),
        (a.seed >= 0 and (a.perturb_seed is None or a.perturb_seed >= 0), "--seed must be >= 0"),
    ]
    for ok, message in checks:
        if not ok:
            raise SystemExit("error: " + message)
    return a


def build_model(args):
    """Nominal model (preset/file, --set, --effect), then the perturbed one and what was drawn."""
    model = gen2_model.load_model(args.model)
    for assignment in args.set:
        gen2_model.apply_override(model, assignment)
    effects = [gen2_model.apply_effect(model, e) for e in args.effect]
    gen2_model.validate(model)
    perturb_seed = args.seed if args.perturb_seed is None else args.perturb_seed
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([perturb_seed, 0])))
    actual = dict(model)
    key, default_sensitivity, _, _ = RESPONSES[args.response]
    written = args.sensitivity or default_sensitivity
    true_sensitivity = written
    perturbations = []
    for name, r in args.perturb:
        factor = 1.0 + r * rng.uniform(-1.0, 1.0)
        nominal = written if name == "sensitivity" else model[name]
        value = nominal * factor if math.isfinite(nominal) else nominal
        if name == "sensitivity":
            true_sensitivity = value
        else:
            actual[name] = value
        perturbations.append({"key": name, "relative_half_width": r, "factor": factor,
                              "nominal": gen2_model.json_number(nominal), "actual": gen2_model.json_number(value)})
    try:
        gen2_model.validate(actual)
    except gen2_model.ModelError as e:
        raise gen2_model.ModelError(f"--perturb: the perturbed model is not valid: {e}") from None
    return model, actual, effects, perturbations, written, true_sensitivity


def simulate_record(job):
    """One record: (index, frequency, amplitude, model, args, sensitivities) -> arrays and its truth."""
    k, frequency_hz, amplitude_v, model, args, written, true_sensitivity = job
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([args.seed, 1 + k])))
    hum_phase = rng.uniform(0.0, 2 * math.pi)
    drive_phase = rng.uniform(-math.pi, math.pi) if args.random_drive_phase else 0.0
    fs = args.sample_rate_hz
    total = round((args.settle_s + args.duration_s) * fs)
    kept = min(total, round(args.duration_s * fs))
    t_sim = np.arange(total - kept, total) / fs
    multisine = None
    if args.excitation == "multisine":  # drawn after the stepped sine's numbers, which stay as they were
        multisine = gen2_integrate.MultisineDrive(amplitude_v, args.band_hz[0], args.band_hz[1], args.duration_s,
                                                  args.grid == "odd", rng)
        dyn = gen2_integrate.Dynamics(model, 0.0, 0.0, multisine=multisine)
    else:
        dyn = gen2_integrate.Dynamics(model, amplitude_v, 2 * math.pi * frequency_hz, drive_phase)
    start = time.perf_counter()
    sim = gen2_integrate.simulate(dyn, total / fs, t_sim, method=args.method, rtol=args.rtol)
    seconds = time.perf_counter() - start
    t_kept = np.arange(kept) / fs
    voltage = dyn.raw_drive(t_sim) + args.voltage_noise_rms * rng.standard_normal(kept)
    response = RESPONSES[args.response][2]
    sensed = true_sensitivity * sim[response]
    sensed = sensed + model["a_s"] * sensed ** 2  # the sensor's own quadratic term (sensor_quadratic)
    volts = (sensed + args.offset_v
             + args.hum_v * np.sin(2 * math.pi * args.hum_hz * t_kept + hum_phase)
             + args.noise_rms * rng.standard_normal(kept))
    truth = {"file": f"rec_{k + 1:03d}.csv", "frequency_hz": frequency_hz, "amplitude_v": amplitude_v,
             "hum_phase_rad": hum_phase, "segments": sim["segments"], "lower_impacts": sim["lower_impacts"],
             "seconds": round(seconds, 3)}
    if args.random_drive_phase:
        truth["drive_phase_rad"] = drive_phase
    if multisine is not None:
        truth.update(frequency_hz=None, amplitude_v=None, level_v_rms=amplitude_v, lines=len(multisine.omegas),
                     line_phases_rad=multisine.phases.tolist())
    clean = (t_kept, dyn.raw_drive(t_sim), sensed)
    return k, t_kept, voltage, volts, truth, clean


def write_csv(path, header, columns):
    """%.17g: every double round-trips, so a noiseless record is the simulation to the last bit."""
    table = np.column_stack(columns)
    with open(path, "w") as f:
        f.write(header + "\n")
        np.savetxt(f, table, fmt="%.17g", delimiter=",")


def write_record(args, column, t, voltage, volts, truth, clean):
    header = f"time_s,voltage_V,{column}"
    write_csv(os.path.join(args.out, truth["file"]), header, [t, voltage, volts])
    if args.clean_out:
        write_csv(os.path.join(args.clean_out, truth["file"]), header, list(clean))
    return truth


def main(argv=None):
    args = parse_args(sys.argv[1:] if argv is None else argv)
    try:
        nominal, model, effects, perturbations, written, true_sensitivity = build_model(args)
    except gen2_model.ModelError as e:
        raise SystemExit(f"error: {e}") from None
    # A multisine record is given its level where a stepped sine's is given its amplitude.
    steps = ([(a, f) for a in args.amplitudes_v for f in args.frequencies_hz] if args.excitation == "stepped-sine"
             else [(level, None) for level in args.levels_v_rms])
    jobs = [(k, f, a, model, args, written, true_sensitivity) for k, (a, f) in enumerate(steps)]
    os.makedirs(args.out, exist_ok=True)
    if args.clean_out:
        os.makedirs(args.clean_out, exist_ok=True)
    key, _, _, _ = RESPONSES[args.response]
    column = "force_sensor_V" if args.response == "force" else f"{args.response}_sensor_V"
    records = [None] * len(jobs)
    start = time.perf_counter()
    if args.jobs > 1:
        with ProcessPoolExecutor(max_workers=args.jobs) as pool:
            results = pool.map(simulate_record, jobs)
            for result in results:
                records[result[0]] = write_record(args, column, *result[1:])
    else:
        for job in jobs:
            result = simulate_record(job)
            records[result[0]] = write_record(args, column, *result[1:])
    manifest = {
        "format": "strokelab-recordings/1",
        "actuator": args.actuator,
        "sample_rate_hz": args.sample_rate_hz,
        "channels": {
            "voltage": {"column": "voltage_V", "unit": "V", "note": "drive voltage measured before the power amplifier"},
            args.response: dict({"column": column, "unit": "V", key: written}, **({"nominal": True} if args.nominal else {})),
        },
        "records": [{"file": r["file"], "excitation": "broadband"} if args.excitation == "multisine" else
                    {"file": r["file"], "drive_frequency_hz": r["frequency_hz"], "drive_amplitude_v": r["amplitude_v"]}
                    for r in records],
    }
    for directory in [args.out] + ([args.clean_out] if args.clean_out else []):
        with open(os.path.join(directory, "manifest.json"), "w") as f:
            json.dump(manifest, f, indent=2)
            f.write("\n")
    truth = {
        "format": "strokelab-gen2-truth/1",
        "generator": "tools/gen2/synth_campaign.py",
        "command": sys.argv if argv is None else ["synth_campaign.py"] + list(argv),
        "model": gen2_model.to_json(model),
        "nominal_model": gen2_model.to_json(nominal),
        "library_model": gen2_model.library_part(model),
        "effects": [{"name": n, "key": k, "value": v} for n, k, v in effects],
        "perturbations": perturbations,
        "integrator": {"method": args.method, "rtol": args.rtol},
        "response": args.response,
        "sensitivity_written": written,
        "sensitivity_true": true_sensitivity,
        "nominal_sensitivity": args.nominal,
        "noise_rms_v": args.noise_rms,
        "voltage_noise_rms_v": args.voltage_noise_rms,
        "offset_v": args.offset_v,
        "hum_v": args.hum_v,
        "hum_hz": args.hum_hz,
        "seed": args.seed,
        "perturb_seed": args.seed if args.perturb_seed is None else args.perturb_seed,
        "settle_s": args.settle_s,
        "duration_s": args.duration_s,
        "excitation": args.excitation,
        **({"band_hz": args.band_hz, "grid": args.grid} if args.excitation == "multisine" else {}),
        "sample_rate_hz": args.sample_rate_hz,
        "wall_seconds": round(time.perf_counter() - start, 3),
        "records": records,
    }
    truth_path = args.truth or os.path.join(args.out, "truth.json")
    if os.path.dirname(truth_path):
        os.makedirs(os.path.dirname(truth_path), exist_ok=True)
    with open(truth_path, "w") as f:
        json.dump(truth, f, indent=2)
        f.write("\n")
    print(f"wrote {len(records)} records to {args.out} in {truth['wall_seconds']} s")


if __name__ == "__main__":
    main()
