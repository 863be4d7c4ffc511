#!/bin/bash
# Builds an older revision of rephoto beside this checkout, forced to the code a CPU without
# AVX-512 runs, so that its speed and this build's can be measured in turns on one machine.
#
#   bench/reference_build.sh REV DIR     # e.g. bench/reference_build.sh af3fe9d /tmp/ref-af3fe9d
#   then, in turns:  DIR/build/bench/rephoto_bench_metrics ...   (the old code's AVX2 path)
#                    REPHOTO_ISA=avx2 build/bench/rephoto_bench_metrics ...
#
# Why: a speed goal stated in milliseconds holds on the machine it was measured on. A shared
# VM's speed drifts by tens of per cent between days, and another machine differs by more, so
# this build's figure against a goal means little alone. The ratio new / old measured in turns
# on one machine does carry over: new figure on the goal's machine ~= ratio x the old figure
# measured there (the issue's table). docs/speed.md has the figures and the method.
#
# Revisions that have core/isa.h take REPHOTO_ISA=avx2 at run time and are built unchanged.
# Older ones (before 4da57b8) picked the AVX-512 kernels by CPUID; the script edits their
# dispatch in DIR (never in this checkout) so that they run their AVX2 (x86-64-v3) versions:
# the metrics' HasAvx512() answers false, the render/metric clones lose their x86-64-v4
# variant, and Embree is asked for isa=avx2. Each edit must apply, else the script stops.
set -euo pipefail
rev=${1:?usage: bench/reference_build.sh REV DIR}
dir=${2:?usage: bench/reference_build.sh REV DIR}
repo=$(cd "$(dirname "$0")/.." && pwd)
if [ -e "$dir" ]; then
  echo "reference_build: $dir exists; remove it (git worktree remove --force $dir) or name another" >&2
  exit 2
fi
git -C "$repo" worktree add --detach "$dir" "$rev" > /dev/null
cd "$dir"
note="run it with REPHOTO_ISA=avx2 for the AVX2 code"
if ! git grep -q "REPHOTO_ISA" -- src/rephoto/core; then
  note="AVX2 code forced"
  edit() {  # file sed-expression pattern-that-must-appear-after
    sed -i "$2" "$1"
    grep -q -- "$3" "$1" || { echo "reference_build: $1: the AVX2 edit did not apply" >&2; exit 1; }
  }
  edit src/rephoto/metrics/kernels.cc 's/static const bool has = __builtin_cpu_supports/static const bool has = false \&\& __builtin_cpu_supports/' 'has = false &&'
  for f in src/rephoto/metrics/kernels.h src/rephoto/render/render.cc; do
    edit "$f" 's/target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")/target_clones("arch=x86-64-v3", "default")/' 'target_clones("arch=x86-64-v3", "default")'
  done
  for f in $(git grep -l 'rtcNewDevice(nullptr)' -- src); do
    edit "$f" 's/rtcNewDevice(nullptr)/rtcNewDevice("isa=avx2")/' 'rtcNewDevice("isa=avx2")'
  done
  if git grep -n 'x86-64-v4' -- src | grep -v '__attribute__((target("arch=x86-64-v4")))' |
      grep -v '^[^:]*:[0-9]*: *//' | grep -q .; then
    echo "reference_build: $rev has AVX-512 dispatch this script does not know; not built" >&2
    exit 1
  fi
fi
bash scripts/build.sh > build.log 2>&1 || { echo "reference_build: build failed, see $dir/build.log" >&2; exit 1; }
echo "$dir/build (revision $(git rev-parse --short HEAD); $note)"
