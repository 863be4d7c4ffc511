#!/usr/bin/env bash
# Installs the Debian 12 packages rephoto needs to build, test and benchmark.
# Idempotent: when everything is present it only checks with dpkg and exits (well under a second).
# Usage: scripts/install-deps.sh            (as root, or through sudo when available)
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git ca-certificates
  clang libclang-rt-14-dev
  libembree-dev libtbb-dev libeigen3-dev
  libturbojpeg0-dev libspng-dev libdeflate-dev libtinyexr-dev zlib1g-dev
  libmeshoptimizer-dev libtinyobjloader-dev libboost-dev
  libcli11-dev nlohmann-json3-dev libfmt-dev libtomlplusplus-dev libxxhash-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  python3-skimage python3-numpy python3-scipy
  python3-dev python3-pybind11 pybind11-dev python3-pytest python3-venv python3-pip
  python3-setuptools python3-wheel python3-pandas python3-matplotlib
  libegl-dev libgl-dev libgles-dev libegl-mesa0 libgl1-mesa-dri
  chromium libjs-three
  slurmctld slurmd slurm-client munge
  libsqlite3-dev libcpp-httplib-dev libarchive-dev libssl-dev python3-websocket
  nginx-light openssl
  colmap
  libdnnl-dev libomp-dev python3-torch python3-torchvision
)

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
