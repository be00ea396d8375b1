#!/usr/bin/env bash
# Regenerates the bundled logs in datasets/logs/ from their scenarios (deterministic: the same
# seed gives byte-identical files). Run from the repository root after building.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${TRAVERSE:-build/release/traverse}
"$bin" simulate multi-stop -o datasets/logs/multi-stop --seed 1 --quiet
"$bin" simulate straight-1m -o datasets/logs/straight-1m --seed 1 --quiet
