#!/usr/bin/env bash
# Builds the strokelab image from deploy/Dockerfile, tagged with the project's version (the VERSION
# in `project(strokelab VERSION ...)` of the top CMakeLists.txt): strokelab:VERSION.
#
#   deploy/docker-build.sh [docker build options...]     e.g. --build-arg STROKELAB_MARCH=x86-64
#
# Pulls nothing when the base images (debian:12, debian:12-slim) are already local (--pull=false);
# the build still installs Debian packages with apt-get inside the image.
set -euo pipefail
cd "$(dirname "$0")/.."
version=$(sed -n 's/^project(strokelab VERSION \([0-9.]*\).*/\1/p' CMakeLists.txt)
[ -n "$version" ] || { echo "docker-build.sh: no 'project(strokelab VERSION X.Y.Z' in CMakeLists.txt" >&2; exit 1; }
echo "building strokelab:$version"
exec docker build --pull=false -f deploy/Dockerfile -t "strokelab:$version" "$@" .
