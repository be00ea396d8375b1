#!/bin/bash
# docs/results.md "Session 26: correlated slip …": Rocky-7 tilted-multi logs of the independent
# generator with per-wheel Gauss-Markov slip (3 %, tau 5 s), seeds 1-5, run with four rover.yaml
# variants (white slip only; common slip c_x, c_y; with c_omega; with c_omega and a tighter gyro
# rate perturbation), with and without the sun. Prints one line per seed, variant, sun and
# estimator: final position error (m), yaw RMSE (deg), yaw RMSE/sigma, position NEES, position
# RMSE/sigma.  Usage: scripts/correlated_slip_table.sh [WORKDIR] (default /tmp/slipc)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
B=${B:-$ROOT/build/release/traverse}
W=${1:-/tmp/slipc}
mkdir -p "$W" && cd "$W"
for s in 1 2 3 4 5; do
  [ -d g$s ] || /usr/bin/python3 "$ROOT/scripts/independent_sim.py" --rover "$ROOT/datasets/rovers/rocky7" \
    --scenario tilted-multi --seed $s --slip-sigma 0.03 --out g$s >/dev/null
  for variant in base c2 c3 c3rp; do
    d=g${s}_$variant; rm -rf $d; cp -r g$s $d
    case $variant in
      c2) printf "  common_longitudinal_mps: 0.001\n  common_lateral_mps: 0.0001\n  common_time_constant_s: 5\n" > ins.txt;;
      c3|c3rp) printf "  common_longitudinal_mps: 0.001\n  common_lateral_mps: 0.0001\n  common_yaw_rate_rad_s: 0.004\n  common_time_constant_s: 5\n" > ins.txt;;
      base) : > ins.txt;;
    esac
    sed -i '/^  spin_rad_s:/r ins.txt' $d/rover.yaml
    if [ $variant = c3rp ]; then
      sed -i "s/^gyro:/gyro:\n  rate_perturbation_rad_s2_per_sqrt_hz: 0.0005/" $d/rover.yaml
    fi
    for sun in sun nosun; do
      a=""; [ $sun = nosun ] && a="--no-sun"
      "$B" run -q $a $d -o $d.$sun.r > $d.$sun.log 2>&1
      /usr/bin/python3 -c "
import json;m=json.load(open('$d.$sun.r/metrics.json'))['estimators']
for k in ['dr','ekf','smoother']:
  v=m[k]; print('$s $variant $sun',k,'%.4f %.4f %.3f %.3f %.3f'%(v.get('final_position_error_m',0),v.get('yaw_rmse_deg',0),v.get('yaw_rmse_over_sigma',0),v.get('nees_position_mean',0),v.get('position_rmse_over_sigma',0)))"
    done
  done
done
