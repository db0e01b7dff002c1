#!/usr/bin/env bash
# Builds bench/peers/vtk into build-peers/ (beside build/, git-ignored by the
# /build*/ pattern) and runs the fathom-vs-VTK comparison under xvfb-run.
# Installs nothing: it needs libvtk9-dev, xvfb and xauth (Debian 12:
# apt-get install libvtk9-dev xvfb xauth), plus fathom's own dependencies.
#
#   bench/peers/vtk/run.sh                     # the project's figures
#   bench/peers/vtk/run.sh --frames 9          # extra flags go to every run
#   FATHOM_PEER_BUILD=/tmp/peers bench/peers/vtk/run.sh
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(cd "$here/../../.." && pwd)
build=${FATHOM_PEER_BUILD:-$root/build-peers}
out=$build/out

for tool in cmake ninja xvfb-run; do
    command -v "$tool" >/dev/null || { echo "run.sh: '$tool' not found (see README.md)" >&2; exit 1; }
done

cmake -S "$here" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" --target fathom_vtk_peer
mkdir -p "$out"

echo "fathom checkout: $(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo '?')" \
     "($(git -C "$root" status --porcelain 2>/dev/null | wc -l) changed files)"
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//'), $(nproc) cores"

peer() {
    local name=$1
    shift
    echo
    echo "== $name"
    # A 24-bit screen (xvfb-run's default is 8-bit); VTK renders offscreen.
    xvfb-run -a -s "-screen 0 1280x1024x24" "$build/fathom_vtk_peer" "$@" \
        --json "$out/$name.json" --images "$out/$name"
}

# The figures the project reports: the bundled chest CT, bone preset.
peer lidc2 --volume "$root/data/lidc2.nrrd" --preset ct-bone \
    --width 512 --height 512 --step 0.5 --orbit 90,10,2.6 "$@"

bunny=$(cd "$root/.." && pwd)/shared/data/ct_bunny_stanford/bunny.nhdr
if [[ -f $bunny ]]; then
    peer bunny --volume "$bunny" --preset ct-bone \
        --width 512 --height 512 --step 0.5 --orbit 90,10,2.6 "$@"
else
    echo
    echo "== bunny: $bunny not present, skipped"
fi

echo
echo "JSON and last-frame images: $out"
