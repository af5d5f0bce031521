#!/usr/bin/env bash
# The Slurm array of deploy/slurm/strokelab-workers.sbatch on a real single-node Slurm (Debian 12's
# slurm-wlm 22.05 and munge), started on localhost in a temporary directory:
#   1. the README's command, unchanged (`sbatch --array=1-2 deploy/slurm/strokelab-workers.sbatch URL`,
#      token in $STROKELAB_TOKEN), runs a sweep job on a local `strokelab serve --workers 0`: the job
#      succeeds with exactly its points, and the workers exit on their own once idle
#      (STROKELAB_EXIT_WHEN_IDLE, here 5 s) so the array ends COMPLETED;
#   2. `scancel` of a running array stops its workers (the batch shell passes SIGTERM on).
# Everything it started (munged, slurmctld, slurmd, the server) is stopped at the end, by pid.
#
#   tests/slurm/run.sh [BINARY]     (default build/release/strokelab; run as root)
#
# It needs root (slurmd runs jobs as their user) and the packages slurm-wlm and munge; as root it
# installs missing ones with apt-get (`deploy/local.sh` installs them with its other packages). When
# the cluster cannot start it fails saying why: it never passes silently. `deploy/local.sh test` runs
# it after the Release tests (~15 s here); `deploy/local.sh test-slurm` runs it alone.
set -euo pipefail

repo=$(cd "$(dirname "$0")/../.." && pwd)
binary=$(realpath "${1:-$repo/build/release/strokelab}")
fail() {
  echo "slurm test FAILED: $*" >&2
  if [ -n "${dir:-}" ]; then  # what the cluster and the workers said
    { squeue 2>&1 || true; tail -n 5 "$dir"/*.log "$dir"/munge/log 2>&1 || true; } >&2
    echo "logs kept in $dir" >&2
  fi
  exit 1
}
[ -x "$binary" ] || fail "no strokelab binary at $binary (build it first)"
[ "$(id -u)" = 0 ] || fail "needs root: slurmd must run as root to start jobs (run as root, e.g. in CI)"
if ! command -v slurmctld > /dev/null || ! command -v munged > /dev/null; then
  echo "installing slurm-wlm and munge (apt-get)"
  { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge; } > /dev/null ||
    fail "apt-get could not install slurm-wlm and munge"
fi

dir=$(mktemp -d /tmp/strokelab-slurm.XXXXXX)
chmod 0700 "$dir"
pids=()
cleanup() {
  local status=$?
  for pid in "${pids[@]}"; do kill -TERM "$pid" 2> /dev/null || true; done
  for pid in "${pids[@]}"; do
    for _ in $(seq 50); do kill -0 "$pid" 2> /dev/null || break; sleep 0.1; done
    kill -KILL "$pid" 2> /dev/null || true
  done
  if [ "$status" = 0 ]; then rm -rf "$dir"; fi
}
trap cleanup EXIT
trap 'exit 130' INT TERM  # so that cleanup runs when the test is interrupted

free_port() { python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
wait_for() {  # wait_for SECONDS WHAT COMMAND...: until COMMAND succeeds, or fail naming WHAT
  local seconds=$1 what=$2
  local deadline=$((SECONDS + seconds))
  shift 2
  until "$@" > /dev/null 2>&1; do
    [ "$SECONDS" -lt "$deadline" ] || fail "$what (after $seconds s)"
    sleep 0.2
  done
}

# munge: its own key, socket and files under $dir.
mkdir -p "$dir/munge"
chmod 0700 "$dir/munge"
dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
chmod 0400 "$dir/munge/munge.key"
munged --force --key-file="$dir/munge/munge.key" --socket="$dir/munge/socket" --pid-file="$dir/munge/pid" \
  --log-file="$dir/munge/log" --seed-file="$dir/munge/seed" ||
  fail "munged did not start: $(tail -3 "$dir/munge/log" 2> /dev/null)"
wait_for 10 "munged wrote no pid file" test -s "$dir/munge/pid"
pids+=("$(cat "$dir/munge/pid")")
wait_for 10 "munge cannot encode a credential" \
  sh -c "munge -n -S '$dir/munge/socket' | unmunge -S '$dir/munge/socket'"

# Slurm: one node (this machine, all its CPUs), one partition, no accounting.
node=$(hostname -s)
cpus=$(nproc)
memory_mb=$(awk '/MemTotal/ {print int($2 / 1024)}' /proc/meminfo)
mkdir -p "$dir/state" "$dir/spool"
export SLURM_CONF="$dir/slurm.conf"
cat > "$SLURM_CONF" << EOF
ClusterName=strokelab-test
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$(free_port)
SlurmdPort=$(free_port)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$dir/munge/socket
CredType=cred/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SwitchType=switch/none
MpiDefault=none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
MinJobAge=600
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$((memory_mb / 2)) State=UNKNOWN
PartitionName=test Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
slurmctld -f "$SLURM_CONF" -i || fail "slurmctld did not start: $(tail -5 "$dir/slurmctld.log" 2> /dev/null)"
wait_for 20 "slurmctld wrote no pid file" test -s "$dir/slurmctld.pid"
pids+=("$(cat "$dir/slurmctld.pid")")
slurmd -f "$SLURM_CONF" || fail "slurmd did not start: $(tail -5 "$dir/slurmd.log" 2> /dev/null)"
wait_for 20 "slurmd wrote no pid file" test -s "$dir/slurmd.pid"
pids+=("$(cat "$dir/slurmd.pid")")
node_idle() { sinfo -h -N -o '%T' | grep -qx idle; }
wait_for 60 "node $node never became idle" node_idle
echo "slurm up: node $node, $cpus CPUs"

# The server: remote workers only, with tokens.
port=$(free_port)
token=worker-$(od -An -N16 -tx1 /dev/urandom | tr -d ' \n')
submit=submit-$(od -An -N16 -tx1 /dev/urandom | tr -d ' \n')
printf 'worker %s\nsubmit %s\n' "$token" "$submit" > "$dir/tokens"
"$binary" serve --port "$port" --db "$dir/strokelab.db" --workers 0 --token-file "$dir/tokens" \
  2> "$dir/serve.log" &
pids+=($!)
url=http://127.0.0.1:$port
wait_for 20 "the server did not answer" curl -sf "$url/v1/health"
api() { curl -sf -H "Authorization: Bearer $submit" "$@"; }
json_field() { python3 -c "import json, sys; print(json.load(sys.stdin)$1)"; }

# 1. The README's command, unchanged, from the repository root; logs go to $dir.
frequencies=30 amplitudes=3
job=$(api -X POST "$url/v1/jobs" -H 'Content-Type: application/json' -d "{\"kind\": \"sweep\", \"model\": \"paper\",
  \"grid\": {\"frequency_hz\": {\"from\": 5, \"to\": 40, \"points\": $frequencies},
             \"amplitude_v\": {\"from\": 0.1, \"to\": 0.5, \"points\": $amplitudes}}, \"thresholds\": false}" |
  json_field '["id"]')
# From $dir, so that the #SBATCH --output logs land there; the command is the README's.
cd "$dir"
submitted=$(STROKELAB_TOKEN=$token STROKELAB_BINARY=$binary STROKELAB_EXIT_WHEN_IDLE=5 \
  sbatch --array=1-2 "$repo/deploy/slurm/strokelab-workers.sbatch" "$url") || fail "sbatch refused the README's command"
array=${submitted##* }  # "Submitted batch job N"
echo "sweep job $job; array job $array"
job_done() { [ "$(api "$url/v1/jobs/$job" | json_field '["status"]')" = succeeded ]; }
wait_for 300 "job $job did not succeed" job_done
# Distinct grid points among the rows (one row per point and branch), all pages.
points=$(python3 - "$url/v1/jobs/$job/points" "$submit" << 'PY'
import json, sys, urllib.parse, urllib.request
url, token, seen, cursor = sys.argv[1], sys.argv[2], set(), None
while True:
    query = "?limit=1000" + ("&cursor=" + urllib.parse.quote(str(cursor)) if cursor else "")
    request = urllib.request.Request(url + query, headers={"Authorization": "Bearer " + token})
    page = json.load(urllib.request.urlopen(request))
    seen.update((p["frequency_hz"], p["amplitude_v"]) for p in page["points"])
    cursor = page.get("next_cursor")
    if not cursor:
        break
print(len(seen))
PY
)
[ "$points" = $((frequencies * amplitudes)) ] || fail "job $job has $points points, not $((frequencies * amplitudes))"
array_gone() { [ -z "$(squeue -h -j "$array" 2> /dev/null)" ]; }
wait_for 120 "the idle workers did not exit" array_gone
for task in 1 2; do
  state=$(scontrol show job "${array}_$task" | grep -o 'JobState=[A-Z]*')
  [ "$state" = JobState=COMPLETED ] || fail "array task $task ended $state: $(cat "strokelab-worker-${array}_$task.log")"
done
grep -h "tasks completed" strokelab-worker-"$array"_*.log
echo "ok: README's sbatch command ran the sweep ($points points) and the workers exited when idle"

# 2. scancel stops running workers.
submitted=$(STROKELAB_TOKEN=$token STROKELAB_BINARY=$binary STROKELAB_EXIT_WHEN_IDLE=3600 \
  sbatch --array=1-2 "$repo/deploy/slurm/strokelab-workers.sbatch" "$url") || fail "sbatch refused the second array"
array=${submitted##* }
both_running() { [ "$(squeue -h -j "$array" -t RUNNING | wc -l)" = 2 ]; }
wait_for 60 "the second array did not start" both_running
worker_started() { grep -q "^worker " "strokelab-worker-${array}_1.log" "strokelab-worker-${array}_2.log"; }
wait_for 20 "the workers did not start" worker_started
scancel "$array"
wait_for 60 "scancel did not stop the array" array_gone
for task in 1 2; do
  state=$(scontrol show job "${array}_$task" | grep -o 'JobState=[A-Z]*')
  [ "$state" = JobState=CANCELLED ] || fail "array task $task ended $state after scancel"
done
if pgrep -f -- "--name slurm-${array}_" > /dev/null || pgrep -f -- "--name slurm-$array-" > /dev/null; then
  fail "a worker of array $array still runs after scancel"
fi
tail -n 2 strokelab-worker-"$array"_*.log
echo "ok: scancel stopped the workers"
echo "slurm test passed"
