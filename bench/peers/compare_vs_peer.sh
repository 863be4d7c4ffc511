#!/bin/bash
# Whole-process CPU time of `rephoto compare` against the OpenCV-composed peer
# (compare_opencv.py) on one photo/rendering pair, measured in turns in one run so that both
# see the same machine load. Prints user+system CPU seconds and peak RSS of every run and the
# medians. Needs /usr/bin/time and Debian's python3-opencv.
#
#   bench/peers/compare_vs_peer.sh PHOTOS_DIR RENDERS_DIR [TURNS] [REPHOTO] [OTHER_REPHOTO]
#
# The folders must hold one pair with the same stem. Metrics: the paper's set plus psnr, no
# error images. OTHER_REPHOTO (optional): a second rephoto binary (e.g. an older build) run in
# the same turns.
set -euo pipefail
photos=$1
renders=$2
turns=${3:-5}
rephoto=${4:-build/apps/rephoto/rephoto}
other=${5:-}
here=$(cd "$(dirname "$0")" && pwd)
photo=$(ls "$photos"/* | head -1)
render=$(ls "$renders"/* | head -1)
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
metrics=1-ncc,cb+cr,zssd,dssim,census,psnr
measure() {  # label command...
  local label=$1
  shift
  /usr/bin/time -f "%U %S %M" -o "$out/time" "$@" > /dev/null 2>&1
  read -r user sys rss < "$out/time"
  echo "$label $(echo "$user + $sys" | bc) $rss" | tee -a "$out/all"
}
for ((i = 0; i < turns; ++i)); do
  measure rephoto "$rephoto" compare --photos "$photos" --renders "$renders" --metrics $metrics \
    --no-error-images --out "$out/run"
  if [[ -n $other ]]; then
    measure other "$other" compare --photos "$photos" --renders "$renders" --metrics $metrics \
      --no-error-images --out "$out/run"
  fi
  measure peer /usr/bin/python3 "$here/compare_opencv.py" "$photo" "$render"
done
median() { grep "^$1 " "$out/all" | awk '{print $2}' | sort -g | awk '{v[NR]=$1} END {print v[int((NR+1)/2)]}'; }
r=$(median rephoto)
p=$(median peer)
echo "median CPU seconds: rephoto $r, peer $p, ratio $(echo "scale=3; $r / $p" | bc)"
if [[ -n $other ]]; then
  o=$(median other)
  echo "median CPU seconds: other $o, rephoto/other $(echo "scale=3; $r / $o" | bc)"
fi
