#!/bin/bash
# AlexNet LPIPS: rephoto (bench/bench_lpips.cc) against PyTorch on the CPU (lpips_torch.py,
# Debian python3-torch), same weights, same sizes (1 MP = 1152x864, 12 MP = 4000x3000), 2
# threads each, measured in turns in one run so that both see the same machine load. Prints
# per call: wall seconds and process CPU seconds (all threads), the medians, and the ratios
# rephoto / PyTorch.
#
#   bench/peers/lpips_vs_torch.sh [TURNS] [WEIGHTS_DIR] [BENCH_BINARY]
#
# WEIGHTS_DIR: alex.pth + alexnet-owt-7be5be79.pth (real or random: the time is the same);
# default: random ones made by src/rephoto/lpips/lpips_reference.py in a temp folder.
set -euo pipefail
turns=${1:-3}
weights=${2:-}
bench=${3:-build/bench/rephoto_bench_lpips}
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
if [[ -z $weights ]]; then
  weights=$work/weights
  /usr/bin/python3 "$here/../../src/rephoto/lpips/lpips_reference.py" "$weights" > /dev/null
fi
export OMP_NUM_THREADS=2
for size in "1MP 1152 864" "12MP 4000 3000"; do
  read -r label width height <<< "$size"
  : > "$work/$label"
  for ((i = 0; i < turns; ++i)); do
    REPHOTO_LPIPS_WEIGHTS=$weights "$bench" --benchmark_filter="Alex$label" \
      --benchmark_repetitions=1 --benchmark_format=json 2> /dev/null |
      /usr/bin/python3 -c '
import json, sys
b = json.load(sys.stdin)["benchmarks"][0]
scale = {"ms": 1e-3, "us": 1e-6, "ns": 1e-9, "s": 1.0}[b["time_unit"]]
print("rephoto", b["real_time"] * scale, b["cpu_time"] * scale)' | tee -a "$work/$label"
    /usr/bin/python3 "$here/lpips_torch.py" "$weights" alex "$width" "$height" 1 2 |
      awk '{print "torch", $1, $2}' | tee -a "$work/$label"
  done
  /usr/bin/python3 - "$work/$label" "$label" << 'PY'
import statistics, sys
rows = [line.split() for line in open(sys.argv[1])]
med = lambda who, k: statistics.median(float(r[k]) for r in rows if r[0] == who)
rw, rc, tw, tc = med("rephoto", 1), med("rephoto", 2), med("torch", 1), med("torch", 2)
print(f"{sys.argv[2]}: rephoto wall {rw:.2f} s cpu {rc:.2f} s | torch wall {tw:.2f} s cpu "
      f"{tc:.2f} s | ratio wall {rw / tw:.2f} cpu {rc / tc:.2f}")
PY
done
