#!/usr/bin/env bash
# Monte Carlo accuracy of every estimator on every scenario (docs/results.md), seeds 1..RUNS.
# Writes results/accuracy/<scenario>.json and prints the tables. Run from the repository root
# after building the release preset. RUNS defaults to 20.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${TRAVERSE:-build/release/traverse}
runs=${RUNS:-20}
out=results/accuracy
mkdir -p "$out"
for s in straight-1m turn-in-place-360 obstacle planar-18m multi-stop; do
  echo "== $s ($runs runs)"
  "$bin" bench accuracy --scenario "$s" --runs "$runs" --json "$out/$s.json" --quiet
done
# Sun-sensor rate sweep of R §5: f_others / f_SS = 1 … 10 on planar-18m (others at 50 Hz).
for k in 1 2 3 4 5 6 7 8 9 10; do
  rate=$(python3 -c "print(50/$k)")
  "$bin" bench accuracy --scenario planar-18m --runs "$runs" --set "sensors.sun.rate_hz=$rate" \
    --json "$out/planar-18m-sun-ratio-$k.json" --quiet
done
python3 scripts/accuracy_tables.py "$out"
