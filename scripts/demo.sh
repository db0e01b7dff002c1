#!/usr/bin/env bash
# One command from a fresh Debian 12 machine to a picture: installs the
# packages, builds fathom (Release) and renders the bundled chest CT.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DFATHOM_BUILD_TESTS=OFF
cmake --build build --parallel
mkdir -p out
./build/fathom render --volume data/lidc2.nrrd --preset ct-bone --orbit 90,10,2.6 \
  --width 512 --height 512 -o out/lidc2-bone.png
echo "wrote out/lidc2-bone.png"
