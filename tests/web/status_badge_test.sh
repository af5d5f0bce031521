#!/usr/bin/env bash
# The web page's status badge in headless Chromium (issue 16, point 5): a fit job that succeeded as a
# computation but did not converge showed as a green "succeeded". Its job status carries "warnings",
# and the page shows them in amber, in the job list and in the detail title.
#
#   tests/web/status_badge_test.sh BINARY [SOURCE_DIR]
#
# Synthesises a small campaign under a data root, starts `BINARY serve` on it, fits it with one
# Ceres iteration (a fit that cannot converge), loads http://127.0.0.1:PORT/?job=ID and checks the
# DOM. Environment: CHROMIUM (default: chromium on PATH).
set -euo pipefail

bin=${1:?usage: status_badge_test.sh STROKELAB_BINARY [SOURCE_DIR]}
src=${2:-$(cd "$(dirname "$0")/../.." && pwd)}
browser=${CHROMIUM:-$(command -v chromium || command -v chromium-browser || true)}
[ -n "$browser" ] || { echo "FAIL: chromium is not installed (Debian package chromium)" >&2; exit 1; }

work=$(mktemp -d "${TMPDIR:-/tmp}/strokelab-badge.XXXXXX")
pid=""
trap '[ -z "$pid" ] || { kill "$pid" 2>/dev/null; wait "$pid" 2>/dev/null; }; rm -rf "$work"' EXIT
export HOME="$work/home" XDG_CONFIG_HOME="$work/home/.config" XDG_CACHE_HOME="$work/home/.cache"
mkdir -p "$HOME" "$work/data"
die() { echo "FAIL: $*" >&2; [ ! -f "$work/serve.log" ] || tail -5 "$work/serve.log" >&2; exit 1; }

"$bin" synth --out "$work/data/c" --amplitudes-v 0.1,0.4 --settle-s 2 --seed 5 > /dev/null
"$bin" serve --port 0 --db "$work/jobs.db" --workers 1 --quiet --data-root "$work/data" 2> "$work/serve.log" &
pid=$!
url=""
for _ in $(seq 1 150); do
  url=$(grep -o 'http://127\.0\.0\.1:[0-9]*' "$work/serve.log" | head -1 || true)
  [ -z "$url" ] || break
  sleep 0.1
done
[ -n "$url" ] || die "the server did not start"

job=$(curl -sf "$url/v1/jobs" -H 'Content-Type: application/json' \
        -d '{"kind": "fit", "campaign": {"path": "c"}, "options": {"max_iterations": 1}}' |
      python3 -c 'import json, sys; print(json.load(sys.stdin)["id"])') || die "the fit job was not accepted"
status=""
for _ in $(seq 1 600); do
  status=$(curl -sf "$url/v1/jobs/$job")
  case "$status" in *'"status":"queued"'* | *'"status":"running"'*) sleep 0.1 ;; *) break ;; esac
done
case "$status" in *'"warnings":["fit did not converge"'*) ;; *) die "job $job: $status" ;; esac

dom="$work/dom.html"
for budget in 3000 10000 30000; do
  timeout 120 "$browser" --headless --no-sandbox --disable-gpu --no-first-run --disable-background-networking \
    --disable-component-update --disable-dev-shm-usage --user-data-dir="$work/profile" --virtual-time-budget=$budget \
    --dump-dom "$url/?job=$job" > "$dom" 2> "$work/chromium.log" || true
  ! grep -q 'id="detail-title"[^>]*>Job ' "$dom" || break
done
grep -q '<td class="status-warning">succeeded: fit did not converge[^<]*</td>' "$dom" ||
  die "the job list does not show the warning in amber: $(grep -o '<td class="status-[^<]*' "$dom" | head -3)"
grep -q "<h2[^>]*class=\"status-warning\"[^>]*>Job $job (fit, succeeded: fit did not converge[^<]*)</h2>" "$dom" &&
  grep -q 'id="detail-title"' "$dom" ||
  die "the detail title does not show the warning in amber: $(grep -o '<h2[^>]*id="detail-title"[^<]*' "$dom")"
grep -q '\.status-warning { color: #b36b00' "$src/clients/web/index.html" || die "the amber colour is gone"
echo "PASS: job $job shows 'succeeded: fit did not converge' in amber"
