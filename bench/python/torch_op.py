#!/usr/bin/python3
"""Times fathom.torch.render_grids forward and forward+backward (float64, 32^3 grids, 128x128)
and the pure-PyTorch alpha quadrature on the same problem (docs/python.md, "Measured").

    PYTHONPATH=build/python python3 bench/python/torch_op.py [TORCH_THREADS]
"""
import pathlib
import statistics
import sys
import time

import numpy as np
import torch

import fathom
import fathom.torch as ft

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "peers" / "torch"))
from torch_alpha import render as reference_alpha  # noqa: E402

n, w, h, reps, step = 32, 128, 128, 5, 0.5
if len(sys.argv) > 1:
    torch.set_num_threads(int(sys.argv[1]))
g = torch.Generator().manual_seed(0)
density = (0.05 * torch.rand((n, n, n), generator=g, dtype=torch.float64)).requires_grad_()
color = torch.rand((n, n, n, 3), generator=g, dtype=torch.float64).requires_grad_()
c = (n - 1) / 2
cam = fathom.Camera.orbit(30, 20, 2.5, center=(c, c, c), radius=np.sqrt(3) * c)


def median_time(f):
    ts = []
    for _ in range(reps):
        t = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts)


for integrator in ("alpha", "preintegrated"):
    opts = dict(width=w, height=h, integrator=integrator, step=step, termination=0.0)
    fwd = median_time(lambda: ft.render_grids(density, color, cam, **opts))
    both = median_time(lambda: ft.render_grids(density, color, cam, **opts).sum().backward())
    print(f"fathom.torch {integrator:14s} {n}^3, {w}x{h}: forward {fwd:.3f} s, forward+backward {both:.3f} s")
o, d = cam.rays(w, h)
rays = torch.from_numpy(np.concatenate([o, d], axis=2).reshape(-1, 6))
ref = median_time(lambda: reference_alpha(density, color, rays, n, step).sum().backward())
print(f"pure PyTorch alpha ({torch.get_num_threads()} threads): forward+backward {ref:.3f} s")
