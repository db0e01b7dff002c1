#!/usr/bin/env bash
# One command from a fresh Debian 12 machine to a tested build: installs the
# packages, builds and runs every test (Release), then builds and runs them
# again under AddressSanitizer + UndefinedBehaviorSanitizer.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
jobs=$(nproc)

echo "== Release build and tests"
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DFATHOM_WERROR=ON -DFATHOM_BUILD_BENCH=ON
cmake --build build --parallel "$jobs"
ctest --test-dir build --output-on-failure --parallel "$jobs"

echo "== ASan + UBSan build and tests"
# -O1 -g1: line tables for the sanitizers' reports at half the compile time of
# RelWithDebInfo's -O2 -g (the CI budget is 2 cores).
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" \
  -DFATHOM_SANITIZE=ON -DFATHOM_WERROR=ON
cmake --build build-asan --parallel "$jobs"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build-asan --output-on-failure --parallel "$jobs"
