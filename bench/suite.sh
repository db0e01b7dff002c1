#!/usr/bin/env bash
# fathom's benchmark suite: `fathom bench` over the shared real volumes, both
# image sizes, both steps, each integrator, a bone and a soft-tissue preset,
# 1 and 2 threads, empty-space skipping on and off. One JSON file per run
# (with peak resident memory: each run is its own process), then the table of
# docs/performance.md from bench/suite_table.py.
#
#   bench/suite.sh [quick|full] [OUT]     (default: quick, out/bench-suite)
#
# FATHOM: the fathom binary (default build/fathom); DATA: the shared data
# folder (default ../shared/data; missing volumes are skipped).
# quick: 512², step 0.5, alpha and preintegrated, 2 threads, plus 1-thread
# and skipping-off rows on the chest CT (under a minute on 2 cores; 22 s on
# the machine of docs/performance.md).
# full: the whole matrix (14 minutes on that machine, up to an hour on slower
# ones).
set -euo pipefail
cd "$(dirname "$0")/.."
mode=${1:-quick}
out=${2:-out/bench-suite}
fathom=${FATHOM:-build/fathom}
data=${DATA:-../shared/data}
mkdir -p "$out"

# name path orbit
volumes=(
  "lidc2 data/lidc2.nrrd 90,10,2.6"
  "bunny $data/ct_bunny_stanford/bunny.nhdr 30,20,2.4"
  "embryo $data/sim_and_small_vtkdata/embryo.slc 30,20,2.4"
)
presets=(ct-bone ct-soft-tissue)

run() {  # name path orbit size step integrator preset threads skip frames
  local name=$1 path=$2 orbit=$3 size=$4 step=$5 integ=$6 preset=$7 threads=$8 skip=$9 frames=${10}
  local tag="$name-$size-$step-$integ-$preset-t$threads-$skip"
  local extra=()
  [ "$skip" = noskip ] && extra+=(--no-skip-empty)
  if [ -s "$out/$tag.json" ]; then echo "have $tag"; return; fi
  "$fathom" bench --volume "$path" --preset "$preset" --orbit "$orbit" --width "$size" --height "$size" \
    --step "$step" --integrator "$integ" --threads "$threads" --frames "$frames" "${extra[@]}" \
    --json "$out/$tag.json"
}

for v in "${volumes[@]}"; do
  read -r name path orbit <<<"$v"
  if [ ! -e "$path" ]; then echo "skip $name: $path not found"; continue; fi
  for preset in "${presets[@]}"; do
    if [ "$mode" = full ]; then
      for size in 512 1024; do
        for step in 0.5 1; do
          for integ in alpha riemann preintegrated preintegrated-simple; do
            for threads in 1 2; do run "$name" "$path" "$orbit" "$size" "$step" "$integ" "$preset" "$threads" skip 5; done
            [ "$size" = 512 ] && run "$name" "$path" "$orbit" "$size" "$step" "$integ" "$preset" 2 noskip 3
          done
        done
      done
    else
      for integ in alpha preintegrated; do
        run "$name" "$path" "$orbit" 512 0.5 "$integ" "$preset" 2 skip 3
        if [ "$name" = lidc2 ]; then
          run "$name" "$path" "$orbit" 512 0.5 "$integ" "$preset" 1 skip 3
          run "$name" "$path" "$orbit" 512 0.5 "$integ" "$preset" 2 noskip 3
        fi
      done
    fi
  done
done
python3 bench/suite_table.py "$out"/*.json
