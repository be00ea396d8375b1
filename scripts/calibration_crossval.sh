#!/usr/bin/env bash
# Cross-validation of `traverse calibrate` on the two real WVU Pathfinder logs (docs/results.md,
# "Odometry calibration"): calibrates on each run, then runs every estimator on each run
# uncalibrated, with its own calibration and with the other run's; prints one Markdown row per
# (run, calibration): ATE posyaw (m) of DR, EKF, smoother, and the EKF's and smoother's
# position RMSE/σ and % of GPS fixes within 3σ.
#   bash scripts/calibration_crossval.sh [OUTDIR]     (default out/calibration-crossval)
set -euo pipefail
cd "$(dirname "$0")/.."
B=build/release/traverse
out=${1:-out/calibration-crossval}
mkdir -p "$out"
runs=(s5t1 test17run)
for r in "${runs[@]}"; do
  "$B" -q calibrate "datasets/logs/wvu-pathfinder-$r" -o "$out/cal-$r.yaml"
done
echo "| run | calibration | DR | EKF | smoother | EKF RMSE/σ | EKF fixes in 3σ (%) | smoother RMSE/σ | smoother fixes in 3σ (%) |"
echo "|---|---|---|---|---|---|---|---|---|"
for r in "${runs[@]}"; do
  for c in none "${runs[@]}"; do
    o="$out/$r-$c"
    arg=()
    [ "$c" != none ] && arg=(--calibration "$out/cal-$c.yaml")
    "$B" -q run "datasets/logs/wvu-pathfinder-$r" "${arg[@]}" -o "$o" 2>/dev/null
    /usr/bin/python3 - "$o/metrics.json" "$r" "$c" <<'PY'
import json, sys
est = json.load(open(sys.argv[1]))["estimators"]
g = lambda e, k: est.get(e, {}).get(k, float("nan"))
row = [sys.argv[2], sys.argv[3]] + ["%.2f" % g(e, "ate_posyaw_m") for e in ("dr", "ekf", "smoother")]
for e in ("ekf", "smoother"):
    row += ["%.2f" % g(e, "position_rmse_over_sigma"), "%.0f" % g(e, "gps_within_3sigma_pct")]
print("| " + " | ".join(row) + " |")
PY
  done
done
