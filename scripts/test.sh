#!/usr/bin/env bash
# One command from a fresh Debian 12 machine to a tested build: installs the
# packages, builds and runs every test (Release), then builds and runs them
# again under AddressSanitizer + UndefinedBehaviorSanitizer. The Python module
# is built and its pytest suite run in the Release build only.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
jobs=$(nproc)

echo "== Release build and tests"
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DFATHOM_WERROR=ON -DFATHOM_BUILD_BENCH=ON
cmake --build build --parallel "$jobs"
ctest --test-dir build --output-on-failure --parallel "$jobs"

echo "== Python tests (the module in build/python, Debian's python3)"
if [ -d build/python/fathom ]; then
  status=0
  PYTHONPATH=build/python /usr/bin/python3 -m pytest -q -p no:cacheprovider python/tests || status=$?
  if [ "$status" -eq 5 ]; then
    echo "pytest collected no tests"  # exit code 5: not a failure
  elif [ "$status" -ne 0 ]; then
    exit "$status"
  fi
else
  echo "the Python module was not built (FATHOM_BUILD_PYTHON=OFF): no Python tests"
fi

echo "== ASan + UBSan build and tests (SIMD lanes unfused: the scalar code's bits)"
# -Og -g1: line tables for the sanitizers' reports; -Og compiles the
# instrumented code in half of -O1's time and its tests run about a tenth
# longer (docs/development.md). FATHOM_SIMD_FMA=OFF: the Release build's
# kernels fuse multiply-adds and its tests check them against the scalar code
# within tolerances; here every SIMD test asks for the scalar code's bits
# (tests/simd_check.h). Highway targets: the scalar fallback (its gathers are
# plain loads, which AddressSanitizer checks) and AVX-512's eight lanes; the
# Release build tests SSE4's two and AVX2's four against the scalar code.
# The tests run as 8 GoogleTest shards per core: an instrumented process
# takes about 0.6 s to start.
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-Og -g1" \
  -DFATHOM_SANITIZE=ON -DFATHOM_WERROR=ON -DFATHOM_BUILD_PYTHON=OFF -DFATHOM_SIMD_FMA=OFF \
  -DFATHOM_HWY_DISABLED_TARGETS="HWY_SSSE3|HWY_SSE4|HWY_AVX2" -DFATHOM_TEST_SHARDS=$((8 * jobs))
cmake --build build-asan --parallel "$jobs"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build-asan --output-on-failure --parallel "$jobs"
