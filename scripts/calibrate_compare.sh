#!/usr/bin/env bash
# Our stereo calibration beside OpenCV's (scripts/calibrate_opencv.py) on rendered board images:
# writes the default cell with lens distortion, renders a 9x6@25 board in 15 poses (plus the
# table view) per seed, and scores both calibrations against the true rig.json.
# Usage: scripts/calibrate_compare.sh [OUT] [SEED...]   (default out/calibrate-compare, seeds 3 4 5)
# Needs a venv with scripts/requirements-peers.txt (PYTHON overrides .peers/bin/python) and a
# built camplace (BIN overrides target/debug/camplace; it is not built here).
set -euo pipefail
out=${1:-out/calibrate-compare}
shift || true
seeds=${*:-3 4 5}
py=${PYTHON:-.peers/bin/python}
bin=${BIN:-target/debug/camplace}
script=$(cd "$(dirname "$0")" && pwd)/calibrate_opencv.py
[ -x "$bin" ] || { echo "no camplace binary at $bin" >&2; exit 1; }
mkdir -p "$out"
$bin init "$out/cell.toml" >/dev/null
sed -i '/^camera_k = \[\]$/a camera_dist = [-0.1, 0.05, 0.0005, -0.0003, 0.0]' "$out/cell.toml"
for seed in $seeds; do
  dir=$out/boards$seed
  rm -rf "$dir"
  $bin render --cell "$out/cell.toml" --board 9x6@25 --views 15 --seed "$seed" --out "$dir" >/dev/null
  echo "== seed $seed"
  $py "$script" "$dir" --board 9x6@25 --camplace "$bin" --ours "$dir/ours.json" --per-camera
done
