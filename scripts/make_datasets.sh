#!/usr/bin/env bash
# Regenerates the bundled logs in datasets/logs/ (deterministic: byte-identical files): the
# simulated ones from their scenarios (same seed, same files), the real ones from the source
# files in datasets/real/ (docs/real-logs.md). Run from the repository root after building.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${TRAVERSE:-build/release/traverse}
# Debian's python3 has python3-h5py (scripts/setup.sh); another python3 first on PATH may not.
py=${PYTHON:-/usr/bin/python3}
"$bin" simulate multi-stop -o datasets/logs/multi-stop --seed 1 --quiet
"$bin" simulate straight-1m -o datasets/logs/straight-1m --seed 1 --quiet
for run in s5t1 test17run; do
  "$py" scripts/import_wvu_pathfinder.py datasets/real/wvu-pathfinder/$run.mat \
    datasets/logs/wvu-pathfinder-$run
done
