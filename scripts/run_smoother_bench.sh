#!/usr/bin/env bash
# Smoother scaling table: benchmarks/bench_smoother.cpp's BM_SmoothSegment at 1 000, 10 000 and
# 100 000 nodes, each size in its own process (peak RSS is process-wide), then the time ratios
# for 10x the nodes (the issue's bound: <= 11x).
#   scripts/run_smoother_bench.sh [build/release/benchmarks/bench_smoother] [sizes...]
set -euo pipefail
bench=${1:-build/release/benchmarks/bench_smoother}
shift || true
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(1000 10000 100000)
[ -x "$bench" ] || { echo "no benchmark binary $bench (ninja -C <build> bench_smoother)" >&2; exit 1; }

out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for n in "${sizes[@]}"; do
  echo "== $n nodes" >&2
  "$bench" --benchmark_filter="^BM_SmoothSegment/$n/" --benchmark_out="$out/$n.json" \
    --benchmark_out_format=json >&2
done

python3 - "$out" "${sizes[@]}" <<'EOF'
import json, sys
out, sizes = sys.argv[1], sys.argv[2:]
rows = {}
for n in sizes:
    b = json.load(open(f"{out}/{n}.json"))["benchmarks"][0]
    rows[n] = b
hdr = ("nodes", "LM iter", "build s", "solve s", "cov s", "total s", "us/node/iter",
       "wall ms", "CPU ms", "peak RSS MB", "RSS before MB", "status")
print("| " + " | ".join(hdr) + " |")
print("|" + "---|" * len(hdr))
for n in sizes:
    b = rows[n]
    print("| %d | %.1f | %.3f | %.3f | %.3f | %.3f | %.2f | %.1f | %.1f | %.0f | %.0f | %s |" % (
        b["nodes"], b["lm_iterations"], b["build_s"], b["solve_s"], b["covariance_s"],
        b["total_s"], b["us_per_node_iter"], b["real_time"], b["cpu_time"], b["peak_rss_MB"],
        b["rss_before_MB"], b.get("label", "")))
print()
for a, c in zip(sizes, sizes[1:]):
    ra, rc = rows[a], rows[c]
    f = rc["nodes"] / ra["nodes"]
    print("%s -> %s nodes (x%.0f): total time x%.2f (CPU x%.2f), LM iterations x%.2f, "
          "time per node per iteration x%.2f, peak RSS increase x%.2f" % (
              a, c, f, rc["total_s"] / ra["total_s"], rc["cpu_time"] / ra["cpu_time"],
              rc["lm_iterations"] / ra["lm_iterations"],
              rc["us_per_node_iter"] / ra["us_per_node_iter"],
              (rc["peak_rss_MB"] - rc["rss_before_MB"]) /
              max(ra["peak_rss_MB"] - ra["rss_before_MB"], 1e-9)))
EOF
