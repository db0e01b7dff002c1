"""fathom: direct volume rendering from Python (docs/python.md).

The C++ core one import away::

    import fathom
    vol = fathom.load_volume("data/lidc2.nrrd")
    tf = fathom.TransferFunction.preset("ct-bone", vol)
    cam = fathom.Camera.orbit(30, 10, 2.6, volume=vol)
    img = fathom.render(vol, tf, cam, width=256, height=256)   # float32 (H, W, 4)
    fathom.save_image("chest.png", img)

Axis convention: a volume's numpy array has shape (nz, ny, nx) (or
(nz, ny, nx, C)), x the fastest axis, as the samples lie in the file;
Volume.dims, spacing and origin are (x, y, z). Volume.array is a view of the
C++ storage, never a copy.

The PyTorch autograd functions are in fathom.torch (imports torch).
"""
from ._fathom import (  # noqa: F401
    Camera,
    Error,
    TransferFunction,
    Volume,
    __version__,
    load_volume,
    render,
    render_scene,
    save_image,
    save_volume,
)

__all__ = [
    "Camera",
    "Error",
    "TransferFunction",
    "Volume",
    "load_volume",
    "render",
    "render_scene",
    "save_image",
    "save_volume",
]
