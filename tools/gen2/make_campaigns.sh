#!/bin/bash
# The issue-13 baseline set from the second generator, regenerated from the seeds below, and what
# `strokelab diagnose` names for each. Not committed data: writes under OUT (default /work/gen2-campaigns).
#
#   tools/gen2/make_campaigns.sh [OUT] [CASE...]      (default: every case; STROKELAB=path/to/strokelab)
#
# Every campaign: 6 frequencies x 4 amplitudes (5-11 Hz, 0.1-0.5 V), 1 s records at 51.2 kHz after 5 s
# from rest, 0.5 mV noise, 10 mV offset, 0.5 mV hum, k_p, c_p, g, d, k_s perturbed by up to 10 %
# (as tests/diagnose/concealed_effects.h, with seeds used nowhere else). The effect cases share one
# actuator (--perturb-seed 1300), so one noiseless campaign without any effect (OUT/clean/none) gives
# every effect's size in noise units (effect_size.py -> OUT/CASE/effect_size.json). Each case's noise
# has its own seed. Per case: OUT/CASE/{manifest.json, rec_*.csv, truth.json, diagnosis.json,
# effect_size.json}, OUT/clean/CASE (noiseless), and a line in OUT/summary.txt.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
OUT="${1:-/work/gen2-campaigns}"
shift || true
STROKELAB="${STROKELAB:-$HERE/../../build/release/strokelab}"
PY=/usr/bin/python3
JOBS="${JOBS:-2}"
COMMON=(--frequencies-hz 5,6,7,8,9,11 --amplitudes-v 0.1,0.3,0.4,0.5 --settle-s 5 --duration-s 1
        --sample-rate-hz 51200 --noise-rms 0.0005 --offset-v 0.01 --hum-v 0.0005
        --perturb k_p=0.1,c_p=0.1,g=0.1,d=0.1,k_s=0.1 --jobs "$JOBS")
NOISE=0.0005

# case | noise seed | perturbation seed | effects
CASES=(
  "control_1|1301|1301|"
  "control_2|1302|1302|"
  "force_factor|1303|1300|--effect force_factor=-5e4 --set b1=-10"
  "quadratic_damping|1304|1300|--effect quadratic_damping=1"
  "coil_inductance|1305|1300|--effect coil_inductance=2e-3"
  "cubic_hertzian|1306|1300|--effect cubic_stiffness=1.5e7 --effect hertzian_contact=1.5e7"
  "stop_mount|1307|1300|--effect stop_mount=3000"
  "position_damping|1308|1300|--effect position_damping=2e5"
)

mkdir -p "$OUT/clean"
if [ ! -f "$OUT/clean/none/manifest.json" ]; then
  "$PY" "$HERE/synth_campaign.py" --out "$OUT/clean/none" "${COMMON[@]}" --noise-rms 0 --offset-v 0 --hum-v 0 \
      --seed 1300 --perturb-seed 1300 > /dev/null
fi
for entry in "${CASES[@]}"; do
  IFS='|' read -r name seed perturb_seed effects <<< "$entry"
  if [ $# -gt 0 ] && [[ ! " $* " == *" $name "* ]]; then continue; fi
  dir="$OUT/$name"
  rm -rf "$dir" "$OUT/clean/$name"
  # shellcheck disable=SC2086  # effects is a list of flags
  "$PY" "$HERE/synth_campaign.py" --out "$dir" --clean-out "$OUT/clean/$name" "${COMMON[@]}" \
      --seed "$seed" --perturb-seed "$perturb_seed" $effects
  size="-"
  if [ -n "$effects" ]; then
    size="$("$PY" "$HERE/effect_size.py" --with "$OUT/clean/$name" --without "$OUT/clean/none" \
             --noise-rms "$NOISE" --out "$dir/effect_size.json")"
  fi
  start=$(date +%s)
  "$STROKELAB" diagnose --data "$dir" --json > "$dir/diagnosis.json" 2> "$dir/diagnose.stderr" || true
  seconds=$(( $(date +%s) - start ))
  named="$("$PY" "$HERE/summarize_diagnosis.py" "$dir/diagnosis.json")"
  echo "$name (seed $seed; $effects): effect size: $size; diagnose ${seconds}s: $named" | tee -a "$OUT/summary.txt"
done
