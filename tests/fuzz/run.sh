#!/usr/bin/env bash
# Builds the libFuzzer targets with clang and runs each for SECONDS (default
# 60) on a seed corpus made from the shared real files (../shared/data) and
# the test suite's small files. Findings are written to build-fuzz/findings/.
#   tests/fuzz/run.sh [SECONDS] [READER...]
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds=${1:-60}
shift || true
readers=("$@")
[ ${#readers[@]} -eq 0 ] && readers=(nrrd metaimage slc vtk vti nifti nifti_gz dicom vdb raw)
CXX=${CXX:-clang++} cmake -S tests/fuzz -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
ninja -C build-fuzz $(printf 'fuzz_%s ' "${readers[@]}")
data=../shared/data
corpus=build-fuzz/corpus
mkdir -p build-fuzz/findings
seed() {  # seed READER FILE...: small files (at most 1 MiB) go in whole, larger ones as their first 64 KiB
    local r=$1
    shift
    mkdir -p "$corpus/$r"
    for f in "$@"; do
        [ -f "$f" ] || continue
        head -c 1048576 "$f" >"$corpus/$r/$(basename "$f")"
    done
}
seed nrrd "$data"/sim_and_small_vtkdata/headsq/quarter.nhdr
seed slc "$data"/sim_and_small_vtkdata/neghip.slc
seed vtk "$data"/sim_and_small_vtkdata/ironProt.vtk
seed vti "$data"/sim_and_small_vtkdata/hydrogen.vti
seed nifti_gz "$data"/mri_colin27_ch2better/*.nii.gz
seed vdb "$data"/vdb_wdas_cloud/*.vdb
seed dicom "$data"/sim_and_small_vtkdata/dicom_stack_cptac/*
mkdir -p "$corpus/nifti"
for f in "$data"/mri_colin27_ch2better/*.nii.gz; do
    [ -f "$f" ] && { gzip -dc "$f" | head -c 1048576 >"$corpus/nifti/$(basename "$f" .gz)" || true; }
done
for r in metaimage raw; do mkdir -p "$corpus/$r"; done
# attached gzip data (two members), so that the inflate path is fuzzed from the start
{ printf 'NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: gzip\n\n'
  seq 1 20 | head -c 32 | gzip -c; seq 21 40 | head -c 32 | gzip -c; } >"$corpus/nrrd/attached_gzip.nrrd"
# A huge allocation must throw std::bad_alloc, as it does without ASan (the
# readers turn it into an error), not abort the run.
export ASAN_OPTIONS=${ASAN_OPTIONS:-allocator_may_return_null=1}
failed=()
for r in "${readers[@]}"; do
    echo "== fuzz_$r for ${seconds}s"
    # OpenVDB 10 leaks the node it was reading when a tree fails to read
    # (docs/formats.md): not fathom's, so leaks are not findings there.
    leaks=1
    [ "$r" = vdb ] && leaks=0
    ./build-fuzz/fuzz_"$r" -max_total_time="$seconds" -rss_limit_mb=4096 -max_len=1048576 \
        -detect_leaks=$leaks -artifact_prefix=build-fuzz/findings/"$r"- "$corpus/$r" || failed+=("$r")
done
if [ ${#failed[@]} -gt 0 ]; then
    echo "== findings in: ${failed[*]} (build-fuzz/findings/)"
    exit 1
fi
echo "== no findings"
