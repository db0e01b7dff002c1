#!/usr/bin/env bash
# The accuracy study of docs/accuracy.md, from the repository root or anywhere:
#   bench/accuracy/run.sh
# 1. builds fathom_accuracy (bench/accuracy_study.cpp) in build-bench with
#    -DFATHOM_BUILD_BENCH=ON (configuring it if needed);
# 2. renders both cases (smooth analytic field, chest CT with a spike TF) with
#    every integrator at steps 4 .. 1/8 and compares each image with the
#    reference integrator: bench/accuracy/results.csv;
# 3. plots RMSE against step with gnuplot (installing gnuplot-nox when gnuplot
#    is missing): docs/accuracy_convergence.png;
# 4. prints the RMSE table and the measured convergence orders.
# Environment: SIZE (image width = height, default 256), JOBS (build jobs).
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
build="$root/build-bench"
csv="$root/bench/accuracy/results.csv"
png="$root/docs/accuracy_convergence.png"
size="${SIZE:-256}"
jobs="${JOBS:-$(nproc)}"

build_tool() {
    if [ ! -f "$build/CMakeCache.txt" ]; then
        cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DFATHOM_BUILD_BENCH=ON -DFATHOM_BUILD_TESTS=OFF
    else
        cmake -S "$root" -B "$build" -DFATHOM_BUILD_BENCH=ON > /dev/null
    fi
    cmake --build "$build" --target fathom_accuracy -j "$jobs"
}

ensure_gnuplot() {
    command -v gnuplot > /dev/null && return
    local sudo=""
    if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
    echo "run.sh: gnuplot not found; installing gnuplot-nox"
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends gnuplot-nox
}

start=$SECONDS
build_tool
echo "run.sh: rendering ${size}x${size} images (this takes a minute or two)"
"$build/bench/fathom_accuracy" --volume "$root/data/lidc2.nrrd" --tf "$root/examples/tf/ct-spike.json" \
    --size "$size" --out "$csv" > /dev/null
ensure_gnuplot
gnuplot -e "results='$csv'; output='$png'" "$root/bench/accuracy/plot.gp"
echo "run.sh: wrote ${csv#"$root"/} and ${png#"$root"/} in $((SECONDS - start)) s"
"$build/bench/fathom_accuracy" --summary "$csv"
