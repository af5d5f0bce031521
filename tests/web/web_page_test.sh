#!/usr/bin/env bash
# The web page in headless Chromium (Debian package `chromium`), driven over the DevTools protocol
# by tests/web/page_interaction.py (one browser for all of it):
#
#   tests/web/web_page_test.sh BINARY [SOURCE_DIR]
#
# Starts `BINARY serve --port 0` on a temporary database, submits a small Eq. 1 sweep of the paper
# model with the Python client, waits until it succeeds, and starts a second server with a token
# file. Then, in Chromium:
#   - the console check is shown to catch an uncaught error (a page with a known one), so that a
#     silent pass means a clean page;
#   - http://127.0.0.1:PORT/?job=ID: the job is listed as succeeded, the saturation map and both FRF
#     families are drawn (uPlot, the library the server serves from /vendor/), with the jump-interval
#     line and the job's grid and model (its resolved spec), and no error message;
#   - the mouse on the up-sweep point that stands farthest from the other amplitudes' curves (and
#     on its cell of the map): the readout shows that point's f, V, |H|, phase, peak-force ratio,
#     branch and stability as the REST API gives them; its amplitude's button hides its curve in
#     both families (canvas pixel and series), and shows it again;
#   - nothing on the console: no uncaught exception, no CSP refusal, no failed load;
#   - the server with tokens, the page without one: the server's 401 message, not a job list.
# Environment: CHROMIUM (default: chromium on PATH); WEB_TEST_FULL=1 runs the demo's full Eq. 1 x 26
# sweep instead of the small one; WEB_TEST_SCREENSHOT=FILE saves the page with the hover readout,
# WEB_TEST_FRF_SCREENSHOT=FILE the server's SVG FRF family of the sweep (docs/make_screenshots.sh
# makes docs/web-page.png and docs/frf-family.png this way).
set -euo pipefail

bin=${1:?usage: web_page_test.sh STROKELAB_BINARY [SOURCE_DIR]}
src=${2:-$(cd "$(dirname "$0")/../.." && pwd)}
chromium=${CHROMIUM:-$(command -v chromium || command -v chromium-browser || true)}
if [ -z "$chromium" ]; then
  echo "FAIL: chromium is not installed (Debian package chromium; deploy/local.sh installs it)" >&2
  exit 1
fi

tmp=$(mktemp -d "${TMPDIR:-/tmp}/strokelab-web.XXXXXX")
server_pids=()
cleanup() {
  for pid in "${server_pids[@]}"; do kill "$pid" 2>/dev/null || true; wait "$pid" 2>/dev/null || true; done
  rm -rf "$tmp"
}
trap cleanup EXIT
# Chromium writes caches and crash reports under HOME and XDG dirs: keep them in the temp dir.
export HOME="$tmp/home" XDG_CONFIG_HOME="$tmp/home/.config" XDG_CACHE_HOME="$tmp/home/.cache"
mkdir -p "$HOME"

fail() {
  echo "FAIL: $*" >&2
  for log in "$tmp"/*.err; do [ -f "$log" ] && { echo "--- $log (tail)" >&2; tail -20 "$log" >&2; }; done
  exit 1
}

# start_server NAME [serve options...]: starts a server, adds it to server_pids, sets port.
start_server() {
  local name=$1
  shift
  # The log exists before the server starts: the background shell opens it later, and sed must not race it.
  : > "$tmp/$name.err"
  "$bin" serve --port 0 --db "$tmp/$name.db" --quiet "$@" 2> "$tmp/$name.err" &
  local pid=$!
  server_pids+=("$pid")
  port=""
  for _ in $(seq 1 200); do
    port=$(sed -n 's|^strokelab serving http://127\.0\.0\.1:\([0-9]*\) .*|\1|p' "$tmp/$name.err" | head -1)
    [ -n "$port" ] && break
    kill -0 "$pid" 2>/dev/null || fail "the server $name exited at start"
    sleep 0.1
  done
  [ -n "$port" ] || fail "the server $name did not print its address within 20 s"
}

# 1. A server with tokens (no workers: it only answers the page) and one with a finished sweep.
printf 'submit web-test-submit-token-0123\nread web-test-read-token-0123456\n' > "$tmp/tokens"
start_server auth --workers 0 --token-file "$tmp/tokens"
auth_port=$port
start_server page --workers 2
if [ "${WEB_TEST_FULL:-0}" = 1 ]; then
  amplitude_points=26 frequency_points=117
else
  amplitude_points=6 frequency_points=40
fi
job_id=$(PYTHONPATH="$src/clients/python" /usr/bin/python3 - "http://127.0.0.1:$port" \
           "$frequency_points" "$amplitude_points" <<'EOF'
import sys
from strokelab_client import Client
client = Client(sys.argv[1])
job_id = client.submit({"kind": "sweep", "name": "paper model, Eq. 1 grid", "model": "paper",
                        "grid": {"frequency_hz": {"from": 5, "points": int(sys.argv[2]), "spacing": "eq1"},
                                 "amplitude_v": {"from": 0.1, "to": 0.6, "points": int(sys.argv[3])}}})
job = client.wait(job_id, poll_s=0.2, timeout_s=300)
if job["status"] != "succeeded":
    sys.exit(f"job {job_id} {job['status']}: {job.get('error')}")
print(job_id)
EOF
) || fail "the sweep did not succeed"
echo "sweep job $job_id succeeded ($frequency_points x $amplitude_points grid) on port $port"

# 2. The page in Chromium.
options=(--auth-url "http://127.0.0.1:$auth_port/")
if [ -n "${WEB_TEST_SCREENSHOT:-}" ]; then options+=(--screenshot "$WEB_TEST_SCREENSHOT" --height 1480); fi
if [ -n "${WEB_TEST_FRF_SCREENSHOT:-}" ]; then options+=(--frf-screenshot "$WEB_TEST_FRF_SCREENSHOT"); fi
/usr/bin/python3 "$src/tests/web/page_interaction.py" --chromium "$chromium" --server "http://127.0.0.1:$port" \
  --profile "$tmp/profile" sweep "$job_id" "${options[@]}" || fail "the page in Chromium (above)"
echo "PASS"
