#!/usr/bin/env bash
# The README's picture of the study report's 3D view: the view of report.html alone at the
# top of a headless Chromium window, saved as a PNG.
# Usage: scripts/screenshot_report.sh [REPORT_HTML] [OUT_PNG]
#   defaults: out/study/report.html (camplace study --quick --out out/study writes one)
#   and docs/report-3d-view.png
set -euo pipefail
report=${1:-out/study/report.html}
out=${2:-docs/report-3d-view.png}
browser=$(command -v chromium || command -v chromium-browser) || {
    echo "no chromium on PATH (apt-get install chromium)" >&2
    exit 2
}
[ -f "$report" ] || {
    echo "$report: no such report; camplace study --quick --out out/study writes one" >&2
    exit 2
}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# A style after the page moves the view to the window's top left; the page is otherwise as written.
{
    cat "$report"
    echo '<style>body{margin:0}#view3d{position:fixed;top:0;left:0;z-index:9;background:#fff;padding:8px;width:1184px}</style>'
} >"$tmp/page.html"
"$browser" --headless --no-sandbox --disable-gpu --hide-scrollbars --window-size=1200,580 \
    --virtual-time-budget=5000 --screenshot="$tmp/shot.png" "file://$tmp/page.html" 2>/dev/null
cp "$tmp/shot.png" "$out"
echo "wrote $out"
