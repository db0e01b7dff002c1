#!/usr/bin/env python3
"""The fraction of this machine's sampling peak each integrator reaches.

Alternates, RUNS times, the SIMD interpolation's peak (the
`roofline_trilinear_simd` microbenchmark of fathom_bench: the inner loop
alone, its data in L1/L2) with `fathom bench` frames of each integrator that
evaluate every sample (`--no-skip-empty --termination 0`, 1 thread), and
prints per integrator the evaluated samples/s and their fraction of the peak
measured beside them (each run against its own peak measurement, so the
machine's drift cancels as far as it can), as a Markdown table.

  bench/roofline.py [--runs 10] [--volume data/lidc2.nrrd] [--preset ct-soft-tissue]
                    [--integrators alpha,preintegrated,preintegrated-simple]

fathom_bench needs a build configured with -DFATHOM_BUILD_BENCH=ON.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def peak(bench):
    out = subprocess.run(
        [bench, "--benchmark_filter=^roofline_trilinear_simd$", "--benchmark_min_time=1", "--benchmark_format=json"],
        check=True, capture_output=True, text=True).stdout
    return json.loads(out)["benchmarks"][0]["samples/s"]


def frames(fathom, args, integrator):
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "bench.json")
        subprocess.run(
            [fathom, "bench", "--volume", args.volume, "--preset", args.preset, "--orbit", args.orbit,
             "--width", str(args.size), "--height", str(args.size), "--frames", str(args.frames),
             "--integrator", integrator, "--threads", "1", "--no-skip-empty", "--termination", "0",
             "--json", path],
            check=True, capture_output=True, text=True)
        with open(path, encoding="utf-8") as f:
            return json.load(f)["segments_per_second"]


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=10)
    p.add_argument("--fathom", default=os.path.join(ROOT, "build", "fathom"))
    p.add_argument("--bench", default=os.path.join(ROOT, "build", "bench", "fathom_bench"))
    p.add_argument("--volume", default=os.path.join(ROOT, "data", "lidc2.nrrd"))
    p.add_argument("--preset", default="ct-soft-tissue")
    p.add_argument("--orbit", default="90,10,2.6")
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--frames", type=int, default=5)
    p.add_argument("--integrators", default="alpha,preintegrated,preintegrated-simple")
    args = p.parse_args()
    for tool in (args.fathom, args.bench):
        if not os.access(tool, os.X_OK):
            sys.exit(f"roofline.py: {tool} not found (build with -DFATHOM_BUILD_BENCH=ON)")
    integrators = args.integrators.split(",")
    peaks, rates, fractions = [], {i: [] for i in integrators}, {i: [] for i in integrators}
    for run in range(args.runs):
        for integrator in integrators:
            top = peak(args.bench)
            rate = frames(args.fathom, args, integrator)
            peaks.append(top)
            rates[integrator].append(rate)
            fractions[integrator].append(rate / top)
        print(f"run {run + 1}/{args.runs}: " +
              ", ".join(f"{i} {100 * fractions[i][-1]:.0f} %" for i in integrators), file=sys.stderr)

    def m(x):
        return x / 1e6

    print(f"SIMD sampling peak: {m(min(peaks)):.0f}–{m(max(peaks)):.0f} M samples/s "
          f"(median {m(statistics.median(peaks)):.0f} M, {len(peaks)} measurements)\n")
    print("| integrator | evaluated samples/s | of the peak beside it |")
    print("|---|---:|---:|")
    for i in integrators:
        r, f = rates[i], fractions[i]
        print(f"| {i} | {m(min(r)):.0f}–{m(max(r)):.0f} M (median {m(statistics.median(r)):.0f} M) | "
              f"{100 * min(f):.0f}–{100 * max(f):.0f} % (median **{100 * statistics.median(f):.0f} %**) |")


if __name__ == "__main__":
    main()
