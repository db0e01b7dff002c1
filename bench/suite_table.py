#!/usr/bin/env python3
"""Turns `fathom bench --json` files into the Markdown tables of
docs/performance.md: one row per run, then thread scaling (1 → 2 threads)
and what empty-space skipping buys (off → on), for runs that match.

Runs of the same configuration from several passes of the suite (e.g.
`bench/suite.sh full out/a` and `out/b`) are merged: each row keeps the pass
with the shortest median frame, so a burst of noise on a shared machine in
one pass does not stand in the tables.

usage: bench/suite_table.py RUN.json [RUN.json ...]
"""
import json
import os
import sys


def key(r, **override):
    k = dict(volume=os.path.basename(r["scene"]), size=f'{r["width"]}x{r["height"]}', step=r["step"],
             integrator=r["integrator"], preset=r.get("preset", ""), threads=r["threads"],
             skip=r.get("skip_empty", True))
    k.update(override)
    return tuple(sorted(k.items()))


def main(paths):
    runs = []
    for p in paths:
        with open(p) as f:
            runs.append(json.load(f))
    if not runs:
        sys.exit("suite_table: no runs")
    passes = {}
    for r in runs:
        passes.setdefault(key(r), []).append(r)
    by_key = {k: min(rs, key=lambda r: r["median_seconds"]) for k, rs in passes.items()}
    runs = sorted(by_key.values(),
                  key=lambda r: (r["scene"], r["width"], r["step"], r["integrator"], r.get("preset", ""),
                                 -r["threads"], not r.get("skip_empty", True)))
    print(f'Machine: {runs[0].get("cpu", "?")}, {runs[0].get("hardware_threads", "?")} hardware threads.')
    most = max(len(rs) for rs in passes.values())
    if most > 1:
        print(f'Each row: the shortest median frame of up to {most} passes.')
    print()
    print("| volume | image | step | integrator | preset | threads | skipping | median frame | "
          "samples/s | pixels/s | setup | peak RSS |")
    print("|---|---|---:|---|---|---:|---|---:|---:|---:|---:|---:|")
    for r in runs:
        print(f'| {os.path.basename(r["scene"])} | {r["width"]}² | {r["step"]} | {r["integrator"]} | '
              f'{r.get("preset", "")} | {r["threads"]} | {"on" if r.get("skip_empty", True) else "off"} | '
              f'{r["median_seconds"]:.3f} s | {r["segments_per_second"] / 1e6:.1f} M | '
              f'{r["pixels_per_second"] / 1e3:.0f} k | {r.get("setup_seconds", 0):.3f} s | '
              f'{r.get("peak_rss_bytes", 0) / 1e6:.0f} MB |')
    scaling = [(r, by_key.get(key(r, threads=1))) for r in runs if r["threads"] == 2]
    scaling = [(two, one) for two, one in scaling if one]
    if scaling:
        print("\nThread scaling (median frame, 1 → 2 threads):\n")
        print("| volume | integrator | preset | 1 thread | 2 threads | speed-up |")
        print("|---|---|---|---:|---:|---:|")
        for two, one in scaling:
            print(f'| {os.path.basename(two["scene"])} {two["width"]}² step {two["step"]} | {two["integrator"]} | '
                  f'{two.get("preset", "")} | {one["median_seconds"]:.3f} s | {two["median_seconds"]:.3f} s | '
                  f'{one["median_seconds"] / two["median_seconds"]:.2f}× |')
    skipping = [(r, by_key.get(key(r, skip=False))) for r in runs if r.get("skip_empty", True)]
    skipping = [(on, off) for on, off in skipping if off]
    if skipping:
        print("\nEmpty-space skipping (median frame, off → on; images identical):\n")
        print("| volume | integrator | preset | threads | off | on | speed-up |")
        print("|---|---|---|---:|---:|---:|---:|")
        for on, off in skipping:
            print(f'| {os.path.basename(on["scene"])} {on["width"]}² step {on["step"]} | {on["integrator"]} | '
                  f'{on.get("preset", "")} | {on["threads"]} | {off["median_seconds"]:.3f} s | '
                  f'{on["median_seconds"]:.3f} s | {off["median_seconds"] / on["median_seconds"]:.2f}× |')


if __name__ == "__main__":
    main(sys.argv[1:])
