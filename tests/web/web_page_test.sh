#!/usr/bin/env bash
# The web page in headless Chromium (Debian package `chromium`): it loads, lists jobs, shows a
# finished sweep's saturation map and FRF families, and logs nothing to the console.
#
#   tests/web/web_page_test.sh BINARY [SOURCE_DIR]
#
# Starts `BINARY serve --port 0` on a temporary database, submits a small Eq. 1 sweep of the paper
# model with the Python client, waits until it succeeds, loads http://127.0.0.1:PORT/?job=ID and
#   - checks the DOM: the job is listed as succeeded, the map's title and the FRF titles are there
#     as inline SVG, the jump-interval line is there, the job's grid and model (its resolved spec)
#     are shown, and no "cannot list jobs" message;
#   - checks the console: Chromium's log (--enable-logging=stderr) has no CONSOLE line at all
#     (uncaught exceptions, console.error/warn/log, failed resource loads); a page with a known
#     uncaught error is loaded first to prove that such lines are caught;
#   - takes a 1400 x 1000 screenshot and checks it is a PNG;
#   - with a token file: the page without a token shows the server's 401 message, not a map.
# Environment: CHROMIUM (default: chromium on PATH); WEB_TEST_FULL=1 runs the demo's full Eq. 1 x 26
# sweep instead of the small one; WEB_TEST_SCREENSHOT=FILE copies the screenshot there (this is how
# docs/web-page.png is made: WEB_TEST_FULL=1 WEB_TEST_SCREENSHOT=docs/web-page.png).
set -euo pipefail

bin=${1:?usage: web_page_test.sh STROKELAB_BINARY [SOURCE_DIR]}
src=${2:-$(cd "$(dirname "$0")/../.." && pwd)}
chromium=${CHROMIUM:-$(command -v chromium || command -v chromium-browser || true)}
if [ -z "$chromium" ]; then
  echo "FAIL: chromium is not installed (Debian package chromium; deploy/local.sh installs it)" >&2
  exit 1
fi

tmp=$(mktemp -d "${TMPDIR:-/tmp}/strokelab-web.XXXXXX")
server_pid=""
cleanup() {
  if [ -n "$server_pid" ]; then kill "$server_pid" 2>/dev/null || true; wait "$server_pid" 2>/dev/null || true; fi
  rm -rf "$tmp"
}
trap cleanup EXIT
# Chromium writes caches and crash reports under HOME and XDG dirs: keep them in the temp dir.
export HOME="$tmp/home" XDG_CONFIG_HOME="$tmp/home/.config" XDG_CACHE_HOME="$tmp/home/.cache"
mkdir -p "$HOME"

fail() {
  echo "FAIL: $*" >&2
  if [ -f "$tmp/server.err" ]; then echo "--- server log (tail)" >&2; tail -20 "$tmp/server.err" >&2; fi
  exit 1
}

# start_server NAME [serve options...]: starts the server, sets server_pid and port.
start_server() {
  local name=$1
  shift
  "$bin" serve --port 0 --db "$tmp/$name.db" --quiet "$@" 2> "$tmp/server.err" &
  server_pid=$!
  port=""
  for _ in $(seq 1 200); do
    port=$(sed -n 's|^strokelab serving http://127\.0\.0\.1:\([0-9]*\) .*|\1|p' "$tmp/server.err" | head -1)
    [ -n "$port" ] && break
    kill -0 "$server_pid" 2>/dev/null || fail "the server exited at start"
    sleep 0.1
  done
  [ -n "$port" ] || fail "the server did not print its address within 20 s"
}
stop_server() {
  kill "$server_pid" 2>/dev/null || true
  wait "$server_pid" 2>/dev/null || true
  server_pid=""
}

# chrome RUN_NAME URL ACTION...: one headless Chromium run with a fresh profile; its log goes to
# $tmp/RUN_NAME.log, its stdout to $tmp/RUN_NAME.out.
chrome() {
  local name=$1 url=$2
  shift 2
  rm -rf "$tmp/profile-$name"
  timeout 120 "$chromium" --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
    --disable-background-networking --disable-component-update --disable-sync --disable-default-apps --disable-dev-shm-usage \
    --user-data-dir="$tmp/profile-$name" --enable-logging=stderr --v=0 --window-size=1400,1000 \
    --hide-scrollbars "$@" "$url" > "$tmp/$name.out" 2> "$tmp/$name.log" || true
}
console_lines() { grep -a 'CONSOLE' "$tmp/$1.log" || true; }

# 0. The console check catches an uncaught error (so a silent pass means a clean page).
chrome selfcheck "data:text/html,<script>undefinedFunction()</script>" --virtual-time-budget=1000 --dump-dom
console_lines selfcheck | grep -q 'Uncaught ReferenceError' ||
  fail "the console check does not see an uncaught error (Chromium's log format changed?): $(cat "$tmp/selfcheck.log")"

# 1. A server with a finished sweep.
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
url="http://127.0.0.1:$port/?job=$job_id"

# 2. The DOM once the page has loaded the job (retried with more virtual time on a slow machine).
ok=0
for budget in 5000 15000 40000; do
  chrome dom "$url" --virtual-time-budget=$budget --dump-dom
  if grep -q 'Stroke saturation, up-sweep branch' "$tmp/dom.out" && grep -q 'Jump (bistable) intervals\|No jump interval' "$tmp/dom.out"; then
    ok=1
    break
  fi
done
[ $ok = 1 ] || fail "the saturation map is not in the page's DOM after 40 s of virtual time: $(head -c 3000 "$tmp/dom.out")"
dom="$tmp/dom.out"
grep -q "<h2[^>]*id=\"detail-title\"[^>]*>Job $job_id (sweep, succeeded)</h2>" "$dom" || fail "the detail title does not name job $job_id as succeeded"
grep -q '<td class="status-succeeded">succeeded</td>' "$dom" || fail "the job list does not show the succeeded job"
[ "$(grep -o '<svg' "$dom" | wc -l)" -ge 3 ] || fail "fewer than 3 inline SVG pictures (map, FRF up, FRF down)"
grep -q 'First-order FRF |H|, up-sweep branch' "$dom" || fail "the up-sweep FRF family is missing"
grep -q 'First-order FRF |H|, down-sweep branch' "$dom" || fail "the down-sweep FRF family is missing"
grep -q '<details id="spec">' "$dom" && grep -q 'mass_kg = 0.032' "$dom" && grep -q 'amplitude: [0-9]* values' "$dom" ||
  fail "the job's grid and model (its resolved spec) are not shown"
grep -q 'id="jobs-note"></p>' "$dom" || fail "the job list shows a note: $(grep -o 'id="jobs-note">[^<]*' "$dom")"
# Error messages in the rendered page (the script's own text, which contains them, left out).
sed '/<script[ >]/,/<\/script>/d' "$dom" > "$tmp/dom-body.html"
if grep -q 'cannot list jobs\|cannot load the results\|cannot show job\|failed:' "$tmp/dom-body.html"; then
  fail "the page shows an error: $(grep -o 'cannot [^<]*\|failed:[^<]*' "$tmp/dom-body.html" | head -3)"
fi
if [ -n "$(console_lines dom)" ]; then fail "console messages on the page: $(console_lines dom)"; fi
echo "DOM: job list, saturation map, FRF families and jump intervals present; console clean"

# 3. The screenshot.
chrome shot "$url" --virtual-time-budget="$budget" --screenshot="$tmp/page.png"
[ -s "$tmp/page.png" ] || fail "no screenshot written: $(tail -5 "$tmp/shot.log")"
[ "$(head -c 8 "$tmp/page.png" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] || fail "the screenshot is not a PNG"
if [ -n "$(console_lines shot)" ]; then fail "console messages on the page (screenshot run): $(console_lines shot)"; fi
if [ -n "${WEB_TEST_SCREENSHOT:-}" ]; then
  cp "$tmp/page.png" "$WEB_TEST_SCREENSHOT"
  echo "screenshot: $WEB_TEST_SCREENSHOT ($(wc -c < "$tmp/page.png") bytes)"
fi
stop_server

# 4. With tokens: no token in the page -> the server's 401 message instead of a job list.
printf 'submit web-test-submit-token-0123\nread web-test-read-token-0123456\n' > "$tmp/tokens"
start_server auth --workers 0 --token-file "$tmp/tokens"
chrome auth "http://127.0.0.1:$port/" --virtual-time-budget=3000 --dump-dom
grep -q 'id="jobs-note">cannot list jobs: missing bearer token' "$tmp/auth.out" ||
  fail "without a token the page does not show the 401 message: $(grep -o 'id="jobs-note">[^<]*' "$tmp/auth.out")"
stop_server
echo "without a token: the page shows the server's 401 message"
echo "PASS"
