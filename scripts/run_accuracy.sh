#!/usr/bin/env bash
# Every accuracy table of docs/results.md in one command: Monte Carlo over seeds 1..RUNS of
# every scenario (traverse bench accuracy --out), the sun-sensor rate sweep of R §5 and the
# noise-sensitivity study — DR, EKF, RTS and the batch smoother side by side. Writes
# results/accuracy/*.json and accuracy.md, prints the study tables (scripts/accuracy_tables.py)
# and, when python3-matplotlib is installed, the plots docs/images/study-*.png. Run from the
# repository root after building the release preset. RUNS defaults to 20; JOBS to all cores.
# STUDIES=0 skips the sweep and the sensitivity study; SCENARIOS=0 skips the per-scenario tables.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${TRAVERSE:-build/release/traverse}
runs=${RUNS:-20}
jobs=${JOBS:-0}
out=results/accuracy
mkdir -p "$out"
if [ "${SCENARIOS:-1}" != 0 ]; then
  "$bin" bench accuracy --runs "$runs" --jobs "$jobs" --out "$out" --quiet
fi
if [ "${STUDIES:-1}" != 0 ]; then
  # Sun-sensor rate sweep (R §5): f_others / f_SS = 1 … 10 on planar-18m (others at 50 Hz).
  for k in 1 2 3 4 5 6 7 8 9 10; do
    rate=$(/usr/bin/python3 -c "print(50/$k)")
    "$bin" bench accuracy --scenario planar-18m --runs "$runs" --jobs "$jobs" --quiet \
      --set "sensors.sun.rate_hz=$rate" --json "$out/planar-18m-sun-ratio-$k.json"
  done
  # Noise sensitivity on planar-18m: white wheel slip (the scenario's 0.02 m/s is R–B's), and
  # gyro-bias drift (random walk; the scenario has none). The simulator writes what it injected
  # into the log's rover.yaml, so every estimator is told the truth about the noise.
  for slip in 0.005 0.01 0.02 0.04 0.08; do
    "$bin" bench accuracy --scenario planar-18m --runs "$runs" --jobs "$jobs" --quiet \
      --set "slip.longitudinal_white_mps=$slip" --json "$out/planar-18m-slip-$slip.json"
  done
  for rw in 0 2e-5 1e-4 5e-4; do
    "$bin" bench accuracy --scenario planar-18m --runs "$runs" --jobs "$jobs" --quiet \
      --set "sensors.gyro.bias_random_walk_rad_s_per_sqrt_s=$rw" \
      --json "$out/planar-18m-biasrw-$rw.json"
  done
fi
/usr/bin/python3 scripts/accuracy_tables.py "$out"
