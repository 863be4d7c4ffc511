#!/usr/bin/env bash
# Sets everything up and runs the whole test suite (what CI runs, see .ci/run):
#   1. installs Debian packages, builds Release in ./build, runs every ctest test (the browser
#      tests drive Debian's headless chromium: report/ with --dump-dom, service/ through the
#      DevTools protocol with Debian's python3-websocket, tests/browser/);
#   2. builds the file readers' tests (scene, split, io, mesh) and the libFuzzer targets with
#      clang, AddressSanitizer + UndefinedBehaviorSanitizer in ./build-sanitize (preset
#      "sanitize") and runs the tests (skip with REPHOTO_SKIP_SANITIZE=1);
#   2b. installs the Python package into a fresh venv (build/python-venv, Debian's
#      /usr/bin/python3 with --system-site-packages, offline) reusing ./build, and runs its pytest
#      tests from another folder (skip with REPHOTO_SKIP_PYTHON=1);
#   3. runs each libFuzzer target (scene readers, PLY, OBJ, images, depth maps, experiment
#      files; see fuzz/) for REPHOTO_FUZZ_SECONDS (default 10)
#      on that build (skipped with REPHOTO_SKIP_SANITIZE=1 or REPHOTO_SKIP_FUZZ=1).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/build.sh
ctest --test-dir build --output-on-failure -j2

if [ -z "${REPHOTO_SKIP_PYTHON:-}" ]; then
  echo "== Python package (pip install into build/python-venv, pytest)"
  rm -rf build/python-venv
  /usr/bin/python3 -m venv --system-site-packages build/python-venv
  REPHOTO_BUILD_DIR=build build/python-venv/bin/python -m pip install --quiet --no-index \
    --no-build-isolation --no-deps .
  (cd /tmp && REPHOTO_CLI="$OLDPWD/build/apps/rephoto/rephoto" PYTHONPATH="$OLDPWD/python/tests" \
    "$OLDPWD/build/python-venv/bin/python" -m pytest -q -p no:cacheprovider "$OLDPWD/python/tests")
fi

if [ -z "${REPHOTO_SKIP_SANITIZE:-}" ]; then
  echo "== readers under AddressSanitizer + UndefinedBehaviorSanitizer"
  cmake --preset sanitize >/dev/null
  mapfile -t targets < <(cmake --build build-sanitize --target help |
    sed -n 's/^\(test_\(scene\|split\|io\|mesh\)_[a-z_]*\|fuzz_[a-z_]*\):.*/\1/p' | sort -u)
  cmake --build build-sanitize --target "${targets[@]}"
  ASAN_OPTIONS=detect_leaks=1 LSAN_OPTIONS=suppressions=$PWD/scripts/lsan.supp \
    UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    ctest --test-dir build-sanitize --output-on-failure -j2 -R '^(scene|split|io|mesh)/'
fi

if [ -z "${REPHOTO_SKIP_SANITIZE:-}" ] && [ -z "${REPHOTO_SKIP_FUZZ:-}" ]; then
  echo "== libFuzzer targets"
  BUILD_DIR=build-sanitize scripts/fuzz.sh "${REPHOTO_FUZZ_SECONDS:-10}"
fi
