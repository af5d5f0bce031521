#!/usr/bin/env bash
# Soak test of the service on loopback: `strokelab serve` with a fresh database under concurrent
# submitters, cancellers and queriers, and remote workers restarted now and then (SIGKILL and
# SIGTERM), for a set time or request count; then a report (requests, latency p50/p99 per kind, jobs
# by outcome, points written, errors by kind, server RSS at start and end) and database checks.
#
#   deploy/soak.sh [SECONDS] [--max-requests N] [--workers N] [--json FILE] ...
#     SECONDS defaults to 300. Other options: tests/soak/soak_client.py --help.
#     STROKELAB_BINARY picks the binary (default: build/release/strokelab, else build/*/strokelab).
# Exit code 0 when the checks pass (file intact, each task's rows once, server alive).
set -euo pipefail
cd "$(dirname "$0")/.."

duration=300
if [[ $# -gt 0 && $1 =~ ^[0-9]+$ ]]; then
  duration=$1
  shift
fi

binary=${STROKELAB_BINARY:-}
if [[ -z $binary ]]; then
  for candidate in build/release/strokelab build/*/strokelab; do
    if [[ -x $candidate ]]; then binary=$candidate; break; fi
  done
fi
if [[ -z $binary || ! -x $binary ]]; then
  echo "soak: no strokelab binary (build first, or set STROKELAB_BINARY)" >&2
  exit 2
fi

# The driver cleans up its own children; this also covers a driver killed outright.
python3 tests/soak/soak_client.py --binary "$binary" --duration "$duration" "$@" &
driver=$!
trap 'kill -TERM $driver 2>/dev/null; wait $driver' INT TERM
wait $driver
