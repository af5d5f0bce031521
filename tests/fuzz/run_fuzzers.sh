#!/usr/bin/env bash
# Runs every libFuzzer harness of tests/fuzz for SECONDS each (default 60), as many at once as there
# are cores, and prints, per harness, the executions, executions per second, corpus size and
# findings; exits 1 if any harness found a crash, leak, timeout or out-of-memory. The harnesses must be built first (deploy/local.sh fuzz
# SECONDS builds them into build/asan, the ASan+UBSan build, and calls this script; CI runs it for 15 s
# per harness).
#
#   tests/fuzz/run_fuzzers.sh [SECONDS] [HARNESS ...]
#
# Each harness starts from its checked-in seeds (tests/fuzz/corpus/NAME, read only) and a working
# corpus in build/asan/corpus/NAME that keeps the inputs found by earlier runs on this machine.
# Findings go to build/asan/findings/NAME/ (crash-*, leak-*, timeout-*, oom-*); to keep one as a
# regression, copy it into tests/fuzz/corpus/NAME/ and add a GoogleTest case for it.
set -euo pipefail
cd "$(dirname "$0")/../.."

SECONDS_EACH=${1:-60}
shift || true
FUZZ_DIR=${STROKELAB_FUZZ_DIR:-build/asan}
HARNESSES=("$@")
[ ${#HARNESSES[@]} -gt 0 ] || HARNESSES=(job_spec recordings http)

# Leaks are findings; UB already aborts (-fno-sanitize-recover). A slow input is a finding past 25 s
# (the service's own request timeouts are 5 s); memory beyond 2 GB is one too.
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1}

# One harness: fuzzes it, then writes its row of the table to $FUZZ_DIR/logs/NAME.row and, when it
# failed, the end of its log to NAME.failure.
fuzz_one() {  # NAME
  local name=$1
  local binary="$FUZZ_DIR/tests/fuzz/fuzz_$name"
  local work="$FUZZ_DIR/corpus/$name" findings="$FUZZ_DIR/findings/$name" log="$FUZZ_DIR/logs/$name.log"
  mkdir -p "$work" "$findings" "$(dirname "$log")"
  rm -f "$FUZZ_DIR/logs/$name.failure"
  local start elapsed status=0 executions per_second corpus found
  start=$(date +%s)
  "$binary" -max_total_time="$SECONDS_EACH" -timeout=25 -rss_limit_mb=2048 -print_final_stats=1 \
    -artifact_prefix="$findings/" "$work" "tests/fuzz/corpus/$name" >"$log" 2>&1 || status=$?
  elapsed=$(($(date +%s) - start))
  executions=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  per_second=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  corpus=$(grep -o 'corp: [0-9]*' "$log" | tail -1 | cut -d' ' -f2 || true)  # libFuzzer's in-memory corpus
  found=$(find "$findings" -type f -newermt "@$start" | wc -l)
  printf '%-12s %8s %12s %8s %10s  %s\n' "$name" "$elapsed" "${executions:-?}" "${per_second:-?}" "${corpus:-?}" \
    "$found" >"$FUZZ_DIR/logs/$name.row"
  if [ "$status" -ne 0 ] || [ "$found" -ne 0 ]; then
    { echo "fuzz_$name failed (exit $status); the end of $log:"; tail -40 "$log"; } >"$FUZZ_DIR/logs/$name.failure"
  fi
}

for name in "${HARNESSES[@]}"; do
  if [ ! -x "$FUZZ_DIR/tests/fuzz/fuzz_$name" ]; then
    echo "no $FUZZ_DIR/tests/fuzz/fuzz_$name: build the harnesses first (deploy/local.sh fuzz)" >&2
    exit 2
  fi
done
# Each harness is one process on one core: as many run at once as there are cores, so that each
# still gets SECONDS of a whole core and the table takes ceil(harnesses / cores) x SECONDS.
JOBS=$(nproc)
running=0
for name in "${HARNESSES[@]}"; do
  fuzz_one "$name" &
  running=$((running + 1))
  if [ "$running" -ge "$JOBS" ]; then
    wait -n || true
    running=$((running - 1))
  fi
done
wait || true

failed=0
printf '%-12s %8s %12s %8s %10s  %s\n' harness seconds executions exec/s corpus findings
for name in "${HARNESSES[@]}"; do
  cat "$FUZZ_DIR/logs/$name.row"
  if [ -f "$FUZZ_DIR/logs/$name.failure" ]; then
    failed=1
    cat "$FUZZ_DIR/logs/$name.failure" >&2
  fi
done
exit $failed
