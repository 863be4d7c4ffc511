#!/usr/bin/env bash
# Sets everything up and runs the main job on the built-in demo scene:
# installs Debian packages, builds ./build, runs `rephoto demo --out out/demo`, then a short
# simulated capture followed by `rephoto live` (4 photos on one side, then 4 photos taken
# where the live page suggested; docs/live.md).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/build.sh
build/apps/rephoto/rephoto demo --out out/demo "$@"
build/apps/rephoto/rephoto live-experiment --out out/demo/live --width 320 --height 240 \
  --steps 4 --seeds 0 --no-ring > /dev/null
echo "simulated capture: out/demo/live/suggested (curves: out/demo/live/closed_loop.svg)"
echo "its live page: build/apps/rephoto/rephoto live --watch out/demo/live/suggested/watch" \
  "--out out/demo/live/suggested/run --listen 127.0.0.1:8090"
