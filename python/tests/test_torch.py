"""fathom.torch: gradcheck in float64, agreement with a pure-PyTorch alpha quadrature, errors."""
import numpy as np
import pytest

import fathom

torch = pytest.importorskip("torch")
import fathom.torch as ft  # noqa: E402  (needs torch)


def grids(n=4, dtype=torch.float64, seed=0):
    g = torch.Generator().manual_seed(seed)
    density = (0.2 + 0.8 * torch.rand((n, n, n), generator=g, dtype=dtype)).requires_grad_()
    color = torch.rand((n, n, n, 3), generator=g, dtype=dtype).requires_grad_()
    return density, color


def camera(n=4, az=30.0, el=25.0, distance=2.2):
    c = (n - 1) / 2.0
    return fathom.Camera.orbit(az, el, distance, center=(c, c, c), radius=np.sqrt(3) * c)


@pytest.mark.parametrize("integrator", ["alpha", "riemann", "preintegrated", "preintegrated-simple"])
def test_gradcheck_grids(integrator):
    density, color = grids()
    cam = camera()
    fn = lambda d, c: ft.render_grids(d, c, cam, width=6, height=5, integrator=integrator,  # noqa: E731
                                      termination=0.0, step=0.7)
    assert torch.autograd.gradcheck(fn, (density, color), eps=1e-6, atol=1e-8, rtol=1e-6)


def test_gradcheck_scalar_volume_and_tf():
    g = torch.Generator().manual_seed(1)
    # Values inside one linear piece of the TF (knots at 0, 0.5, 1): no kink in reach of the finite differences.
    volume = (0.1 + 0.3 * torch.rand((4, 4, 4), generator=g, dtype=torch.float64)).requires_grad_()
    tf = fathom.TransferFunction.from_arrays(extinction=[[0, 0.2], [0.5, 2.0], [1, 0.5]],
                                             color=[[0, 1, 0.2, 0.1], [1, 0.1, 0.5, 1]])
    alpha = torch.tensor(tf.alpha_points[:, 1], dtype=torch.float64, requires_grad=True)
    color = torch.tensor(tf.color_points[:, 1:], dtype=torch.float64, requires_grad=True)
    cam = camera()
    for integrator in ("alpha", "preintegrated"):
        fn = lambda v, a, c: ft.render_tf(v, tf, cam, alpha=a, color=c, width=6, height=5,  # noqa: E731
                                          integrator=integrator, termination=0.0)
        assert torch.autograd.gradcheck(fn, (volume, alpha, color), eps=1e-6, atol=1e-8, rtol=1e-6)


def reference_alpha(density, color, origins, dirs, step):
    """The alpha quadrature in pure PyTorch (SPEC §5) over a unit lattice [0, n-1]^3 at the origin:
    uniform segments of each ray's span in the box, one trilinear sample at each segment's near
    end, alpha_i = 1 - exp(-sigma_i delta), C = sum T_(i-1) alpha_i c_i, alpha = 1 - T (black
    background, no early termination). Returns (rays, 4)."""
    n = density.shape[0]
    hi = float(n - 1)
    with torch.no_grad():
        safe = torch.where(dirs == 0, torch.full_like(dirs, 1e-300), dirs)
        ta, tb = (0.0 - origins) / safe, (hi - origins) / safe
        t0 = torch.clamp(torch.minimum(ta, tb).max(dim=1).values, min=0.0)
        t1 = torch.maximum(ta, tb).min(dim=1).values
        hit = t1 > t0
        length = torch.where(hit, t1 - t0, torch.zeros_like(t0))
        segs = torch.clamp(torch.ceil(length / step), min=1).long()
        delta = length / segs
        j = torch.arange(int(segs.max()), dtype=torch.float64)
        valid = (j[None, :] < segs[:, None]) & hit[:, None]
        p = origins[:, None, :] + (t0[:, None] + j[None, :] * delta[:, None])[..., None] * dirs[:, None, :]
        p = torch.clamp(p, 0.0, hi)
        i0 = torch.clamp(torch.floor(p).long(), max=n - 2)
        f = p - i0
    flat_d, flat_c = density.reshape(-1), color.reshape(-1, 3)
    sigma = torch.zeros(p.shape[:2], dtype=torch.float64)
    col = torch.zeros(p.shape[:2] + (3,), dtype=torch.float64)
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                w = ((f[..., 0] if dx else 1 - f[..., 0]) * (f[..., 1] if dy else 1 - f[..., 1]) *
                     (f[..., 2] if dz else 1 - f[..., 2]))
                k = (i0[..., 0] + dx) + n * ((i0[..., 1] + dy) + n * (i0[..., 2] + dz))  # x fastest
                sigma = sigma + w * flat_d[k]
                col = col + w[..., None] * flat_c[k]
    tau = sigma * delta[:, None] * valid
    alpha = 1.0 - torch.exp(-tau)
    t_before = torch.exp(-(torch.cumsum(tau, dim=1) - tau))
    radiance = ((t_before * alpha)[..., None] * col).sum(dim=1)
    return torch.cat([radiance, (1.0 - torch.exp(-tau.sum(dim=1)))[:, None]], dim=1)


def test_agrees_with_pure_pytorch_alpha_quadrature():
    n, w, h, step = 6, 9, 7, 0.6
    density, color = grids(n, seed=2)
    cam = camera(n, az=40, el=15, distance=4.5)
    ours = ft.render_grids(density, color, cam, width=w, height=h, integrator="alpha", step=step,
                           termination=0.0)
    o, d = cam.rays(w, h)
    ref = reference_alpha(density, color, torch.from_numpy(o.reshape(-1, 3)), torch.from_numpy(d.reshape(-1, 3)),
                          step).reshape(h, w, 4)
    assert ref[..., 3].max() > 0.5 and ref[..., 3].min() == 0.0  # the volume and the background are both seen
    assert torch.allclose(ours, ref, rtol=0, atol=1e-12)
    weights = torch.rand((h, w, 4), generator=torch.Generator().manual_seed(5), dtype=torch.float64)
    g_ours = torch.autograd.grad((ours * weights).sum(), (density, color))
    g_ref = torch.autograd.grad((ref * weights).sum(), (density, color))
    for a, b in zip(g_ours, g_ref):
        assert (a - b).abs().max() <= 1e-10 * b.abs().max()


def test_forward_is_the_renderers_image():
    density, color = grids(5, seed=4)
    cam = camera(5)
    kw = dict(width=11, height=9, integrator="preintegrated", step=0.4)
    ours = ft.render_grids(density, color, cam, **kw)
    d = fathom.Volume.from_array(density.detach().numpy())
    c = fathom.Volume.from_array(color.detach().numpy())
    # DiffRenderer's forward is Renderer's front to back without skipping and SIMD, bit for bit (in double).
    img = fathom.render(d, c, cam, no_skip_empty=True, no_simd=True, **kw)
    assert torch.equal(ours.float(), torch.from_numpy(img))


def test_float32_in_float32_out():
    density, color = grids(dtype=torch.float32)
    img = ft.render_grids(density, color, camera(), width=6, height=5, integrator="alpha")
    assert img.dtype == torch.float32
    img.sum().backward()
    assert density.grad.dtype == torch.float32 and color.grad.shape == (4, 4, 4, 3)
    assert density.grad.abs().max() > 0


def test_jitter_and_spacing_reach_the_op():
    density, color = grids()
    cam = camera()
    plain = ft.render_grids(density, color, cam, width=6, height=5, integrator="alpha")
    jittered = ft.render_grids(density, color, cam, width=6, height=5, integrator="alpha", jitter=True)
    assert not torch.equal(plain, jittered)
    d = fathom.Volume.from_array(density.detach().numpy(), spacing=(0.5, 0.5, 0.5))
    c = fathom.Volume.from_array(color.detach().numpy(), spacing=(0.5, 0.5, 0.5))
    scaled = ft.render_grids(density, color, cam, width=6, height=5, integrator="alpha", jitter=True,
                             spacing=(0.5, 0.5, 0.5), no_skip_empty=True, no_simd=True)
    img = fathom.render(d, c, cam, width=6, height=5, integrator="alpha", jitter=True, no_skip_empty=True,
                        no_simd=True)
    assert torch.equal(scaled.float(), torch.from_numpy(img))


def test_errors():
    density, color = grids()
    cam = camera()
    with pytest.raises(ValueError, match=r"color: shape \(4, 4, 4\)"):
        ft.render_grids(density, density, cam, width=4, height=4)
    with pytest.raises(ValueError, match="same lattice"):
        ft.render_grids(density, torch.rand((4, 4, 5, 3), dtype=torch.float64), cam, width=4, height=4)
    with pytest.raises(TypeError, match="float32 or float64"):
        ft.render_grids(torch.ones((4, 4, 4), dtype=torch.int32), color, cam, width=4, height=4)
    with pytest.raises(TypeError, match="torch.Tensor"):
        ft.render_grids(density.detach().numpy(), color, cam, width=4, height=4)
    with pytest.raises(fathom.Error, match="shading is not differentiable"):
        ft.render_grids(density, color, cam, width=4, height=4, shade=True)
    with pytest.raises(fathom.Error, match="reference integrator"):
        ft.render_grids(density, color, cam, width=4, height=4, integrator="reference")
    tf = fathom.TransferFunction.preset("grayscale")
    with pytest.raises(ValueError, match="alpha values"):
        ft.render_tf(density, tf, cam, alpha=torch.zeros(9, dtype=torch.float64), width=4, height=4)
