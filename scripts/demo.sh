#!/usr/bin/env bash
# Sets everything up and runs the main job on the built-in demo scene:
# installs Debian packages, builds ./build, runs `rephoto demo --out out/demo`.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/build.sh
build/apps/rephoto/rephoto demo --out out/demo "$@"
