#!/usr/bin/env bash
# rephoto live with COLMAP registration on a real scene: the photos of IMAGES are copied one by
# one, in a shuffled order (seed SEED), into a watched folder while `rephoto live --colmap` runs;
# prints each photo's status and latency split (register / predict / depth / model / suggest).
# Usage: scripts/live-colmap.sh IMAGES OUT [SEED] [EXTRA rephoto live options...]
set -euo pipefail
images=$1; out=$2; seed=${3:-1}; shift $(( $# >= 3 ? 3 : 2 ))
rephoto=${REPHOTO:-$(dirname "$0")/../build/apps/rephoto/rephoto}
rm -rf "$out"; mkdir -p "$out/watch"
"$rephoto" live --watch "$out/watch" --out "$out/run" --colmap --exit-when-idle 20 \
  --stable-seconds 1 "$@" > "$out/live.log" 2>&1 &
pid=$!
for f in $(ls "$images" | /usr/bin/python3 -c "import sys,random; l=sys.stdin.read().split(); random.Random($seed).shuffle(l); print(' '.join(l))"); do
  cp "$images/$f" "$out/watch/.$f.part" && mv "$out/watch/.$f.part" "$out/watch/$f"
  sleep 1
done
wait $pid
/usr/bin/python3 - "$out/run/live.json" <<'PY'
import json, sys
api = json.load(open(sys.argv[1]))
keys = ["register", "predict", "depth", "model", "suggest", "total"]
print("photo status completeness 1-ncc " + " ".join(keys))
for p in api["photos"]:
    s = p.get("seconds", {})
    c = p.get("completeness"); e = p.get("error")
    print(p["name"], p["status"], "-" if c is None else f"{c:.3f}", "-" if e is None else f"{e:.3f}",
          " ".join(f"{s.get(k, 0):.2f}" for k in keys), p.get("message", ""))
PY
