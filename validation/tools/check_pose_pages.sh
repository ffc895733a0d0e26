#!/usr/bin/env bash
# Check that the joint sliders of `ergohand pose`'s view page show the toolkit's own geometry:
# pose a reconstructed hand with the angles kept and plain dual-quaternion skinning (the
# geometry the sliders show) in a few poses (two built-ins and seeded random angles within
# every joint's limits), then open each page in headless Chromium (check_view.sh --agree-obj):
# the page re-skins the hand at the pose's angles with its own port of the forward kinematics
# and the skinning, and every vertex must be within 0.01 mm of the OBJ `pose` wrote.
#
#   bash validation/tools/check_pose_pages.sh ERGOHAND_BINARY MODEL_DIR [WORK_DIR] [RANDOM_POSES]
#
# WORK_DIR (default: a temporary folder) receives the poses, OBJs and pages. RANDOM_POSES
# defaults to 3; seeds are 1..RANDOM_POSES, so a run is repeatable.
set -euo pipefail
if [ "$#" -lt 2 ]; then
  echo "usage: $0 ERGOHAND_BINARY MODEL_DIR [WORK_DIR] [RANDOM_POSES]" >&2
  exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
bin=$1
model=$2
work=${3:-$(mktemp -d)}
n=${4:-3}
mkdir -p "$work"

pose() { "$bin" --quiet pose "$model" --pose "$1" --keep-angles --plain-skinning --out "$work/$2.obj"; }
pose open open
pose fist fist
# Random angles within the limits the page itself lists (its data), one pose file per seed.
for seed in $(seq 1 "$n"); do
  python3 - "$work/open.view.html" "$seed" > "$work/random$seed.toml" <<'EOF'
import json, random, re, sys
html = open(sys.argv[1], encoding="utf-8").read()
data = json.loads(re.search(r'<script id="ergohand-view-data" type="application/json">(.*?)</script>', html, re.S).group(1))
rng = random.Random(int(sys.argv[2]))
for j in data["rig"]["joints"]:
    # a margin of 1 degree inside each limit, so that clamping changes nothing
    a = [round(rng.uniform(lo + 1, hi - 1), 3) if hi - lo > 2 else 0.0 for lo, hi in j["limits_deg"]]
    print(f'{j["name"]} = {a[0] if len(a) == 1 else a}')
EOF
  pose "$work/random$seed.toml" "random$seed"
done
pages=("$work/open.view.html" "$work/fist.view.html")
for seed in $(seq 1 "$n"); do pages+=("$work/random$seed.view.html"); done
bash "$here/check_view.sh" --agree-obj "${pages[@]}"
