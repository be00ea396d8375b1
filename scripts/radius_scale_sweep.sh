#!/usr/bin/env bash
# The real logs' ATE against the GPS as a function of the wheels' rolling-radius scale
# (docs/results.md, "Session 20"): runs every estimator on both WVU Pathfinder logs with a
# common radius scale s applied as a calibration overlay, and prints one Markdown row per
# (run, s): 3-D and horizontal ATE posyaw (m) of DR, EKF, RTS and smoother.
#   bash scripts/radius_scale_sweep.sh [OUTDIR] [SCALES...]   (default out/radius-sweep;
#                                                               1.00 1.02 ... 1.10)
set -euo pipefail
cd "$(dirname "$0")/.."
B=build/release/traverse
out=${1:-out/radius-sweep}
shift || true
scales=("$@")
[ ${#scales[@]} -eq 0 ] && scales=(1.00 1.02 1.04 1.06 1.07 1.08 1.10)
mkdir -p "$out"
echo "| run | radius scale | DR | EKF | RTS | smoother | DR horiz. | EKF horiz. | RTS horiz. | smoother horiz. |"
echo "|---|---|---|---|---|---|---|---|---|---|"
for r in s5t1 test17run; do
  for s in "${scales[@]}"; do
    printf 'format: 1\nodometry:\n  wheel_radius_scale_left: %s\n  wheel_radius_scale_right: %s\n' \
      "$s" "$s" > "$out/scale-$s.yaml"
    o="$out/$r-$s"
    "$B" -q run "datasets/logs/wvu-pathfinder-$r" --calibration "$out/scale-$s.yaml" -o "$o" \
      2>/dev/null
    /usr/bin/python3 - "$o/metrics.json" "$r" "$s" <<'PY'
import json, sys
est = json.load(open(sys.argv[1]))["estimators"]
names = ("dr", "ekf", "rts", "smoother")
row = [sys.argv[2], sys.argv[3]]
row += ["%.3f" % est[e]["ate_posyaw_m"] for e in names]
row += ["%.3f" % est[e]["ate_posyaw_horizontal_m"] for e in names]
print("| " + " | ".join(row) + " |")
PY
  done
done
