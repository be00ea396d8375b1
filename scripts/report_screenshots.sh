#!/usr/bin/env bash
# Regenerates docs/images/report-<log>.png: `traverse run` on every bundled log, then headless
# Chromium screenshots the top of each report.html (metrics, top view, elevation, position
# error). Needs chromium (scripts/setup.sh) and, to shrink the PNGs to 256 colours,
# python3-pil (docs only; without it the full-colour PNGs are kept).
set -euo pipefail
cd "$(dirname "$0")/.."
exe=build/release/traverse
out=out/report-screenshots
mkdir -p "$out" docs/images
for log in straight-1m multi-stop wvu-pathfinder-s5t1 wvu-pathfinder-test17run; do
  "$exe" run --quiet "datasets/logs/$log" -o "$out/$log" 2>/dev/null
  png="docs/images/report-$log.png"
  chromium --headless --no-sandbox --disable-gpu --no-first-run --disable-background-networking \
    --hide-scrollbars --user-data-dir="$out/profile" --window-size=1000,2600 \
    --screenshot="$png" "file://$PWD/$out/$log/report.html" >/dev/null 2>&1
  /usr/bin/python3 - "$png" <<'PY' || true
import sys
from PIL import Image
p = sys.argv[1]
Image.open(p).convert("RGB").quantize(256).save(p, optimize=True)
PY
  echo "$png: $(stat -c %s "$png") bytes"
done
