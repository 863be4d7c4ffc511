#!/usr/bin/env bash
# Installs the Debian 12 packages the example pipelines in this folder need (optional for rephoto
# itself; scripts/install-deps.sh covers building rephoto). Idempotent: exits at once when all are
# installed.
# Usage: examples/pipelines/install-deps.sh   (as root, or through sudo when available)
#   colmap          feature extraction, matching, triangulation, poisson_mesher (CPU; no CUDA)
#   python3-numpy   known_poses.py, poisson_mesh.py
#   python3-scipy   nearest neighbours for normals and pixel footprints
#   python3-open3d  Poisson surface, trimming and subdivision (poisson_mesh.py)
set -euo pipefail

packages=(colmap python3-numpy python3-scipy python3-open3d)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0

echo "install-deps: installing ${missing[*]}" >&2
sudo=""
[ "$(id -u)" -ne 0 ] && sudo="sudo"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
