#!/usr/bin/python3
"""One line from `strokelab diagnose --json` output: what it named (with parameters), the held-out
error before and after, `unexplained` if the diagnosis reports it, and the start of its conclusion."""
import json
import sys


def main(path):
    try:
        with open(path) as f:
            d = json.load(f)
    except (OSError, ValueError):
        print("diagnose failed (no JSON): see diagnose.stderr")
        return
    named = []
    for m in d.get("missing_physics", []):
        values = ", ".join(f"{k}={p['value']:.4g}+-{p['standard_error']:.2g}" for k, p in m["parameters"].items())
        named.append(f"{m['effect']}({values}; held-out gain {m['heldout_gain']:.3g})")
    before, after = d["fit_before"]["heldout_nrmse"], d["fit_after"]["heldout_nrmse"]
    unexplained = json.dumps(d["unexplained"])[:80] if "unexplained" in d else "(no field)"
    print(f"named [{'; '.join(named) or 'nothing'}]; held-out nrmse {before:.3g} -> {after:.3g}; "
          f"unexplained {unexplained}; conclusion: {d['conclusion'][:200]}")


if __name__ == "__main__":
    main(sys.argv[1])
