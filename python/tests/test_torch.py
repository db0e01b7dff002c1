"""fathom.torch: gradcheck in float64, agreement with a pure-PyTorch alpha quadrature, errors."""
import sys

import numpy as np
import pytest

import fathom
from conftest import ROOT

torch = pytest.importorskip("torch")
import fathom.torch as ft  # noqa: E402  (needs torch)

# The project's pure-PyTorch alpha quadrature (SPEC §5; autograd through trilinear sampling by
# index math), which bench/peers/torch also checks fathom's C++ gradients against.
sys.path.insert(0, str(ROOT / "bench" / "peers" / "torch"))
from torch_alpha import render as reference_alpha  # noqa: E402


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


def test_agrees_with_pure_pytorch_alpha_quadrature():
    n, w, h, step = 6, 9, 7, 0.6
    density, color = grids(n, seed=2)
    cam = camera(n, az=40, el=15, distance=4.5)
    ours = ft.render_grids(density, color, cam, width=w, height=h, integrator="alpha", step=step,
                           termination=0.0)
    o, d = cam.rays(w, h)
    rays = torch.from_numpy(np.concatenate([o, d], axis=2).reshape(-1, 6))
    ref = reference_alpha(density, color, rays, n, step).reshape(h, w, 4)
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
