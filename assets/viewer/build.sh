#!/usr/bin/env bash
# Build viewer.bundle.js: src/viewer.js with three.js, tree-shaken and minified by esbuild
# into one IIFE (a classic script: no import, no eval, no network), which the Rust crate
# include_str!s and inlines into view-template.html.
#
#   bash assets/viewer/build.sh
#
# Installs the pinned devDependencies (package-lock.json) with `npm ci` when node_modules is
# missing or stale. Needs node and npm.
set -euo pipefail
cd "$(dirname "$0")"

if [ ! -x node_modules/.bin/esbuild ] || [ ! -d node_modules/three ] \
    || [ package-lock.json -nt node_modules/.package-lock.json ]; then
  npm ci --no-audit --no-fund --loglevel=error
fi

node_modules/.bin/esbuild src/viewer.js \
  --bundle --format=iife --platform=browser --target=es2020,chrome100,firefox100,safari15 \
  --minify --tree-shaking=true --charset=ascii --legal-comments=eof \
  --define:process.env.NODE_ENV='"production"' \
  --log-level=warning --outfile=viewer.bundle.js

# The bundle goes inside <script>...</script> of an HTML page: it must not end the element
# early or switch the tokenizer into its escaped states, and must stay self-contained.
if grep -q -i -E '</script|<!--|<script' viewer.bundle.js; then
  echo "build.sh: viewer.bundle.js contains </script, <script or <!--, which breaks inlining" >&2
  exit 1
fi
if grep -q -E '(^|[^A-Za-z0-9_$.])(import|export)[[:space:]]*[{*("'"'"']' viewer.bundle.js; then
  echo "build.sh: viewer.bundle.js still has an import or export" >&2
  exit 1
fi
if grep -q -E 'https?://[A-Za-z0-9.-]+\.(com|org|net|io)/[^ "]*\.(js|wasm|glb|png|jpg|woff2?)' viewer.bundle.js; then
  echo "build.sh: note: the bundle names a URL of a resource (not loaded by the viewer):" >&2
  grep -o -E 'https?://[A-Za-z0-9.-]+\.(com|org|net|io)/[^ "]*\.(js|wasm|glb|png|jpg|woff2?)' viewer.bundle.js | sort -u | head -5 >&2
fi
echo "viewer.bundle.js: $(wc -c < viewer.bundle.js) bytes"
