"""fathom's differentiable renderer as PyTorch autograd functions.

    import fathom, fathom.torch
    cam = fathom.Camera.orbit(30, 20, 3.0, center=(1.5, 1.5, 1.5), radius=2.6)
    img = fathom.torch.render_grids(density, color, cam, width=64, height=64, integrator="alpha")
    img[..., :3].mean().backward()          # density.grad, color.grad from the C++ backward pass

Tensors are CPU tensors, float32 or float64, in fathom's axis order: density
(nz, ny, nx), color (nz, ny, nx, 3), x fastest. The C++ side integrates and
differentiates in double precision whatever the tensors' type; the image and
the gradients come back in the inputs' dtype (float64 inputs: exact to double
rounding, as torch.autograd.gradcheck needs). The keywords are the render
flags of fathom.render (width=, height=, integrator=, step=, model=, order=,
termination=, sample_point=, jitter=, background=, crop=, clip_plane=,
threads=); shading, gradient opacity, the projection and isosurface models
and the reference integrator are not differentiable and are refused
(fathom.Error). The rendering and the backward pass run without the GIL.
"""
import torch

from . import _fathom

__all__ = ["render_grids", "render_tf"]


def _array(t):
    """A C-contiguous numpy array over (a CPU copy of) a tensor's values."""
    return t.detach().cpu().contiguous().numpy()


def _grad(g, like):
    return torch.from_numpy(g).to(dtype=like.dtype, device=like.device)


class _RenderGrids(torch.autograd.Function):
    @staticmethod
    def forward(ctx, density, color, camera, spacing, origin, options):
        job = _fathom._DiffRender.grids(_array(density), _array(color), spacing, origin, camera, **options)
        ctx.job = job
        return torch.from_numpy(job.forward()).to(dtype=density.dtype, device=density.device)

    @staticmethod
    def backward(ctx, grad_image):
        density, color = ctx.needs_input_grad[:2]
        g = ctx.job.backward(_array(grad_image.to(torch.float64)))
        return (_grad(g["density"], grad_image) if density else None,
                _grad(g["color"], grad_image) if color else None, None, None, None, None)


class _RenderTf(torch.autograd.Function):
    @staticmethod
    def forward(ctx, volume, alpha, color, tf, camera, spacing, origin, options):
        job = _fathom._DiffRender.scalar_tf(_array(volume), tf, _array(alpha.to(torch.float64)),
                                            _array(color.to(torch.float64)), spacing, origin, camera,
                                            **options)
        ctx.job = job
        return torch.from_numpy(job.forward()).to(dtype=alpha.dtype, device=alpha.device)

    @staticmethod
    def backward(ctx, grad_image):
        want_volume, want_alpha, want_color = ctx.needs_input_grad[:3]
        g = ctx.job.backward(_array(grad_image.to(torch.float64)), want_scalar=want_volume)
        return (_grad(g["scalar"], grad_image) if want_volume else None,
                _grad(g["tf_alpha"], grad_image) if want_alpha else None,
                _grad(g["tf_color"], grad_image) if want_color else None, None, None, None, None, None)


def render_grids(density, color, camera, *, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0), **options):
    """Renders pre-classified grids: density sigma (nz, ny, nx) in 1/world unit and RGB color
    (nz, ny, nx, 3), node-centred, node (i, j, k) at origin + spacing * (i, j, k).

    Returns an (H, W, 4) tensor (linear RGB and alpha, row 0 at the top) in density's dtype,
    differentiable with respect to density and color."""
    _check_tensor(density, "density")
    _check_tensor(color, "color")
    return _RenderGrids.apply(density, color, camera, tuple(spacing), tuple(origin), options)


def render_tf(volume, tf, camera, *, alpha=None, color=None, spacing=(1.0, 1.0, 1.0),
              origin=(0.0, 0.0, 0.0), **options):
    """Renders a scalar volume (nz, ny, nx) classified by a fathom.TransferFunction.

    alpha: (N,) tensor of the TF's alpha values as written (opacity, or extinction for an
    extinction TF), one per alpha point; color: (M, 3) tensor, one RGB per color point.
    Either may be omitted (the TF's own values, no gradient). The control points' scalar
    positions stay those of tf. Returns (H, W, 4) in alpha's dtype (float64 when neither is
    given), differentiable with respect to volume (float32 or float64), alpha and color."""
    _check_tensor(volume, "volume")
    if alpha is None:
        alpha = torch.as_tensor(tf.alpha_points[:, 1], dtype=torch.float64)
    if color is None:
        color = torch.as_tensor(tf.color_points[:, 1:], dtype=alpha.dtype)
    _check_tensor(alpha, "alpha")
    _check_tensor(color, "color")
    return _RenderTf.apply(volume, alpha, color, tf, camera, tuple(spacing), tuple(origin), options)


def _check_tensor(t, name):
    if not isinstance(t, torch.Tensor):
        raise TypeError(f"{name} must be a torch.Tensor, got {type(t).__name__}")
    if t.device.type != "cpu":
        raise ValueError(f"{name} is on {t.device}: fathom renders on the CPU (pass {name}.cpu())")
