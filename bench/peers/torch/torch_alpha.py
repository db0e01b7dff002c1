#!/usr/bin/python3
"""The PyTorch reference of fathom's differentiable alpha quadrature.

Reads the problem bench/diff_peer.cpp wrote (density and color grids on a
unit lattice, rays, adjoints), evaluates the same alpha quadrature with
PyTorch autograd (CPU, float64): uniform segments of eq. (8) inside the box,
one trilinear sample at each segment's near end, alpha_i = 1 - exp(-sigma_i delta),
C = sum T_(i-1) alpha_i c_i, and the loss L = sum adjoint . (C, alpha), then
  - checks its forward results and gradients against fathom's, and
  - times forward + backward, reporting fathom's speed-up.
Usage: torch_alpha.py PROBLEM_DIR [THREADS] [REPEATS]
"""
import json
import sys
import time

import numpy as np
import torch


def load(d, name, shape):
    return torch.from_numpy(np.fromfile(f"{d}/{name}", dtype=np.float64).reshape(shape))


def render(density, color, rays, n, step):
    """Forward results (R, 4) of the alpha quadrature; autograd tracks the grids."""
    o, d = rays[:, :3], rays[:, 3:]
    hi = float(n - 1)
    # Box [0, n-1]^3, t >= 0 (as fathom's intersect_box).
    with torch.no_grad():
        safe = torch.where(d == 0, torch.full_like(d, 1e-300), d)
        ta, tb = (0.0 - o) / safe, (hi - o) / safe
        t_lo = torch.minimum(ta, tb)
        t_hi = torch.maximum(ta, tb)
        flat = d == 0
        inside = ((o >= 0) & (o <= hi)) | ~flat
        t_lo = torch.where(flat, torch.full_like(t_lo, -np.inf), t_lo)
        t_hi = torch.where(flat, torch.full_like(t_hi, np.inf), t_hi)
        t0 = torch.clamp(t_lo.max(dim=1).values, min=0.0)
        t1 = t_hi.min(dim=1).values
        hit = (t1 > t0) & inside.all(dim=1)
        length = torch.where(hit, t1 - t0, torch.zeros_like(t0))
        segs = torch.clamp(torch.ceil(length / step), min=1).long()
        delta = length / segs
        m = int(segs[hit].max()) if hit.any() else 1
        j = torch.arange(m, dtype=torch.float64)
        valid = (j[None, :] < segs[:, None]) & hit[:, None]
        t = t0[:, None] + j[None, :] * delta[:, None]
        p = o[:, None, :] + t[..., None] * d[:, None, :]
        p = torch.clamp(p, 0.0, hi)
        i0 = torch.clamp(torch.floor(p).long(), max=n - 2)
        f = p - i0
    flat_d = density.reshape(-1)
    flat_c = color.reshape(-1, 3)

    def idx(dx, dy, dz):
        return (i0[..., 0] + dx) + n * ((i0[..., 1] + dy) + n * (i0[..., 2] + dz))

    sigma = torch.zeros(p.shape[:2], dtype=torch.float64)
    col = torch.zeros(p.shape[:2] + (3,), dtype=torch.float64)
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                w = ((f[..., 0] if dx else 1 - f[..., 0]) * (f[..., 1] if dy else 1 - f[..., 1]) *
                     (f[..., 2] if dz else 1 - f[..., 2]))
                k = idx(dx, dy, dz)
                sigma = sigma + w * flat_d[k]
                col = col + w[..., None] * flat_c[k]
    tau = sigma * delta[:, None] * valid
    alpha = 1.0 - torch.exp(-tau)
    T_before = torch.exp(-(torch.cumsum(tau, dim=1) - tau))
    rgb = (T_before * alpha)[..., None] * col
    radiance = rgb.sum(dim=1)
    opacity = 1.0 - torch.exp(-tau.sum(dim=1))
    return torch.cat([radiance, opacity[:, None]], dim=1)


def main():
    d = sys.argv[1]
    threads = int(sys.argv[2]) if len(sys.argv) > 2 else 0
    repeats = int(sys.argv[3]) if len(sys.argv) > 3 else 3
    if threads > 0:
        torch.set_num_threads(threads)
    prob = json.load(open(f"{d}/problem.json"))
    n, rays_n = prob["n"], prob["rays"]
    density0 = load(d, "density.bin", (n, n, n))  # [k][j][i], x fastest
    color0 = load(d, "color.bin", (n, n, n, 3))
    rays = load(d, "rays.bin", (rays_n, 6))
    adj = load(d, "adjoints.bin", (rays_n, 4))
    times = []
    for _ in range(repeats):
        density = density0.clone().requires_grad_(True)
        color = color0.clone().requires_grad_(True)
        t = time.perf_counter()
        out = render(density, color, rays, n, prob["step"])
        loss = (out * adj).sum()
        loss.backward()
        times.append(time.perf_counter() - t)
    t = sorted(times)[len(times) // 2]
    fwd = load(d, "fathom_forward.bin", (rays_n, 4))
    gd = load(d, "fathom_grad_density.bin", (n, n, n))
    gc = load(d, "fathom_grad_color.bin", (n, n, n, 3))

    def rel(a, b):
        return float((a - b).abs().max() / max(float(b.abs().max()), 1e-300))

    report = {
        "torch_version": torch.__version__,
        "torch_threads": torch.get_num_threads(),
        "torch_seconds_median": t,
        "torch_rays_per_second": rays_n / t,
        "forward_max_rel_diff": rel(out.detach(), fwd),
        "grad_density_max_rel_diff": rel(density.grad, gd),
        "grad_color_max_rel_diff": rel(color.grad, gc),
        "speedup": t / prob["fathom_seconds_median"],
    }
    json.dump(report, open(f"{d}/torch_report.json", "w"), indent=2)
    print(f"torch {torch.__version__} ({torch.get_num_threads()} threads): forward+backward {t:.3f} s "
          f"(median of {repeats}): {rays_n / t:.0f} rays/s")
    print(f"fathom vs torch: forward max rel. diff {report['forward_max_rel_diff']:.2e}, "
          f"d/d density {report['grad_density_max_rel_diff']:.2e}, d/d color {report['grad_color_max_rel_diff']:.2e}")
    print(f"fathom is {report['speedup']:.1f}x faster (fathom {prob['fathom_seconds_median']:.3f} s)")
    ok = max(report["forward_max_rel_diff"], report["grad_density_max_rel_diff"],
             report["grad_color_max_rel_diff"]) < 1e-9
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
