#!/usr/bin/env bash
# One-machine set-up: installs what is missing (Debian packages), builds, then runs or tests.
#   deploy/local.sh run    build and run the main job: the service with a demo sweep
#   deploy/local.sh demo   build and write the demo sweep and the paper's figures as files
#   deploy/local.sh test   build and run every test (what .ci/run calls)
#   deploy/local.sh build  build only
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(build-essential cmake ccache pkg-config libeigen3-dev libsundials-dev libceres-dev nlohmann-json3-dev
          libcpp-httplib-dev libsqlite3-dev libgtest-dev libgmock-dev libbenchmark-dev python3-scipy python3-numpy chromium)

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
}

BUILD_DIR=${STROKELAB_BUILD_DIR:-build/release}
build() {
  export CCACHE_DIR=${CCACHE_DIR:-$HOME/.cache/strokelab-ccache}
  cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$BUILD_DIR" -j "$(nproc)"
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
    build
    ctest --test-dir "$BUILD_DIR" --output-on-failure -j "$(nproc)"
    ;;
  build)
    install_missing
    build
    ;;
  *)
    echo "usage: deploy/local.sh run|demo|test|build" >&2
    exit 2
    ;;
esac
