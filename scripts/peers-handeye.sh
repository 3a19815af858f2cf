#!/usr/bin/env bash
# Our hand-eye calibration beside OpenCV's (scripts/peers-handeye.py) on rendered images and
# robot poses, both setups, five seeds.
# Usage: scripts/peers-handeye.sh [OUT]   (default out/peers-handeye)
# Sets up a venv from scripts/requirements-handeye.txt at $VENV (default .peers-handeye)
# when it is missing, and builds camplace in release.
set -euo pipefail
out=${1:-out/peers-handeye}
venv=${VENV:-.peers-handeye}
here=$(cd "$(dirname "$0")" && pwd)
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q -r "$here/requirements-handeye.txt"
fi
cargo build --release -q </dev/null
"$venv/bin/python" "$here/peers-handeye.py" --camplace target/release/camplace --out "$out"
