#!/usr/bin/env bash
# Open 3-D view pages written by ergohand (view.html: three.js, the GLBs inlined) in headless
# Chromium and fail as a reader's browser would show them broken. Each page is opened from a
# copy alone in an empty temporary folder with the network off, and fails on any console error
# or uncaught exception, any request for something outside the page, the page not reporting
# ready (window.ergohandView.ready) within 30 s, or a blank canvas (too few pixels that differ
# from the background, counted from the canvas itself). check_view.mjs beside this script does
# the work with playwright-core driving the system's Chromium.
#
#   bash validation/tools/check_view.sh [--screenshot DIR] [--agree-obj] PAGE.html [MORE.html ...]
#
# (--agree-obj: see check_view.mjs; check_pose_pages.sh uses it)
#
# WebGL without a GPU: Chromium renders WebGL on ANGLE's SwiftShader backend (a CPU Vulkan
# that ships with Chromium) when started with
#   --use-angle=swiftshader --enable-unsafe-swiftshader
# (the second flag is required since Chromium 13x, which deprecated the silent fallback to
# software WebGL). Do not pass --disable-gpu on its own: it leaves WebGL to that deprecated
# fallback. The other flags are those of check_report.sh: --headless --no-sandbox
# --disable-background-networking --disable-component-update --disable-sync --no-first-run
# --host-resolver-rules="MAP * ~NOTFOUND" (plus Playwright's offline mode).
#
# Installs Chromium (apt-get) and, when missing, node and npm (apt-get), then playwright-core
# from the npm registry into target/view-check (or VIEW_CHECK_DIR), the way .ci/gltf-validate.sh
# installs the glTF validator. No browser is downloaded: Playwright drives the apt Chromium.
# Exit status: 0 every page passes; 1 a page failed; 2 usage or set-up error.
set -euo pipefail

if [ "$#" -lt 1 ]; then
  echo "usage: $0 [--screenshot DIR] [--agree-obj] PAGE.html [MORE.html ...]" >&2
  exit 2
fi

here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
PLAYWRIGHT_VERSION=1.65.1

CHECK_NAME=check_view
# shellcheck source=chromium.sh
. "$here/chromium.sh"
need_chromium
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  echo "check_view: installing node and npm (apt-get)" >&2
  apt_install nodejs npm
  command -v node >/dev/null 2>&1 && command -v npm >/dev/null 2>&1 \
    || { echo "check_view: node/npm could not be installed" >&2; exit 2; }
fi

tool=${VIEW_CHECK_DIR:-$root/target/view-check}
if [ ! -f "$tool/node_modules/playwright-core/package.json" ] \
    || ! grep -q "\"version\": \"$PLAYWRIGHT_VERSION\"" "$tool/node_modules/playwright-core/package.json"; then
  mkdir -p "$tool"
  (cd "$tool" && { [ -f package.json ] || npm init -y >/dev/null; } \
    && npm install --silent --no-audit --no-fund "playwright-core@$PLAYWRIGHT_VERSION" >/dev/null) \
    || { echo "check_view: npm install playwright-core failed" >&2; exit 2; }
fi

CHROMIUM="$CHROMIUM" VIEW_CHECK_DIR="$tool" node "$here/check_view.mjs" "$@"
