#!/usr/bin/env bash
# Validate every .glb under DIR with the Khronos glTF validator (npm package gltf-validator).
# Skips (exit 0, with a note) when node/npm are not installed; fails on any validator error.
set -euo pipefail
dir=${1:?usage: gltf-validate.sh DIR}
mapfile -t files < <(find "$dir" -name '*.glb' | sort)
if [ ${#files[@]} -eq 0 ]; then echo "no GLB under $dir yet"; exit 0; fi
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
  echo "node/npm not installed: glTF validation skipped"; exit 0
fi
tool=${GLTF_VALIDATOR_DIR:-target/gltf-validator}
if [ ! -d "$tool/node_modules/gltf-validator" ]; then
  mkdir -p "$tool"
  (cd "$tool" && npm init -y >/dev/null && npm install --silent --no-audit --no-fund gltf-validator@2.0.0-dev.3.10 >/dev/null)
fi
GLTF_VALIDATOR_DIR="$tool" node validation/tools/gltf_validate.mjs "${files[@]}"
