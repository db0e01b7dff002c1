#!/usr/bin/python3
"""Reconstruction with the torch op: density and color grids fitted to 8 target views of a
small volume by torch.optim.Adam through fathom's C++ forward and backward passes.

    PYTHONPATH=build/python python3 python/examples/reconstruct.py [STEPS]
"""
import sys
import time

import numpy as np
import torch

import fathom
import fathom.torch as ft

n, size = 16, 48  # a 16^3 lattice, 48x48 views
z, y, x = np.meshgrid(*[np.linspace(-1, 1, n)] * 3, indexing="ij")  # numpy (nz, ny, nx)
ball = np.exp(-4 * ((x - 0.2) ** 2 + y ** 2 + z ** 2))
truth_density = torch.tensor(3.0 * ball)
truth_color = torch.tensor(np.stack([ball, 0.3 + 0 * x, 1 - ball], axis=-1))
c = (n - 1) / 2
cameras = [fathom.Camera.orbit(45 * i, 20 * (-1) ** i, 2.5, center=(c, c, c), radius=np.sqrt(3) * c)
           for i in range(8)]
opts = dict(width=size, height=size, integrator="alpha", step=1.0)
targets = [ft.render_grids(truth_density, truth_color, cam, **opts) for cam in cameras]

density = torch.full((n, n, n), 0.1, dtype=torch.float64, requires_grad=True)
color = torch.full((n, n, n, 3), 0.5, dtype=torch.float64, requires_grad=True)
optimizer = torch.optim.Adam([density, color], lr=0.05)
steps = int(sys.argv[1]) if len(sys.argv) > 1 else 150
start = time.perf_counter()
for step in range(steps + 1):
    optimizer.zero_grad()
    loss = sum(((ft.render_grids(density, color, cam, **opts) - t) ** 2).mean()
               for cam, t in zip(cameras, targets)) / len(cameras)
    loss.backward()
    optimizer.step()
    with torch.no_grad():  # keep the medium physical
        density.clamp_(min=0)
        color.clamp_(0, 1)
    if step % 25 == 0:
        psnr = 10 * np.log10(1 / loss.item())
        print(f"step {step:4d}  loss {loss.item():.3e}  PSNR {psnr:5.1f} dB  ({time.perf_counter() - start:.1f} s)")
print(f"density error: {(density - truth_density).abs().mean().item():.3f} mean abs (truth mean "
      f"{truth_density.mean().item():.3f})")
