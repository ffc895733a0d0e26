#!/usr/bin/env bash
# ergohand's elastic tet solve against a Bullet (pybullet) Neo-Hookean soft body on the
# same mesh, for one simulated subject, at each stuffing spacing in $SPACINGS (mm; default
# "6 4.5"). The default 3 mm mesh (157k tetrahedra) is exported too, for ergohand's own figures,
# but pybullet 3.2.7 cannot load it (its loadSoftBody overflows an 8 MB buffer above ~55k
# tetrahedra). Installs pybullet and numpy with pip if missing (pybullet is ~100 MB, so this is
# not part of CI). Figures go to $WORK/compare-SPACING.json and stdout;
# reports/softbody-comparison.md discusses them.
# Usage: validation/tools/softbody_compare.sh [extra options for softbody_compare.py]
set -euo pipefail
cd "$(dirname "$0")/../.."
target=${CARGO_TARGET_DIR:-target}
work=${WORK:-$target/softbody-compare}
spacings=${SPACINGS:-6 4.5}
python3 -c "import pybullet, numpy" 2>/dev/null || python3 -m pip install --quiet pybullet numpy
cargo build --release --quiet --bin ergohand --example tet_softbody_export
bin=$target/release/ergohand
mkdir -p "$work"
if [ ! -f "$work/subject/subject.toml" ]; then
  $bin --quiet synth --seed 1 --out "$work/subject" --duration 3 --force
fi
if [ ! -f "$work/recon/skin.obj" ]; then
  $bin --quiet reconstruct "$work/subject" --out "$work/recon"
fi
echo "== stuffing spacing 3 mm (ergohand only)"
"$target/release/examples/tet_softbody_export" "$work/recon" "$work/export-3" --spacing 3
for h in $spacings; do
  echo "== stuffing spacing $h mm"
  "$target/release/examples/tet_softbody_export" "$work/recon" "$work/export-$h" --spacing "$h"
  python3 validation/tools/softbody_compare.py "$work/export-$h" --out "$work/compare-$h.json" "$@"
done
