#!/bin/bash
# Times this build's AVX2 code against a reference build's (bench/reference_build.sh) in turns,
# on the kernels issue 29 sets goals for, and prints per case the medians, the ratio
# this / reference, and the estimate on the machine the issue measured: ratio x its figure
# for the reference revision (af3fe9d; the table of issue 29). docs/speed.md explains why a
# ratio in turns is the figure that carries over between machines.
#
#   bench/vs_reference.sh REFERENCE_DIR [ROUNDS]     # e.g. /tmp/ref-af3fe9d 3
#
# Needs python3 (Debian's, for the JSON of Google Benchmark). The reference must be af3fe9d for
# the estimates to mean anything; with another revision only the ratios do.
set -euo pipefail
ref=${1:?usage: bench/vs_reference.sh REFERENCE_DIR [ROUNDS]}
rounds=${2:-3}
here=$(cd "$(dirname "$0")/.." && pwd)
new=$here/build/bench
old=$ref/build/bench
for b in rephoto_bench_metrics rephoto_bench_splat; do
  [ -x "$new/$b" ] || { echo "vs_reference: $new/$b missing (bash scripts/build.sh)" >&2; exit 2; }
  [ -x "$old/$b" ] || { echo "vs_reference: $old/$b missing (bench/reference_build.sh)" >&2; exit 2; }
done
metrics='BM_SetOneThread|BM_SetBytesInBandsOneThread|BM_Set/4000|BM_SetBytesInBands/|BM_CensusBytesInBandsOneThread|BM_DssimBytesInBandsOneThread|BM_IcidBytesInBandsOneThread'
splat='BM_RenderSplat/1000/1920'
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for r in $(seq "$rounds"); do
  for who in old new; do
    if [ "$who" = old ]; then dir=$old; isa=""; else dir=$new; isa=avx2; fi
    echo "vs_reference: round $r/$rounds, $who" >&2
    env ${isa:+REPHOTO_ISA=$isa} "$dir/rephoto_bench_metrics" --benchmark_filter="$metrics" \
      --benchmark_min_time=1 --benchmark_format=json > "$out/$who.metrics.$r.json" 2> /dev/null
    env ${isa:+REPHOTO_ISA=$isa} "$dir/rephoto_bench_splat" --benchmark_filter="$splat" \
      --benchmark_format=json > "$out/$who.splat.$r.json" 2> /dev/null
  done
done
python3 - "$out" "$rounds" <<'EOF'
import json, statistics, sys
out, rounds = sys.argv[1], int(sys.argv[2])
# The issue's AVX2 figures for af3fe9d (ms); the goal in the last column.
issue = {
    "BM_SetOneThread": (766, 300), "BM_SetBytesInBandsOneThread": (764, 300),
    "BM_Set": (417, 170), "BM_CensusBytesInBandsOneThread": (146, 60),
    "BM_DssimBytesInBandsOneThread": (271, 100), "BM_IcidBytesInBandsOneThread": (1280, 500),
    "BM_RenderSplat": (607, 350),
}
times = {}
for who in ("old", "new"):
    for kind in ("metrics", "splat"):
        for r in range(1, rounds + 1):
            for b in json.load(open(f"{out}/{who}.{kind}.{r}.json"))["benchmarks"]:
                # wall time for the 2-thread cases, CPU time (= wall on one thread) otherwise
                name = b["name"].split("/")[0]
                key = name + ("/2T" if name in ("BM_Set", "BM_SetBytesInBands", "BM_RenderSplat") else "")
                times.setdefault((key, who), []).append(b["real_time"])
print(f"{'case':42s} {'reference':>10s} {'this':>10s} {'ratio':>6s} {'issue':>8s} {'estimate':>9s} {'goal':>6s}")
for key in sorted({k for k, _ in times}):
    o = statistics.median(times[(key, "old")])
    n = statistics.median(times[(key, "new")])
    base = key.split("/")[0]
    fig, goal = issue.get(base, (None, None))
    est = f"{n / o * fig:9.0f}" if fig else f"{'':9s}"
    print(f"{key:42s} {o:10.1f} {n:10.1f} {n / o:6.2f} {fig or '':>8} {est} {goal or '':>6}")
print(f"(ms, medians of {rounds} rounds in turns; this build with REPHOTO_ISA=avx2)")
EOF
