#!/usr/bin/env bash
# Installs the Debian packages rephoto needs (if missing) and builds it in ./build (Release).
# Usage: scripts/build.sh [extra cmake -D options]
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
if [ ! -f build/CMakeCache.txt ]; then
  cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DREPHOTO_BUILD_PYTHON=ON "$@" >/dev/null
fi
cmake --build build
