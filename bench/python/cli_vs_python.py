#!/usr/bin/python3
"""Times `fathom render SCENE` (a CLI process) against fathom.render_scene and fathom.render
(in process) on the bundled CT scene, alternating them so that they see the same load
(docs/python.md, "Measured").

    PYTHONPATH=build/python python3 bench/python/cli_vs_python.py [REPEATS]
"""
import statistics
import subprocess
import sys
import tempfile
import time

import fathom

scene, cli = "examples/lidc2-bone.json", "build/fathom"
reps = int(sys.argv[1]) if len(sys.argv) > 1 else 5
vol = fathom.load_volume("data/lidc2.nrrd")
tf = fathom.TransferFunction.preset("ct-bone", vol)
cam = fathom.Camera.orbit(90, 10, 2.6, volume=vol)
times = {"cli": [], "render_scene": [], "render": []}
with tempfile.TemporaryDirectory() as tmp:
    for _ in range(reps):
        t = time.perf_counter()
        subprocess.run([cli, "render", scene, "-q", "-o", f"{tmp}/cli.pfm"], check=True)
        times["cli"].append(time.perf_counter() - t)
        t = time.perf_counter()
        a = fathom.render_scene(scene)
        times["render_scene"].append(time.perf_counter() - t)
        t = time.perf_counter()
        b = fathom.render(vol, tf, cam, width=512, height=512, integrator="preintegrated", step=0.5)
        times["render"].append(time.perf_counter() - t)
for name, ts in times.items():
    print(f"{name:13s} median {statistics.median(ts):.3f} s  (min {min(ts):.3f}, max {max(ts):.3f})")
print("render == render_scene:", bool((a == b).all()))
