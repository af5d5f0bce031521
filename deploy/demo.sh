#!/usr/bin/env bash
# The main job until the service lands: the steady-state saturation map of the paper's actuator
# (saturation threshold, jump region, FRF branches) and the paper's simulated figures.
set -euo pipefail
bin=${1:-build/release/strokelab}
out=${STROKELAB_DEMO_DIR:-var}
"$bin" sweep --model paper --grid eq1 --amplitude-v 0.1:0.6 --amplitude-points 26 --out "$out/sweep"
"$bin" paper --out "$out/paper" > /dev/null
echo
echo "saturation map: $out/sweep/saturation_map.svg (threshold curves and jump region drawn on it)"
echo "FRF branches:   $out/sweep/frf_up.svg, $out/sweep/frf_down.svg; tables: $out/sweep/*.csv"
echo "paper figures:  $out/paper/*.svg; summaries: $out/sweep/summary.txt, $out/paper/summary.txt"
