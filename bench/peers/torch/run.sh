#!/usr/bin/env bash
# fathom's differentiable alpha quadrature against a PyTorch autograd
# reference on the same grids and rays (docs/reverse-rendering.md):
# gradients cross-checked, forward+backward timed on the same threads.
#   bench/peers/torch/run.sh [BUILD_DIR] [N] [W] [THREADS]
# Needs Debian's python3-torch (CPU); not needed to build or test fathom.
set -euo pipefail
cd "$(dirname "$0")/../../.."
build=${1:-build}
n=${2:-64}
w=${3:-128}
threads=${4:-2}
out=$build/torch-peer
"$build"/bench/fathom_diff_peer "$out" "$n" "$w" "$threads" 5
/usr/bin/python3 bench/peers/torch/torch_alpha.py "$out" "$threads" 3
