#!/usr/bin/python3
"""A matplotlib figure without Jupyter: the bundled CT in three models and a slice of its
numpy view (matplotlib is optional: Debian's python3-matplotlib).

    PYTHONPATH=build/python python3 python/examples/figure.py [OUT.png]
"""
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import fathom  # noqa: E402

root = pathlib.Path(__file__).resolve().parents[2]
volume = fathom.load_volume(root / "data" / "lidc2.nrrd")
camera = fathom.Camera.orbit(90, 10, 2.6, volume=volume)
views = {
    "ct-bone, emission-absorption": dict(tf="ct-bone"),
    "ct-skin, shaded": dict(tf="ct-skin", shade=True),
    "grayscale, maximum intensity": dict(tf="grayscale", model="mip"),
}
fig, axes = plt.subplots(1, 4, figsize=(16, 4.4))
for ax, (title, kw) in zip(axes, views.items()):
    tf = fathom.TransferFunction.preset(kw.pop("tf"), volume)
    image = fathom.render(volume, tf, camera, width=320, height=320, **kw)
    ax.imshow(np.clip(image[..., :3], 0, 1) ** (1 / 2.2))  # linear radiance → display gamma
    ax.set_title(title)
    ax.axis("off")
k = volume.shape[0] // 2  # numpy (nz, ny, nx): one axial slice, a view of the C++ samples
axes[3].imshow(volume.array[k], cmap="gray", origin="lower")
axes[3].set_title(f"slice k={k} of volume.array")
axes[3].axis("off")
fig.tight_layout()
out = sys.argv[1] if len(sys.argv) > 1 else "lidc2-figure.png"
fig.savefig(out, dpi=80)
print(f"wrote {out}")
