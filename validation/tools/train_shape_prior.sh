#!/bin/bash
# Re-train the shape prior shipped with the generic template
# (assets/generic-hand/shape-prior.json) from a simulated population that shares no seed with
# the validation suite (validation/suite.toml) or the tuning subjects (seeds 401-412):
# seeds 1001-1060, odd seeds the procedural body and even seeds the template body, both hands,
# every third seed in a varied posture, every fifth with the clean capture model, 20 s trials.
#
#   validation/tools/train_shape_prior.sh WORK_DIR [ERGOHAND_BINARY]
#
# Each subject is reconstructed without a prior (`--shape-prior none`) into SUBJECT/out0;
# a subject the toolkit refuses is left out (and named). Takes about 10 minutes on 2 cores.
set -u
work=${1:?usage: train_shape_prior.sh WORK_DIR [ERGOHAND_BINARY]}
bin=${2:-target/release/ergohand}
mkdir -p "$work"
dirs=()
for s in $(seq 1001 1060); do
  if [ $((s % 2)) -eq 1 ]; then body=procedural; else body=template; fi
  if [ $(((s / 2) % 2)) -eq 1 ]; then hand=left; else hand=right; fi
  if [ $((s % 3)) -eq 0 ]; then posture=varied; else posture=template; fi
  preset=typical; [ $((s % 5)) -eq 0 ] && preset=clean
  d="$work/p$s"
  if [ ! -f "$d/out0/skin.obj" ]; then
    "$bin" -q synth --seed $s --out "$d" --body $body --hand $hand --posture $posture \
      --preset $preset --duration 20 --force || { echo "left out: seed $s (synth)"; continue; }
    "$bin" -q reconstruct "$d" --out "$d/out0" --shape-prior none \
      || { echo "left out: seed $s (reconstruct)"; continue; }
  fi
  dirs+=("$d")
done
"$bin" shape-prior "${dirs[@]}" --model out0 --out "$work/shape-prior.json"
