#!/usr/bin/env python3
"""Before/after of two fathom builds on one frame, in alternating runs.

On a shared machine a build's frame time drifts by up to ±10 % between runs
and more over minutes, so docs/performance.md compares builds only in runs
that alternate: base, new, base, new, ... This runs `fathom bench` with the
same arguments for both binaries, PAIRS times in turn (each run its own
process, `--json` to a temporary file), and prints each build's medians and
the ratio base / new of every pair, with their median: the figure the
"What each optimisation bought" rows quote.

usage: bench/ab.py BASE NEW [--pairs N] -- BENCH-ARGS...

    cp build/fathom /tmp/fathom-base   # before the change
    ...                                # change, rebuild
    bench/ab.py /tmp/fathom-base build/fathom --pairs 3 -- \\
        --volume data/lidc2.nrrd --preset ct-bone --orbit 90,10,2.6 \\
        --width 512 --height 512 --threads 2 --frames 5 --integrator alpha
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile


def run_once(binary, args):
    """One `fathom bench` run: its median frame in seconds."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "run.json")
        proc = subprocess.run([binary, "bench", *args, "--json", out], capture_output=True, text=True)
        if proc.returncode != 0:
            sys.exit(f"{binary} bench failed ({proc.returncode}): {proc.stderr.strip()}")
        with open(out) as f:
            return float(json.load(f)["median_seconds"])


def alternate(pairs, first, second):
    """Runs first() and second() in turn, `pairs` times: their lists of results."""
    a, b = [], []
    for _ in range(pairs):
        a.append(first())
        b.append(second())
    return a, b


def report(first_label, first, second_label, second, ratio_label):
    """Prints both sides' frames and the ratio first / second of every pair, with their median."""
    width = max(len(first_label), len(second_label))
    ratios = [x / y for x, y in zip(first, second)]
    fmt = " / ".join
    print(f"{first_label:<{width}} {fmt(f'{t:.3f}' for t in first)} s")
    print(f"{second_label:<{width}} {fmt(f'{t:.3f}' for t in second)} s")
    print(f"{ratio_label} per pair {fmt(f'{r:.2f}' for r in ratios)}; median {statistics.median(ratios):.2f}x")


def main(argv):
    if "--" not in argv:
        sys.exit(__doc__.strip())
    cut = argv.index("--")
    p = argparse.ArgumentParser(description="Alternating before/after runs of `fathom bench`.")
    p.add_argument("base")
    p.add_argument("new")
    p.add_argument("--pairs", type=int, default=2, help="alternating pairs (default 2)")
    opts = p.parse_args(argv[:cut])
    bench_args = argv[cut + 1:]
    if opts.pairs < 1:
        sys.exit("--pairs must be at least 1")
    base, new = alternate(opts.pairs, lambda: run_once(opts.base, bench_args),
                          lambda: run_once(opts.new, bench_args))
    report("base", base, "new", new, "base / new")


if __name__ == "__main__":
    main(sys.argv[1:])
