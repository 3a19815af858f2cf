#!/usr/bin/env bash
# Side by side with OpenCV's SGBM (scripts/peers_stereo.py) on the same rectified,
# rendered pairs: renders N scenes at a placement, reconstructs them, then scores both
# matchers against disparity_truth.pfm with the same disparity range and thread count.
# Usage: scripts/peers-stereo.sh PLACEMENT N OUT   (needs `python3 -m venv .peers` with
# scripts/requirements-peers.txt installed; PYTHON overrides the interpreter)
set -euo pipefail
placement=${1:-r=605,alpha=32,baseline=81,vergence=3.5}
n=${2:-5}
out=${3:-out/peers-stereo}
py=${PYTHON:-.peers/bin/python}
scripts=$(cd "$(dirname "$0")" && pwd)
bin=target/release/camplace
cargo build --release -q
rm -rf "$out"
$bin render --dataset --count "$n" --placement "$placement" --out "$out" >/dev/null
$bin reconstruct --dataset "$out" >/dev/null
read -r f b < <($py -c "import json,sys; r=json.load(open('$out/rig.json'))['rectified']; print(r['K'][0][0], r['baseline'])")
for dir in "$out"/frames/*; do
  read -r lo hi < <($py - "$dir" "$scripts" <<'PY'
import sys, math, numpy as np
sys.path.insert(0, sys.argv[2])
from peers_stereo import read_pfm
t = read_pfm(sys.argv[1] + "/disparity_truth.pfm"); v = t[np.isfinite(t)]
print(max(0, math.floor(v.min()) - 4), math.ceil(v.max()) + 4)
PY
)
  ours=$($bin reconstruct --rectified --left "$dir/rectified_left.png" --right "$dir/rectified_right.png" \
    --focal-px "$f" --baseline-mm "$b" --disparity-range "$lo:$hi" --runs 20 --out "$dir/ours-rectified")
  ms=$(echo "$ours" | sed -E 's/.*median ([0-9.]+) ms.*/\1/')
  echo "== $(basename "$dir") (disparity $lo..$hi)"
  $py "$scripts/peers_stereo.py" --left "$dir/rectified_left.png" --right "$dir/rectified_right.png" \
    --truth "$dir/disparity_truth.pfm" --min-disp "$lo" --max-disp "$hi" --threads 2 --runs 20 \
    --ours "$dir/ours-rectified/disparity.pfm" --ours-ms "$ms"
done
