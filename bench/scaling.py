#!/usr/bin/env python3
"""Thread scaling of one frame, in alternating runs.

bench/suite.sh times a configuration's 1-thread and 2-thread frames minutes
apart, so on a shared machine whose speed drifts between them their ratio
carries the drift (docs/performance-matrix.md, "Zen 5"). This runs `fathom
bench` with the same arguments on 1 thread and on 2 (or --threads A,B) in
turn, PAIRS times (each run its own process, `--json` to a temporary file),
and prints each side's median frames and the speed-up of every pair (the
frame on A threads over the frame on B), with their median.

usage: bench/scaling.py [--fathom BIN] [--pairs N] [--threads A,B] -- BENCH-ARGS...

    bench/scaling.py --pairs 6 -- --volume data/lidc2.nrrd --preset ct-bone \\
        --orbit 90,10,2.6 --width 512 --height 512 --frames 5 --integrator alpha

BENCH-ARGS must not set --threads.
"""
import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from ab import alternate, report, run_once  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main(argv):
    if "--" not in argv:
        sys.exit(__doc__.strip())
    cut = argv.index("--")
    p = argparse.ArgumentParser(description="Alternating 1- and 2-thread runs of `fathom bench`.")
    p.add_argument("--fathom", default=os.path.join(ROOT, "build", "fathom"))
    p.add_argument("--pairs", type=int, default=6, help="alternating pairs (default 6)")
    p.add_argument("--threads", default="1,2", help="the two thread counts, fewer first (default 1,2)")
    opts = p.parse_args(argv[:cut])
    bench_args = argv[cut + 1:]
    if opts.pairs < 1:
        sys.exit("--pairs must be at least 1")
    if any(a == "--threads" or a.startswith("--threads=") for a in bench_args):
        sys.exit("scaling.py sets --threads itself: leave it out of BENCH-ARGS")
    try:
        few, many = (int(t) for t in opts.threads.split(","))
    except ValueError:
        sys.exit(f"--threads wants two counts A,B, not '{opts.threads}'")
    if not 1 <= few < many:
        sys.exit(f"--threads wants 1 <= A < B, not '{opts.threads}'")
    a, b = alternate(opts.pairs, lambda: run_once(opts.fathom, [*bench_args, "--threads", str(few)]),
                     lambda: run_once(opts.fathom, [*bench_args, "--threads", str(many)]))
    report(f"{few} thread{'s' if few > 1 else ''}", a, f"{many} threads", b, "speed-up")


if __name__ == "__main__":
    main(sys.argv[1:])
