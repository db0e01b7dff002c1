"""Shared fixtures of the Python tests (docs/python.md, "Tests").

Run from the repository root after building:
    PYTHONPATH=build/python python3 -m pytest -q python/tests
"""
import json
import os
import pathlib
import shutil
import subprocess

import numpy as np
import pytest

import fathom

ROOT = pathlib.Path(__file__).resolve().parents[2]
SHARED_DATA = ROOT.parent / "shared" / "data"


def find_cli():
    """The fathom CLI: $FATHOM_CLI, the build tree the module was imported from, or PATH."""
    if os.environ.get("FATHOM_CLI"):
        return pathlib.Path(os.environ["FATHOM_CLI"])
    beside = pathlib.Path(fathom.__file__).resolve().parents[2] / "fathom"  # build/python/fathom → build/fathom
    if beside.is_file():
        return beside
    found = shutil.which("fathom")
    return pathlib.Path(found) if found else None


@pytest.fixture(scope="session")
def cli():
    path = find_cli()
    if path is None:
        pytest.skip("the fathom CLI was not found (build it, or set FATHOM_CLI)")
    return path


def read_pfm(path):
    """A PFM file (SPEC §6: 'PF', W H, -1.0 little-endian, rows bottom to top) as (H, W, 3) float32."""
    data = pathlib.Path(path).read_bytes()
    header = []
    pos = 0
    while len(header) < 4:  # "PF", W, H, scale: whitespace-separated tokens
        while data[pos:pos + 1].isspace():
            pos += 1
        end = pos
        while not data[end:end + 1].isspace():
            end += 1
        header.append(data[pos:end].decode())
        pos = end
    pos += 1  # the single whitespace after the scale
    assert header[0] == "PF", header
    w, h, scale = int(header[1]), int(header[2]), float(header[3])
    dtype = "<f4" if scale < 0 else ">f4"
    img = np.frombuffer(data, dtype=dtype, count=w * h * 3, offset=pos).reshape(h, w, 3)
    return img[::-1].astype(np.float32)


def cli_render(cli, scene, out, *flags):
    """`fathom render SCENE -o OUT.pfm FLAGS` read back as (H, W, 3)."""
    subprocess.run([str(cli), "render", str(scene), "-o", str(out), "-q", *map(str, flags)], check=True,
                   capture_output=True)
    return read_pfm(out)


def blob(shape=(12, 14, 16), dtype=np.uint8):
    """A smooth off-centre blob with values 0..200, numpy shape (nz, ny, nx)."""
    z, y, x = np.meshgrid(*[np.linspace(-1, 1, n) for n in shape], indexing="ij")
    v = 200.0 * np.exp(-3.0 * ((x - 0.2) ** 2 + 1.5 * y ** 2 + (z + 0.1) ** 2))
    return v.astype(dtype)


@pytest.fixture
def blob_scene(tmp_path):
    """A raw uint8 blob and a fathom-scene/1 file over it (ct-bone preset, orbit camera)."""
    a = blob()
    a.tofile(tmp_path / "blob.raw")
    scene = {
        "format": "fathom-scene/1",
        "volume": {"path": "blob.raw", "dims": [a.shape[2], a.shape[1], a.shape[0]], "dtype": "uint8",
                   "spacing": [1.0, 0.8, 1.25], "origin": [-3, 2, 1]},
        "transfer_function": {"preset": "ct-bone"},
        "camera": {"orbit": {"azimuth": 35, "elevation": 20, "distance": 2.5}},
        "render": {"width": 40, "height": 32},
    }
    path = tmp_path / "blob.json"
    path.write_text(json.dumps(scene))
    return path
