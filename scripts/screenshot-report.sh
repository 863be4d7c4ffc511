#!/usr/bin/env bash
# Writes a PNG screenshot of a rephoto report.html with headless Chromium (Debian `chromium`,
# installed by scripts/install-deps.sh).
# Usage: scripts/screenshot-report.sh REPORT.html OUT.png [WIDTH [HEIGHT]]
#   WIDTH x HEIGHT is the browser window (default 1400 x 2200); the screenshot is the top of
#   the page at that size.
set -euo pipefail
if [ $# -lt 2 ] || [ $# -gt 4 ]; then
  echo "usage: $0 REPORT.html OUT.png [WIDTH [HEIGHT]]" >&2
  exit 2
fi
report=$1
out=$2
width=${3:-1400}
height=${4:-2200}
[ -f "$report" ] || { echo "$0: $report: no such file" >&2; exit 1; }
browser=$(command -v chromium || command -v chromium-browser || true)
[ -n "$browser" ] || { echo "$0: chromium not found; run scripts/install-deps.sh" >&2; exit 1; }
profile=$(mktemp -d)
trap 'rm -rf "$profile"' EXIT
url="file://$(realpath "$report")"
out_abs="$(realpath -m "$out")"
# --no-sandbox: needed when running as root (containers); the page is a local file.
# Software WebGL (SwiftShader) for the reports' 3D view (docs/view3d.md).
timeout 120 "$browser" --headless --no-sandbox --use-angle=swiftshader --enable-unsafe-swiftshader \
  --hide-scrollbars \
  --no-first-run --no-default-browser-check --disable-extensions --mute-audio \
  --user-data-dir="$profile" --window-size="$width,$height" \
  --screenshot="$out_abs" "$url" >/dev/null 2>"$profile/stderr" || {
  cat "$profile/stderr" >&2
  echo "$0: chromium failed" >&2
  exit 1
}
[ -s "$out_abs" ] || { cat "$profile/stderr" >&2; echo "$0: no screenshot written" >&2; exit 1; }
echo "$out"
