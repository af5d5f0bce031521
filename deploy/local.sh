#!/usr/bin/env bash
# One-machine set-up: installs what is missing (Debian packages), builds, then runs or tests.
#   deploy/local.sh run    build and run the main job: the service with a demo sweep
#   deploy/local.sh demo   build and write the demo sweep and the paper's figures as files
#   deploy/local.sh test   build and run the tests (what .ci/run calls): the Release build and its
#                          tests, the Slurm array on a real single-node Slurm (tests/slurm/run.sh),
#                          then ASan+UBSan on the service, campaign files and fuzz harnesses
#   deploy/local.sh test-release    the Release build and its tests only (the quick loop)
#   deploy/local.sh test-asan       the ASan+UBSan stage of test alone (its own build directory)
#   deploy/local.sh test-slow       the Release build and the tests labelled "slow" (long diagnosis cases)
#   deploy/local.sh test-slurm      the Release build, then the Slurm array of deploy/slurm/ on a real
#                                   single-node Slurm started here (root; tests/slurm/run.sh) alone
#   deploy/local.sh build  build only
#   deploy/local.sh sanitize        both whole sanitizer stages (every ASan test, TSan; ~28 min)
#   deploy/local.sh fuzz [SECONDS]  build the libFuzzer harnesses and run each for SECONDS (default 600)
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(build-essential cmake ninja-build ccache pkg-config libeigen3-dev libsundials-dev libceres-dev nlohmann-json3-dev
          libcpp-httplib-dev libsqlite3-dev libgtest-dev libgmock-dev libbenchmark-dev python3-scipy python3-numpy chromium
          clang libclang-rt-14-dev util-linux tar zlib1g-dev python3-yaml docker-compose slurm-wlm munge)
# clang (+ clang-rt, libFuzzer): the sanitizer and fuzzing builds; util-linux (prlimit) and tar: the
# full-disk and tar-upload tests (both Essential in Debian, listed so the dependency is written down);
# zlib: deflated members of zip campaign uploads. python3-yaml and docker-compose (1.29): the deploy
# files' checks (tests/deploy; `docker-compose config` on deploy/compose.yaml). slurm-wlm and munge:
# the Slurm array test (tests/slurm/run.sh starts its own single-node cluster in a temporary directory).

install_missing() {
  local missing=()
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    echo "installing: ${missing[*]}"
    local sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}"
  fi
  install_web_library
}

# The web page's plotting library (uPlot, pinned with its hash by clients/web/package-lock.json),
# which the build compiles into the server: npm ci into clients/web/node_modules when it is missing
# or holds another version. npm is Debian's package `npm`, installed only when no npm is on PATH (a
# Node.js from elsewhere brings its own, and Debian's would conflict with it). The configure step
# runs the same npm ci if this was skipped (server/cmake/embed_web_library.cmake).
install_web_library() {
  local lock=clients/web/package-lock.json installed=clients/web/node_modules/uplot/package.json
  local pinned have=""
  pinned=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["packages"]["node_modules/uplot"]["version"])' "$lock")
  [ -f "$installed" ] && have=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["version"])' "$installed")
  [ "$have" = "$pinned" ] && return 0
  if ! command -v npm >/dev/null; then
    local sudo=""
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq npm
  fi
  echo "installing the web page's library: uPlot $pinned (npm ci in clients/web)"
  (cd clients/web && npm ci --ignore-scripts --no-audit --no-fund)
}

BUILD_DIR=${STROKELAB_BUILD_DIR:-build/release}

# ctest runs one test more than there are cores: many tests wait as much as they compute (killed
# and restarted processes, expiring leases, a faulty proxy), and the extra one fills the idle core
# time. On 2 cores, against -j 2: Release tests 89.7 -> 77.8 s, ASan tests 180 -> 159 s, TSan fault
# tests 34.5 -> 23.4 s (TSan server tests 59 -> 61 s: they already keep both cores busy).
TEST_JOBS=$(( $(nproc) + 1 ))

# Every build directory uses Ninja: it compiles a library's sources without waiting for the
# libraries it links to be built (Make builds target after target), so both cores stay busy: the
# TSan build took 107 s against 130 s with Make, from an empty compiler cache. A directory that was
# configured for another generator is configured anew (cmake refuses to switch).
configure() {  # DIR CMAKE_ARGS...
  local dir=$1
  shift
  export CCACHE_DIR=${CCACHE_DIR:-$HOME/.cache/strokelab-ccache}
  if [ -f "$dir/CMakeCache.txt" ] && ! grep -q '^CMAKE_GENERATOR:INTERNAL=Ninja$' "$dir/CMakeCache.txt"; then
    echo "$dir was configured for another generator: configuring it anew for Ninja"
    rm -rf "$dir"
  fi
  cmake -S . -B "$dir" -G Ninja "$@" >/dev/null
}

build() {
  configure "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release
  cmake --build "$BUILD_DIR" -j "$(nproc)"
}

# Sanitizer and fuzzing builds (tests/README.md, "Sanitizers and fuzzing"): clang, each in a build
# directory of its own. -O2 keeps the tests' run time near Release; line tables make the reports'
# stacks readable; NDEBUG is left out so that assertions (ours, Eigen's) are checked too.
configure_clang() {  # DIR CMAKE_ARGS...
  local dir=$1
  shift
  configure "$dir" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -gline-tables-only" -DSTROKELAB_BUILD_BENCHMARKS=OFF "$@"
}

# A sanitizer report fails the test that caused it: ASan and TSan stop at the first report, UBSan
# aborts (-fno-sanitize-recover), LeakSanitizer fails the process at exit.
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:detect_stack_use_after_return=1:strict_string_checks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1}
# tests/sanitizers/tsan.supp: the uninstrumented cpp-httplib library's function-local statics.
TSAN_SUPPRESSIONS=$PWD/tests/sanitizers/tsan.supp
export TSAN_OPTIONS=${TSAN_OPTIONS:-halt_on_error=1:second_deadlock_stack=1:suppressions=$TSAN_SUPPRESSIONS}

# ASan + UBSan, with libFuzzer's coverage instrumentation so that the same build holds the fuzz
# harnesses (one clang build instead of two; the instrumentation costs the tests little): every test
# but these. Library/DiagnoseTest.*, Library/BroadbandDiagnoseTest.* (a whole diagnosis, 25-70 s in
# Release; the broadband one's parts run in BroadbandDiagnoseTest.* and DiagnoseCli.*), OpenWorldTest.*
# (the open-world code runs in UnexplainedTest), ExtendedFitTest.* and fit_zscore_study_few (four campaigns of
# the z-score study) run 10-40 s each in Release (minutes here); web_page and web_status_badge drive Chromium, whose
# own code the sanitizers do not see and whose page the server_process and python_client tests
# already serve; of the seven ForceCampaign tests one runs:
# each process synthesises and fits the same campaign (~30 s here) before checking another figure.
# DiagnoseStartsTest.* diagnoses a 44.1 kHz campaign whose selection runs twice (~12 s in Release),
# as Library/DiagnoseTest does one campaign per effect. DiagnosedModel*Test.* run a whole diagnosis
# through the binary (12 and ~20 s in Release); the
# report and map code they reach runs in DiagnoseReportMapsTest and SweepDiagnosisMapsTest.
# readme_commands runs the README's commands, a diagnosis among them (~20 s in Release), and
# CeresLogTest.ADiagnosisPrintsOnlyItsProgress a small diagnosis (~6 s); the code they reach runs
# in the CLI and server tests. MixedCampaign.FitsJointlyToTheParametersOfEachHalf and
# BroadbandCampaignFit.ANominalSensitivityIsReportedAsTheSteppedFitReportsIt fit campaigns with impacts
# (3-7 s in Release) whose fits run past their 120 s budget here and end unconverged; the joint fit
# runs in MixedFitCli, the broadband campaign fit in BroadbandCampaignFit's other tests.
# Then each harness's corpus is replayed (ctest) and each harness fuzzed for FUZZ_SECONDS.
ASAN_DIR=build/asan
ASAN_EXCLUDE='^(web_page|web_page_diagnosis|web_status_badge|readme_commands|CeresLogTest\.ADiagnosisPrintsOnlyItsProgress|Library/DiagnoseTest\..*|DiagnoseStartsTest\..*|Library/BroadbandDiagnoseTest\..*|OpenWorldTest\..*|ExtendedFitTest\..*|fit_zscore_study_few|paper_fit_zscore_study_few|ForceCampaign\.[^J].*|DiagnosedModel(Cli|Slow)Test\..*|MixedCampaign\.FitsJointlyToTheParametersOfEachHalf|BroadbandCampaignFit\.ANominalSensitivityIsReportedAsTheSteppedFitReportsIt)$'
asan_build() {
  configure_clang "$ASAN_DIR" -DSTROKELAB_SANITIZE=address,undefined -DSTROKELAB_FUZZ=ON
  cmake --build "$ASAN_DIR" -j "$(nproc)"
}
asan_stage() {  # FUZZ_SECONDS
  asan_build
  ctest --test-dir "$ASAN_DIR" --output-on-failure -j "$TEST_JOBS" -LE slow -E "$ASAN_EXCLUDE"
  STROKELAB_FUZZ_DIR="$ASAN_DIR" tests/fuzz/run_fuzzers.sh "$1"
}

# The test command's sanitizer stage. Three cold builds and every test under both sanitizers took
# 35.5 min on 2 cores (a clean clone, 2026-11-26: Release build 225 s and tests 254 s, ASan 1030 s,
# TSan 617 s) against the test command's 20 minutes. So the test command builds ASan+UBSan for the
# code that takes outside input only: the service (tests/server), campaign files (tests/recordings)
# and the fuzz harnesses, whose corpora are replayed and fuzzed. Left out there: the tests that fit
# or diagnose whole campaigns through the service or a worker process (30-100 s each under ASan;
# UploadedCampaignFitsAsTheDirectFit and BroadbandAndMixedCampaignsAreFitted stay as the ones that do;
# the broadband diagnosis, 85 s here, runs under ASan in DiagnoseCli), the backup of a running service
# and the kill-and-resume runs (sweeps under ASan, 40-60 s each). `deploy/local.sh sanitize` runs
# both whole sanitizer stages; it is run before each stop and its result is in the closing note.
# From a clean clone with ccache off the whole test command took 17 min 19 s at 5c0af4d (Release
# build 238 s, its tests 293 s, the Slurm array 13 s, this stage 492 s).
ASAN_CI_DIRS=(tests/server tests/recordings tests/fuzz)
ASAN_CI_EXCLUDE='^(CampaignJobsTest\.(ZipUploadFitsAsTheTarUpload|BroadbandCampaignsAreDiagnosedByTheirTimeSeries|AFitSurvivesARestartAndCanBeCancelled|CampaignAtTheArchiveTopAndUnderTheDataRoot|WithoutInProcessWorkersARemoteWorkerRunsTheFit|AFitThatDidNotConvergeSucceedsWithAWarning|DiagnoseJobHasAResultAndAnHtmlReport|AFitsModelFileIsADownload|CancelledDiagnosesDoNotRunBeyondTheWorkerCount)|RemoteCampaignProcess\..*|Backup\.SnapshotsOfARunningServiceAreWholeAndConsistent|ServiceProcess\.(CrashAndResume|RemoteWorkerKilledMidLease))$'
asan_ci_stage() {  # FUZZ_SECONDS
  configure_clang "$ASAN_DIR" -DSTROKELAB_SANITIZE=address,undefined -DSTROKELAB_FUZZ=ON
  build_test_dirs "$ASAN_DIR" "${ASAN_CI_DIRS[@]}"
  test_dirs "$ASAN_DIR" "$ASAN_CI_EXCLUDE" "${ASAN_CI_DIRS[@]}"
  STROKELAB_FUZZ_DIR="$ASAN_DIR" tests/fuzz/run_fuzzers.sh "$1"
}

# Builds only the tests of the given folders (Ninja's DIR/all) and what they need.
build_test_dirs() {  # BUILD_DIR TEST_DIR...
  local build_dir=$1 dir targets=()
  shift
  for dir in "$@"; do targets+=("$dir/all"); done
  cmake --build "$build_dir" -j "$(nproc)" --target "${targets[@]}"
}
# Runs the tests of the given folders but those labelled slow and those matching EXCLUDE.
test_dirs() {  # BUILD_DIR EXCLUDE_REGEX TEST_DIR...
  local build_dir=$1 exclude=$2 dir
  shift 2
  for dir in "$@"; do
    ctest --test-dir "$build_dir/$dir" --output-on-failure -j "$TEST_JOBS" -LE slow ${exclude:+-E "$exclude"}
  done
}

# TSan: the tests of the threaded parts, the job store's task queue, the service with its workers
# and HTTP threads, remote workers, faults (tests/server, tests/fault). Only their targets (Ninja's
# DIR/all) and what those need are built.
TSAN_TEST_DIRS=(tests/server tests/fault)
tsan_stage() {
  configure_clang build/tsan -DSTROKELAB_SANITIZE=thread
  build_test_dirs build/tsan "${TSAN_TEST_DIRS[@]}"
  test_dirs build/tsan "" "${TSAN_TEST_DIRS[@]}"
}

# Seconds each libFuzzer harness runs in `test` and `sanitize` (a smoke run; `fuzz` runs longer).
CI_FUZZ_SECONDS=15

# Runs NAME's command and keeps its wall time for the summary printed at the end.
STAGE_TIMES=()
stage() {  # NAME COMMAND...
  local name=$1 start=$SECONDS
  shift
  echo "== $name"
  "$@"
  STAGE_TIMES+=("$name $((SECONDS - start)) s")
}

# The stages `test` runs: the Release build and its tests, then the sanitizer builds and theirs.
# Tests labelled "slow" (long cases; tests/README.md) are left to `test-slow`.
release_stages() {
  stage "release build" build
  stage "release tests" ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$TEST_JOBS" -LE slow
}
sanitizer_stages() {
  stage "asan+ubsan build, tests, fuzz corpora and ${CI_FUZZ_SECONDS} s per harness" asan_stage "$CI_FUZZ_SECONDS"
  stage "tsan build and tests" tsan_stage
}
ci_sanitizer_stage() {
  stage "asan+ubsan on the service, campaign files and fuzz harnesses (${CI_FUZZ_SECONDS} s each)" asan_ci_stage "$CI_FUZZ_SECONDS"
}

case "${1:-}" in
  run)
    # The service on its embedded SQLite file with one worker per core; once it is up it submits
    # a demo sweep of the paper's model and prints the URL of its saturation map. Ctrl-C stops it.
    install_missing
    build
    mkdir -p var
    exec "$BUILD_DIR/strokelab" serve --db var/strokelab.db --port "${STROKELAB_PORT:-8080}" --demo
    ;;
  demo)
    # The same studies offline, as files: a sweep folder and the paper's figures under var/.
    install_missing
    build
    exec deploy/demo.sh "$BUILD_DIR/strokelab"
    ;;
  test)
    install_missing
    release_stages
    stage "slurm array" tests/slurm/run.sh "$BUILD_DIR/strokelab"
    ci_sanitizer_stage
    printf '%s\n' "stage times:" "${STAGE_TIMES[@]}"
    ;;
  test-release)
    install_missing
    release_stages
    printf '%s\n' "stage times:" "${STAGE_TIMES[@]}"
    ;;
  test-asan)
    install_missing
    ci_sanitizer_stage
    printf '%s\n' "stage times:" "${STAGE_TIMES[@]}"
    ;;
  test-slow)
    install_missing
    stage "release build" build
    stage "slow release tests" ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$TEST_JOBS" -L slow
    printf '%s\n' "stage times:" "${STAGE_TIMES[@]}"
    ;;
  test-slurm)
    install_missing
    stage "release build" build
    stage "slurm array" tests/slurm/run.sh "$BUILD_DIR/strokelab"
    printf '%s\n' "stage times:" "${STAGE_TIMES[@]}"
    ;;
  sanitize)
    install_missing
    sanitizer_stages
    printf '%s\n' "stage times:" "${STAGE_TIMES[@]}"
    ;;
  fuzz)
    install_missing
    asan_build
    STROKELAB_FUZZ_DIR="$ASAN_DIR" tests/fuzz/run_fuzzers.sh "${2:-600}"
    ;;
  build)
    install_missing
    build
    ;;
  *)
    echo "usage: deploy/local.sh run|demo|test|test-release|test-asan|test-slow|test-slurm|build|sanitize|fuzz [SECONDS]" >&2
    exit 2
    ;;
esac
