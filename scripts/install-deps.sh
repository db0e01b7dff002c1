#!/usr/bin/env bash
# Installs the Debian 12 packages fathom builds and tests with (docs/dependencies.md).
set -euo pipefail
packages=(
  build-essential cmake ninja-build pkg-config
  zlib1g-dev libisal-dev libpng-dev libopenexr-dev nlohmann-json3-dev libcli11-dev libpugixml-dev
  libnifti2-dev libniftiio-dev libgdcm-dev libopenvdb-dev libboost-dev
  libavformat-dev libavcodec-dev libswscale-dev
  libgtest-dev libbenchmark-dev libhwy-dev
  python3-dev pybind11-dev python3-numpy python3-pytest python3-torch
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all packages present"
  exit 0
fi
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
