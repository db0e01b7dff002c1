#!/usr/bin/env bash
# Renders docs/gallery/*.png: each shared real dataset in several modes and
# presets, with `fathom` commands only (docs/gallery.md shows them).
#   scripts/gallery.sh [FATHOM] [DATA]   (defaults: build/fathom, ../shared/data)
set -euo pipefail
cd "$(dirname "$0")/.."
fathom=${1:-build/fathom}
data=${2:-../shared/data}
out=docs/gallery
mkdir -p "$out"
size=(--width 320 --height 320)

r() {  # name, then fathom render arguments
  local name=$1
  shift
  echo "gallery: $name"
  "$fathom" render "$@" "${size[@]}" -q -o "$out/$name.png"
}

ct=data/lidc2.nrrd
r chest-bone --volume $ct --preset ct-bone --orbit 90,10,2.6
r chest-bone-shaded --volume $ct --preset ct-bone --orbit 90,10,2.6 --shade
r chest-skin --volume $ct --preset ct-skin --orbit 200,15,2.2 --shade
r chest-cut --volume $ct --preset ct-skin --orbit 90,10,2.6 --shade --clip-plane 180,180,166,0,1,0
r chest-mip --volume $ct --preset grayscale --orbit 90,0,2.6 --model mip
r chest-xray --volume $ct --preset grayscale --orbit 90,0,2.6 --model absorption
r chest-iso --volume $ct --preset ct-bone --orbit 90,10,2.6 --iso 25,0.9,0.65,0.55,0.25 --iso 110,1,1,0.92

head=$data/ct_head_stanford/cthead.nhdr
if [ -e "$head" ]; then
  # CThead's slices run from the crown down: a camera with up = −z shows it upright.
  scene=$(mktemp --suffix=.json)
  trap 'rm -f "$scene"' EXIT
  cat >"$scene" <<JSON
{"format": "fathom-scene/1", "volume": {"path": "$(realpath "$head")"},
 "transfer_function": {"preset": "ct-skin"},
 "camera": {"position": [-44, -343.4, 23.6], "look_at": [127.5, 127.5, 112], "up": [0, 0, -1]}}
JSON
  r head-skin "$scene" --shade
  sed -i 's/"ct-skin"/"ct-bone"/' "$scene"
  r head-bone "$scene" --shade
  r head-iso "$scene" --iso 1100,1,0.95,0.85
fi
bunny=$data/ct_bunny_stanford/bunny.nhdr
if [ -e "$bunny" ]; then
  r bunny-shaded --volume "$bunny" --preset ct-bone --orbit 300,20,2.4 --shade
  r bunny-mip --volume "$bunny" --preset grayscale --orbit 300,20,2.4 --model mip
fi
small=$data/sim_and_small_vtkdata
if [ -e "$small/embryo.slc" ]; then
  r embryo --volume "$small/embryo.slc" --preset ct-soft-tissue --orbit 30,20,2.4 --shade
fi
if [ -e "$small/neghip.slc" ]; then
  r neghip-iso --volume "$small/neghip.slc" --preset grayscale --orbit 30,20,2.6 \
    --iso 60,0.3,0.5,1,0.4 --iso 160,1,0.6,0.2
fi
if [ -e "$small/hydrogen.vti" ]; then
  r hydrogen --volume "$small/hydrogen.vti" --preset mr-default --orbit 30,20,2.6 --shade
fi
if [ -e "$small/ironProt.vtk" ]; then
  r ironprot-iso --volume "$small/ironProt.vtk" --preset grayscale --orbit 30,20,2.6 --iso 40,0.9,0.7,0.3
fi
echo "gallery: done ($out)"
