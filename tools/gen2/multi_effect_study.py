#!/usr/bin/python3
"""Several effects at once (issue 13): gen2 campaigns with two or three concealed effects, diagnosed.

Each case is one campaign of this generator (6 frequencies x 4 amplitudes, 1 s records at 51.2 kHz
after 5 s from rest, 0.5 mV noise, 10 mV offset, 0.5 mV hum, k_p, c_p, g, d and k_s perturbed by up to
10 %; the response channel where the case says) with the listed effects, each at the size the
diagnosis tests use (SHAPED's cases: their own sizes, and campaign arguments in place of these). Every
--strokelab binary diagnoses every campaign (side by side), and each verdict is scored:
- right: exactly the library effects concealed are named, each parameter within 25 % of the truth,
  and nothing is left unexplained (for a case with an effect in no library, a stop on a flexure,
  damping that grows with x^2, suspension creep, the coil's heating or a sensor's quadratic term: the
  library effects named, or fewer, and "unexplained" set);
- honest: not right, but "unexplained" is set and every effect named is one concealed;
- wrong: an effect named that was not concealed, or a parameter beyond 25 %, or nothing left
  unexplained while an effect concealed is not named.

Seeds (fixed before the runs): 9901-9908 and 9911-9920 were run first, 9903 was looked at while the
selection's look-ahead was built and 9925 while it was extended from every model on the path;
9921-9932 (but 9925) and 9941-9950 were run once after. 0.26.0's coil round (the coil's inductance
tried where the rest leave the misfit unexplained) was built on other seeds (9951, 9952) and changed
9905 only. 0.27.0's floor probe for the coil (built on 9713, 9917, 9928 and the coil campaigns 9951-9956)
changed no verdict; its test above the harmonics (built on 9927 and on 72-record campaigns of a stop on
a flexure, 9957 and 9959) turned 9927 right. 9961-9970 were run once at 0.30.0 (7 right, 3 wrong); the
swap and the backward check's new fits of 0.31.0 were built on 9966 and 9967 of them, and 9971-9980 (their
combinations fixed before) were run once after, both versions side by side. The cases of other sizes
and campaign shapes (SHAPED, 9981-10010) were run at 0.31.0: the misfit-scaled significance of 0.32.0 was
built on 9998, and 10001-10010 (fixed after 9998 was looked at) were run once after, both versions side by
side. 10057-10081 are multisine campaigns (broadband, 8,192 Hz; fixed before any was run, and run once at
0.44.0). Campaigns are kept under --out (generated once, then reused).

  tools/gen2/multi_effect_study.py --strokelab build/release/strokelab --out /tmp/multi
  tools/gen2/multi_effect_study.py --strokelab OLD --strokelab NEW --cases 9941-9950
  tools/gen2/multi_effect_study.py --strokelab build/release/strokelab --cases 9961-10010  (not in the default)

A campaign takes 3-5 s to generate (20 s with the coil) and 5-20 s to diagnose, so the 40 cases take
about 10 minutes per binary on 2 cores.
"""

import argparse
import json
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
CAMPAIGN = ["--frequencies-hz", "5,6,7,8,9,11", "--amplitudes-v", "0.1,0.3,0.4,0.5", "--settle-s", "5",
            "--duration-s", "1", "--noise-rms", "0.0005", "--offset-v", "0.01", "--hum-v", "0.0005",
            "--perturb", "k_p=0.1,c_p=0.1,g=0.1,d=0.1,k_s=0.1", "--jobs", "2"]
# The diagnosis tests' sizes (tests/diagnose/concealed_effects.h): gen2 effect -> (library id, key, value).
SIZES = {"cubic_stiffness": ("cubic_stiffness", "k3", 1.5e7), "quadratic_stiffness": ("quadratic_stiffness", "k2", 7e3),
         "hertzian_contact": ("hertzian_contact", "k_s", 1.5e7), "contact_damping": ("contact_damping", "c_s", 40.0),
         "second_stop": ("second_stop", "d_upper", 1.45e-3), "dry_friction": ("dry_friction", "friction_n", 0.001),
         "amplifier_saturation": ("amplifier_saturation", "amplifier_limit_v", 0.45),
         "quadratic_damping": ("quadratic_damping", "c2", 0.3), "force_factor": ("force_factor", "b2", -3e4),
         "coil_inductance": ("coil_inductance", "tau_e", 2e-3), "stop_mount": (None, None, 3000.0),
         "position_damping": (None, None, 2e5), "suspension_creep": (None, None, 30.0),
         "gain_compression": (None, None, 0.4), "sensor_quadratic": (None, None, 0.5)}
K3W = {"cubic_stiffness": 5e6, "quadratic_damping": 0.15}  # the weaker pair of case 9929
# seed -> (effects, response channel or None)
CASES = {
    9901: (["cubic_stiffness", "quadratic_damping"], None), 9902: (["force_factor", "cubic_stiffness"], None),
    9903: (["hertzian_contact", "quadratic_damping"], None), 9904: (["dry_friction", "cubic_stiffness"], None),
    9905: (["coil_inductance", "cubic_stiffness"], None), 9906: (["contact_damping", "quadratic_stiffness"], None),
    9907: (["second_stop", "quadratic_damping"], None), 9908: (["amplifier_saturation", "force_factor"], None),
    9911: (["hertzian_contact", "quadratic_damping"], None), 9912: (["hertzian_contact", "quadratic_damping"], None),
    9913: (["contact_damping", "quadratic_damping"], None), 9914: (["hertzian_contact", "dry_friction"], None),
    9915: (["hertzian_contact", "quadratic_stiffness"], None), 9916: (["contact_damping", "dry_friction"], None),
    9917: (["second_stop", "cubic_stiffness"], None), 9918: (["force_factor", "quadratic_damping"], None),
    9919: (["hertzian_contact", "force_factor"], None), 9920: (["amplifier_saturation", "quadratic_damping"], None),
    9921: (["cubic_stiffness", "hertzian_contact"], "acceleration"),
    9922: (["quadratic_damping", "dry_friction"], None), 9923: (["quadratic_stiffness", "quadratic_damping"], None),
    9924: (["contact_damping", "force_factor"], None),
    9925: (["cubic_stiffness", "hertzian_contact", "quadratic_damping"], None),
    9926: (["hertzian_contact", "quadratic_damping"], "displacement"),
    9927: (["stop_mount", "cubic_stiffness"], None), 9928: (["position_damping", "hertzian_contact"], None),
    9929: (["cubic_stiffness", "quadratic_damping"], None),
    9930: (["hertzian_contact", "quadratic_damping"], "velocity"),
    9931: (["second_stop", "contact_damping"], None), 9932: (["amplifier_saturation", "hertzian_contact"], None),
    9941: (["cubic_stiffness", "hertzian_contact", "quadratic_damping"], None),
    9942: (["cubic_stiffness", "hertzian_contact", "quadratic_damping"], None),
    9943: (["quadratic_stiffness", "contact_damping", "quadratic_damping"], None),
    9944: (["force_factor", "cubic_stiffness", "dry_friction"], None),
    9945: (["hertzian_contact", "quadratic_damping", "dry_friction"], None),
    9946: (["hertzian_contact", "quadratic_damping"], "acceleration"),
    9947: (["cubic_stiffness", "contact_damping"], None), 9948: (["quadratic_damping", "dry_friction"], None),
    9949: (["hertzian_contact", "cubic_stiffness"], None),
    9950: (["force_factor", "hertzian_contact", "quadratic_damping"], None),
    9961: (["force_factor", "dry_friction"], None), 9962: (["quadratic_stiffness", "hertzian_contact"], "velocity"),
    9963: (["amplifier_saturation", "cubic_stiffness"], None),
    9964: (["coil_inductance", "hertzian_contact"], None), 9965: (["second_stop", "hertzian_contact"], None),
    9966: (["contact_damping", "cubic_stiffness"], "displacement"),
    9967: (["quadratic_damping", "force_factor", "quadratic_stiffness"], None),
    9968: (["position_damping", "cubic_stiffness"], None), 9969: (["stop_mount", "quadratic_damping"], None),
    9970: (["cubic_stiffness", "hertzian_contact"], "acceleration"),
    9971: (["force_factor", "quadratic_stiffness"], None),
    9972: (["quadratic_damping", "quadratic_stiffness", "force_factor"], None),
    9973: (["contact_damping", "cubic_stiffness"], None), 9974: (["dry_friction", "quadratic_stiffness"], None),
    9975: (["hertzian_contact", "force_factor", "cubic_stiffness"], None),
    9976: (["amplifier_saturation", "contact_damping"], None), 9977: (["second_stop", "quadratic_damping"], None),
    9978: (["cubic_stiffness", "quadratic_stiffness", "dry_friction"], None),
    9979: (["contact_damping", "cubic_stiffness"], "displacement"),
    9980: (["quadratic_damping", "force_factor"], "velocity"),
}
# Cases at sizes and in campaigns of other shapes (0.32.0): seed -> ({effect: value}, response, campaign
# arguments that replace the default ones). 9981-10000 were fixed before any was run, then all run at
# 0.31.0; of them, 9998 was looked at.
WIDE, FEW = ["--frequencies-hz", "4,5,6,7,7.5,8,9,10,12,14"], ["--frequencies-hz", "5,7,8,10", "--amplitudes-v",
                                                                 "0.15,0.35,0.55"]
NOISY, LONG = ["--noise-rms", "0.002"], ["--sample-rate-hz", "25600", "--duration-s", "2"]
LOOSE = ["--perturb", "k_p=0.2,c_p=0.2,g=0.2,d=0.2,k_s=0.2"]
HUM60, PHASE = ["--hum-hz", "60", "--hum-v", "0.002"], ["--random-drive-phase", "--voltage-noise-rms", "0.0005"]
OFFSET = ["--offset-v", "0.1"]
# Broadband (stop 61): one 1 s multisine record (2-200 Hz, odd lines, random phases) per level at 8192 Hz
# after 2 s from rest, as tests/diagnose/broadband_diagnose_study.py's campaigns of strokelab's own synth:
# levels that stay clear of the stop, and levels whose last reaches it.
MULTISINE = ["--excitation", "multisine", "--sample-rate-hz", "8192", "--settle-s", "2", "--levels-v-rms"]
SMOOTH_MS, CONTACT_MS = MULTISINE + ["0.1,0.25,0.5"], MULTISINE + ["0.1,0.35,0.65"]
QUIET = ["--noise-rms", "0.0001"]  # broadband_diagnose_study.py draws 0.1-0.4 mV
SHAPED = {
    9981: ({"cubic_stiffness": 4.5e7}, None, WIDE),
    9982: ({"hertzian_contact": 6e6, "quadratic_damping": 0.6}, None, []),
    9983: ({"dry_friction": 0.003}, None, NOISY),
    9984: ({"force_factor": -1.5e4, "cubic_stiffness": 1.5e7}, None, LONG),
    9985: ({"contact_damping": 80.0}, "acceleration", LOOSE),
    9986: ({"quadratic_stiffness": 2e4, "hertzian_contact": 1.5e7}, None, FEW),
    9987: ({"amplifier_saturation": 0.35}, None, HUM60),
    9988: ({"second_stop": 1.45e-3, "cubic_stiffness": 7.5e6}, None, PHASE),
    9989: ({"coil_inductance": 4e-3}, "velocity", []),
    9990: ({"quadratic_damping": 0.9, "force_factor": -6e4}, None, OFFSET),
    9991: ({"cubic_stiffness": 3e7, "hertzian_contact": 3e7}, None, WIDE),
    9992: ({"quadratic_damping": 0.6}, None, NOISY),
    9993: ({"dry_friction": 0.002, "force_factor": -3e4}, None, LONG),
    9994: ({"contact_damping": 40.0, "quadratic_stiffness": 1.4e4}, None, LOOSE),
    9995: ({"hertzian_contact": 4.5e7}, "displacement", FEW),
    9996: ({"force_factor": -9e4}, None, PHASE),
    9997: ({"amplifier_saturation": 0.4, "cubic_stiffness": 3e7}, None, OFFSET),
    9998: ({"position_damping": 4e5}, None, HUM60),
    9999: ({"second_stop": 1.3e-3, "hertzian_contact": 1.5e7}, None, WIDE),
    10000: ({"cubic_stiffness": 1.5e7, "quadratic_damping": 0.3, "dry_friction": 0.002}, None, []),
    # Fixed after 9998 (damping that grows with x^2 "explained" by three library effects) was looked at,
    # before the rule built on it was run on them: run once, both versions side by side.
    10001: ({"position_damping": 3e5}, None, WIDE),
    10002: ({"position_damping": 6e5}, "acceleration", []),
    10003: ({"position_damping": 2e5, "quadratic_damping": 0.3}, None, LONG),
    10004: ({"stop_mount": 2000.0}, None, NOISY),
    10005: ({"stop_mount": 3000.0, "cubic_stiffness": 1.5e7}, None, FEW),
    10006: ({"position_damping": 4e5, "cubic_stiffness": 1.5e7}, None, PHASE),
    10007: ({"force_factor": -3e4, "contact_damping": 40.0}, "velocity", OFFSET),
    10008: ({"hertzian_contact": 1.5e7, "dry_friction": 0.002}, None, LOOSE),
    10009: ({"quadratic_stiffness": 7e3, "quadratic_damping": 0.3, "hertzian_contact": 1.5e7}, None, HUM60),
    10010: ({"position_damping": 1e6}, None, []),
    # Fixed at stop 59 (0.41.0) before any was run, and run once: nothing was tuned on them.
    10027: ({"force_factor": -3e4, "hertzian_contact": 1.5e7}, "acceleration", []),
    10028: ({"quadratic_stiffness": 7e3, "dry_friction": 0.002, "hertzian_contact": 1.5e7}, None, []),
    10029: ({"coil_inductance": 2e-3, "quadratic_damping": 0.3}, None, []),
    10030: ({"second_stop": 1.45e-3, "force_factor": -3e4}, None, []),
    10031: ({"amplifier_saturation": 0.45, "quadratic_stiffness": 7e3}, "velocity", []),
    10032: ({"contact_damping": 40.0, "hertzian_contact": 1.5e7}, None, []),
    10033: ({"stop_mount": 3000.0, "force_factor": -3e4}, None, []),
    10034: ({"cubic_stiffness": 1.5e7, "quadratic_damping": 0.3}, "displacement", LONG),
    10035: ({"dry_friction": 0.002, "contact_damping": 40.0}, None, NOISY),
    10036: ({"position_damping": 3e5, "dry_friction": 0.002}, None, LOOSE),
    # Three more effects in no library (stop 60): suspension creep (a Maxwell element, k_m in N/m), the
    # coil's heating (alpha_g in 1/V^2) and a sensor's quadratic term (a_s in 1/V), each 40-220 noise
    # standard errors in some harmonic (effect_size.py). Fixed before any was run, and run once.
    10037: ({"suspension_creep": 30.0}, None, []),
    10038: ({"gain_compression": 0.4}, None, []),
    10039: ({"sensor_quadratic": 0.5}, None, []),
    10040: ({"suspension_creep": 30.0, "cubic_stiffness": 1.5e7}, None, []),
    10041: ({"gain_compression": 0.4, "hertzian_contact": 1.5e7}, None, []),
    10042: ({"sensor_quadratic": 0.5, "quadratic_damping": 0.3}, None, []),
    10043: ({"suspension_creep": 30.0}, "acceleration", []),
    10044: ({"gain_compression": 0.4, "force_factor": -3e4}, None, []),
    10045: ({"sensor_quadratic": 0.5, "dry_friction": 0.002}, None, []),
    10046: ({"suspension_creep": 30.0, "gain_compression": 0.4}, None, []),
    # Fixed after 0.44.0's rules were built on 10037 and 10040 (and checked on 9969 and 10033), before
    # any of these was run: other sizes, channels and partners.
    10047: ({"suspension_creep": 60.0}, None, []),
    10048: ({"suspension_creep": 30.0, "quadratic_damping": 0.3}, None, []),
    10049: ({"suspension_creep": 30.0, "force_factor": -3e4}, None, []),
    10050: ({"suspension_creep": 30.0}, "velocity", []),
    10051: ({"gain_compression": 0.2}, None, []),
    10052: ({"gain_compression": 0.4, "cubic_stiffness": 1.5e7}, None, []),
    10053: ({"sensor_quadratic": 0.5, "cubic_stiffness": 1.5e7}, None, []),
    10054: ({"sensor_quadratic": 0.2}, "acceleration", []),
    10055: ({"position_damping": 3e5, "suspension_creep": 30.0}, None, []),
    10056: ({"suspension_creep": 30.0, "hertzian_contact": 1.5e7}, None, []),
    # Broadband campaigns of this generator (stop 61; its multisine is continuous, strokelab's drive the
    # samples joined by straight lines). Fixed before any was run: controls, library effects at the
    # broadband study's sizes, effects in no library.
    10057: ({}, None, SMOOTH_MS),
    10058: ({}, None, CONTACT_MS),
    10059: ({"cubic_stiffness": 1.5e7}, None, SMOOTH_MS),
    10060: ({"quadratic_damping": 1.0}, None, SMOOTH_MS),
    10061: ({"dry_friction": 0.003}, None, SMOOTH_MS),
    10062: ({"hertzian_contact": 1.5e7}, None, CONTACT_MS),
    10063: ({"cubic_stiffness": 1.5e7, "quadratic_damping": 1.0}, None, SMOOTH_MS),
    10064: ({"suspension_creep": 30.0}, None, SMOOTH_MS),
    10065: ({"gain_compression": 0.4}, None, SMOOTH_MS),
    10066: ({"sensor_quadratic": 0.5}, None, SMOOTH_MS),
    10067: ({"position_damping": 3e5}, None, SMOOTH_MS),
    10068: ({"stop_mount": 3000.0}, None, CONTACT_MS),
    10069: ({"suspension_creep": 30.0, "cubic_stiffness": 1.5e7}, None, SMOOTH_MS),
    # At 0.5 mV, the three 1 s records at 8192 Hz resolve few of these effects (10060 and 10063-10067: the
    # base model's held-out chi-square is noise's). The same kinds at a fifth of the noise, fixed after
    # 10057-10069 were run and before any of these was.
    10070: ({}, None, SMOOTH_MS + QUIET),
    10071: ({}, None, CONTACT_MS + QUIET),
    10072: ({"cubic_stiffness": 1.5e7}, None, SMOOTH_MS + QUIET),
    10073: ({"quadratic_damping": 1.0}, None, SMOOTH_MS + QUIET),
    10074: ({"cubic_stiffness": 1.5e7, "quadratic_damping": 1.0}, None, SMOOTH_MS + QUIET),
    10075: ({"suspension_creep": 30.0}, None, SMOOTH_MS + QUIET),
    10076: ({"gain_compression": 0.4}, None, SMOOTH_MS + QUIET),
    10077: ({"sensor_quadratic": 0.5}, None, SMOOTH_MS + QUIET),
    10078: ({"position_damping": 3e5}, None, SMOOTH_MS + QUIET),
    10079: ({"stop_mount": 3000.0}, None, CONTACT_MS + QUIET),
    10080: ({"suspension_creep": 30.0, "cubic_stiffness": 1.5e7}, None, SMOOTH_MS + QUIET),
    10081: ({"sensor_quadratic": 0.5, "cubic_stiffness": 1.5e7}, None, SMOOTH_MS + QUIET),
}
CASES.update({seed: (list(values), response) for seed, (values, response, _) in SHAPED.items()})


def value(seed, effect):
    if seed in SHAPED:
        return SHAPED[seed][0][effect]
    return K3W[effect] if seed == 9929 else SIZES[effect][2]


def parse_seeds(text):
    seeds = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        seeds += [s for s in range(int(lo), int(hi or lo) + 1) if s in CASES]
    return seeds


def generate(out, seed):
    directory = os.path.join(out, f"c{seed}")
    if os.path.exists(os.path.join(directory, "manifest.json")):
        return directory
    effects, response = CASES[seed]
    command = [sys.executable, os.path.join(HERE, "synth_campaign.py"), "--out", directory, "--seed", str(seed),
               *CAMPAIGN, *(SHAPED[seed][2] if seed in SHAPED else [])]
    for e in effects:
        command += ["--effect", f"{e}={value(seed, e)}"]
    if response:
        command += ["--response", response]
    subprocess.run(command, check=True, capture_output=True)
    return directory


def truth_of(directory):
    """{library id: {key: true value}} of the concealed library effects, and whether any is in no library."""
    with open(os.path.join(directory, "truth.json")) as f:
        truth = json.load(f)
    library, other = {}, False
    for e in truth["effects"]:
        library_id, key, _ = SIZES[e["name"]]
        if library_id is None:
            other = True
            continue
        true_value = e["value"]
        if key == "k_s":  # k_s is perturbed too: the truth is the model's
            true_value = truth["model"]["contact_stiffness"]
        if key == "tau_e":  # gen2 conceals the coil's inductance L; the library fits its pole L / R
            true_value = truth["model"]["coil_inductance_h"] / truth["model"]["coil_resistance_ohm"]
        library[library_id] = {key: true_value}
    return library, other


def score(d, library, other):
    named = {m["effect"]: m["parameters"] for m in d["missing_physics"]}
    unexplained = d["unexplained"] is not None
    off = [f"{e} {k} = {p[k]['value']:.4g} (truth {v:.4g})" for e, keys in library.items() if e in named
           for k, v in keys.items() for p in [named[e]] if abs(p[k]["value"] - v) > 0.25 * abs(v)]
    extra = sorted(set(named) - set(library))
    if extra or off:
        return "wrong", "; ".join([f"named {', '.join(extra)}"] * bool(extra) + off)
    if other:
        return ("right", "") if unexplained else ("wrong", "nothing left unexplained")
    if set(named) == set(library) and not unexplained:
        return "right", ""
    missing = sorted(set(library) - set(named))
    return ("honest" if unexplained else "wrong"), f"missed {', '.join(missing)}" if missing else "unexplained"


def main(argv):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--strokelab", action="append", required=True, help="a binary (repeatable: side by side)")
    parser.add_argument("--out", default="/tmp/gen2-multi-effect", help="campaigns and results [%(default)s]")
    parser.add_argument("--cases", default="9901-9950", help="seeds or ranges, e.g. 9941-9950,9903 [%(default)s]")
    args = parser.parse_args(argv)
    seeds = parse_seeds(args.cases)
    if not seeds:
        parser.error(f"--cases {args.cases}: no case has those seeds")
    os.makedirs(args.out, exist_ok=True)
    counts = {b: {"right": 0, "honest": 0, "wrong": 0} for b in args.strokelab}
    for seed in seeds:
        directory = generate(args.out, seed)
        library, other = truth_of(directory)
        for i, binary in enumerate(args.strokelab):
            run = subprocess.run([binary, "diagnose", "--data", directory, "--json", "--map-frequency-points", "0"],
                                 capture_output=True, text=True)
            if run.returncode:
                verdict, why = "wrong", "error: " + run.stderr.strip()[-200:]
                seconds = float("nan")
            else:
                d = json.loads(run.stdout)
                with open(os.path.join(args.out, f"c{seed}.{i}.json"), "w") as f:
                    f.write(run.stdout)
                verdict, why = score(d, library, other)
                seconds = d["seconds"]
            counts[binary][verdict] += 1
            print(f"{seed} {'+'.join(CASES[seed][0]):50s} [{i}] {verdict:6s} {seconds:5.1f} s  {why}", flush=True)
    for i, binary in enumerate(args.strokelab):
        c = counts[binary]
        print(f"[{i}] {binary}: right {c['right']}, honest {c['honest']}, wrong {c['wrong']} of {len(seeds)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
