#!/usr/bin/env bash
# The main job until the service lands: reproduce the paper's simulated figures and show where the
# paper's actuator saturates its stroke.
set -euo pipefail
bin=${1:-build/release/strokelab}
out=${STROKELAB_DEMO_DIR:-var/paper}
"$bin" paper --out "$out"
echo
echo "figures (SVG) and tables (CSV) are in $out/; the summary is $out/summary.txt"
