#!/usr/bin/env bash
# Makes the screenshots the READMEs show, from a fresh server and the paper model's Eq. 1 x 26 sweep
# (the demo's), in headless Chromium:
#   docs/web-page.png    the web page with the sweep, the mouse on an FRF point and its readout
#   docs/frf-family.png  the server's SVG FRF family of the up-sweep (as `strokelab sweep` writes frf_up.svg)
#
#   docs/make_screenshots.sh [BINARY]        (default: build/release/strokelab)
#
# It is the web page test (tests/web/web_page_test.sh) run on the full grid, with its checks.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-build/release/strokelab}
WEB_TEST_FULL=1 WEB_TEST_SCREENSHOT="$PWD/docs/web-page.png" WEB_TEST_FRF_SCREENSHOT="$PWD/docs/frf-family.png" \
  tests/web/web_page_test.sh "$bin" "$PWD"
