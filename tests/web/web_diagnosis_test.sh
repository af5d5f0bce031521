#!/usr/bin/env bash
# A diagnose job on the web page in headless Chromium (issue 16 point 9; tests/web/page_interaction.py):
#
#   tests/web/web_diagnosis_test.sh BINARY [SOURCE_DIR]
#
# Synthesises a small campaign with a clipping amplifier (`BINARY synth`, 12 records: the case of
# tests/cli/diagnosed_model_test.cc, which the diagnosis finds), serves it with --data-root and
# submits a diagnose job with a small map grid. Chromium opens the job at once: while it runs, the
# page shows its progress as the job status gives it (stage k of N, or tasks done); once finished,
# its conclusion, the diagnosed model's thresholds as a plot whose hover readout gives
# threshold_shift.csv's values at the hovered frequency, the report in a frame, and a "download
# model.json" button whose file equals /v1/jobs/ID/report/model.json. Nothing on the console.
set -euo pipefail

bin=${1:?usage: web_diagnosis_test.sh STROKELAB_BINARY [SOURCE_DIR]}
src=${2:-$(cd "$(dirname "$0")/../.." && pwd)}
chromium=${CHROMIUM:-$(command -v chromium || command -v chromium-browser || true)}
if [ -z "$chromium" ]; then
  echo "FAIL: chromium is not installed (Debian package chromium; deploy/local.sh installs it)" >&2
  exit 1
fi

tmp=$(mktemp -d "${TMPDIR:-/tmp}/strokelab-webdiag.XXXXXX")
server_pid=""
cleanup() {
  if [ -n "$server_pid" ]; then kill "$server_pid" 2>/dev/null || true; wait "$server_pid" 2>/dev/null || true; fi
  rm -rf "$tmp"
}
trap cleanup EXIT
export HOME="$tmp/home" XDG_CONFIG_HOME="$tmp/home/.config" XDG_CACHE_HOME="$tmp/home/.cache"
mkdir -p "$HOME" "$tmp/data"

fail() {
  echo "FAIL: $*" >&2
  if [ -f "$tmp/server.err" ]; then echo "--- server log (tail)" >&2; tail -20 "$tmp/server.err" >&2; fi
  exit 1
}

"$bin" synth --out "$tmp/data/clipping" --frequencies-hz 5,7,9,11 --amplitudes-v 0.1,0.3,0.5 --settle-s 5 \
  --noise-rms 5e-4 --seed 12 --set amplifier_limit_v=0.4 > "$tmp/synth.out" 2>&1 || fail "synth: $(cat "$tmp/synth.out")"

# The log exists before the server starts: the background shell opens it later, and sed must not race it.
: > "$tmp/server.err"
"$bin" serve --port 0 --db "$tmp/jobs.db" --quiet --workers 1 --data-root "$tmp/data" 2> "$tmp/server.err" &
server_pid=$!
port=""
for _ in $(seq 1 200); do
  port=$(sed -n 's|^strokelab serving http://127\.0\.0\.1:\([0-9]*\) .*|\1|p' "$tmp/server.err" | head -1)
  [ -n "$port" ] && break
  kill -0 "$server_pid" 2>/dev/null || fail "the server exited at start"
  sleep 0.1
done
[ -n "$port" ] || fail "the server did not print its address within 20 s"

job_id=$(PYTHONPATH="$src/clients/python" /usr/bin/python3 - "http://127.0.0.1:$port" <<'EOF'
import sys
from strokelab_client import Client
print(Client(sys.argv[1]).submit({"kind": "diagnose", "name": "clipping amplifier", "campaign": {"path": "clipping"},
                                  "options": {"pairs": False, "map_frequency_points": 8, "map_amplitude_points": 4}}))
EOF
) || fail "the diagnose job was refused"
echo "diagnose job $job_id submitted on port $port"
/usr/bin/python3 "$src/tests/web/page_interaction.py" --chromium "$chromium" --server "http://127.0.0.1:$port" \
  --profile "$tmp/profile" diagnose "$job_id" --downloads "$tmp/downloads" || fail "the page in Chromium (above)"
echo "PASS"
