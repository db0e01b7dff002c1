#!/usr/bin/python3
"""Renders the bundled chest CT (data/lidc2.nrrd) with the ct-bone preset and saves a PNG.

    PYTHONPATH=build/python python3 python/examples/render_ct.py [OUT.png]
"""
import pathlib
import sys
import time

import fathom

root = pathlib.Path(__file__).resolve().parents[2]
volume = fathom.load_volume(root / "data" / "lidc2.nrrd")
print(f"{volume}: numpy {volume.array.shape} {volume.array.dtype}, spacing {volume.spacing}")
tf = fathom.TransferFunction.preset("ct-bone", volume)  # scaled to the volume's value range
camera = fathom.Camera.orbit(90, 10, 2.6, volume=volume)
start = time.perf_counter()
image = fathom.render(volume, tf, camera, width=512, height=512, integrator="preintegrated", step=0.5)
print(f"rendered {image.shape} in {time.perf_counter() - start:.2f} s")
out = sys.argv[1] if len(sys.argv) > 1 else "lidc2-bone.png"
fathom.save_image(out, image)
print(f"wrote {out}")
