"""Rendering: render_scene gives the CLI's pixels, render equals render_scene, errors, the GIL."""
import json
import threading
import time

import numpy as np
import pytest

import fathom
from conftest import ROOT, SHARED_DATA, blob, cli_render, read_pfm


@pytest.mark.parametrize("overrides, flags", [
    ({}, []),
    ({"integrator": "alpha", "step": 0.3}, ["--integrator", "alpha", "--step", 0.3]),
    ({"integrator": "riemann", "sample_point": "mid", "width": 24, "height": 20},
     ["--integrator", "riemann", "--sample-point", "mid", "--width", 24, "--height", 20]),
    ({"model": "absorption", "order": "back-to-front"}, ["--model", "absorption", "--order", "back-to-front"]),
    ({"model": "mip"}, ["--model", "mip"]),
    ({"shade": True, "phong": (0.2, 0.6, 0.3, 20)}, ["--shade", "--phong", "0.2,0.6,0.3,20"]),
    ({"iso": [(80, 1, 0.5, 0.2), (150,)]}, ["--iso", "80,1,0.5,0.2", "--iso", "150"]),
    ({"crop": (-3, 2, 1, 5, 12, 20), "clip_plane": (2, 6, 8, 1, 0.2, 0)},
     ["--crop", "-3,2,1,5,12,20", "--clip-plane", "2,6,8,1,0.2,0"]),
    ({"background": (0.1, 0.2, 0.3), "termination": 0.0, "step_unit": "world", "step": 0.7},
     ["--background", "0.1,0.2,0.3", "--termination", 0, "--step-unit", "world", "--step", 0.7]),
    ({"jitter": True, "jitter_seed": 7, "integrator": "alpha", "no_skip_empty": True, "no_simd": True},
     ["--jitter", "--jitter-seed", 7, "--integrator", "alpha", "--no-skip-empty", "--no-simd"]),
    ({"integrator": "alpha", "no_packets": True}, ["--integrator", "alpha", "--no-packets"]),
])
def test_render_scene_gives_the_cli_pixels(cli, blob_scene, tmp_path, overrides, flags):
    img = fathom.render_scene(blob_scene, **overrides)
    assert img.dtype == np.float32 and img.ndim == 3 and img.shape[2] == 4
    ref = cli_render(cli, blob_scene, tmp_path / "cli.pfm", *flags)
    assert img.shape[:2] == ref.shape[:2]
    assert img[..., :3].max() > 0 or overrides.get("model") == "absorption"
    np.testing.assert_array_equal(img[..., :3], ref)  # bit for bit


def test_packets_give_the_one_by_one_pixels(blob_scene):
    for integrator in ("alpha", "riemann"):
        packets = fathom.render_scene(blob_scene, integrator=integrator)
        one_by_one = fathom.render_scene(blob_scene, integrator=integrator, no_packets=True)
        assert packets[..., :3].max() > 0
        np.testing.assert_array_equal(packets, one_by_one)  # bit for bit


def test_render_equals_render_scene_for_the_same_scene(blob_scene):
    spec = json.loads(blob_scene.read_text())
    a = blob()
    vol = fathom.Volume.from_array(a, spacing=spec["volume"]["spacing"], origin=spec["volume"]["origin"])
    tf = fathom.TransferFunction.preset("ct-bone", vol)
    cam = fathom.Camera.orbit(35, 20, 2.5, volume=vol)
    for kw in ({}, {"integrator": "alpha", "step": 0.25}, {"model": "emission", "integrator": "riemann"}):
        mine = fathom.render(vol, tf, cam, width=40, height=32, **kw)
        np.testing.assert_array_equal(mine, fathom.render_scene(blob_scene, **kw))


def test_bundled_ct_scene_gives_the_cli_pixels(cli, tmp_path):
    scene = ROOT / "examples" / "lidc2-bone.json"
    img = fathom.render_scene(scene, width=48, height=40, step=1.0)
    ref = cli_render(cli, scene, tmp_path / "ct.pfm", "--width", 48, "--height", 40, "--step", 1.0)
    np.testing.assert_array_equal(img[..., :3], ref)
    assert img[..., 3].max() > 0.5  # the bone is there


def test_shared_volume_gives_the_cli_pixels(cli, tmp_path):
    path = SHARED_DATA / "sim_and_small_vtkdata" / "hydrogen.vti"
    if not path.exists():
        pytest.skip(f"{path} not present (../shared/data beside the clone)")
    scene = tmp_path / "h.json"
    scene.write_text(json.dumps({"format": "fathom-scene/1", "volume": {"path": str(path)},
                                 "transfer_function": {"preset": "grayscale"},
                                 "camera": {"orbit": {"azimuth": 20, "elevation": 30}}}))
    img = fathom.render_scene(scene, width=32, height=32, integrator="preintegrated-simple")
    np.testing.assert_array_equal(img[..., :3], cli_render(cli, scene, tmp_path / "h.pfm", "--width", 32,
                                                          "--height", 32, "--integrator",
                                                          "preintegrated-simple"))


def test_preclassified_grids_render():
    rng = np.random.default_rng(3)
    d = fathom.Volume.from_array(rng.random((5, 6, 7), dtype=np.float32))
    c = fathom.Volume.from_array(rng.random((5, 6, 7, 3), dtype=np.float32))
    cam = fathom.Camera.orbit(10, 20, volume=d)
    img = fathom.render(d, c, cam, width=16, height=12, integrator="alpha")
    assert img.shape == (12, 16, 4) and img[..., 3].max() > 0.1


def test_save_image_round_trips_pfm(tmp_path, blob_scene):
    img = fathom.render_scene(blob_scene)
    fathom.save_image(tmp_path / "out.pfm", img)
    np.testing.assert_array_equal(read_pfm(tmp_path / "out.pfm"), img[..., :3])
    fathom.save_image(tmp_path / "out.png", img, alpha=True)
    assert (tmp_path / "out.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(ValueError, match=r"\(H, W, 4\)"):
        fathom.save_image(tmp_path / "bad.png", np.zeros((4, 4)))


def test_errors_are_fathom_errors_with_the_file_name(tmp_path):
    missing = tmp_path / "nope.nrrd"
    with pytest.raises(fathom.Error, match="nope.nrrd") as e:
        fathom.load_volume(missing)
    assert isinstance(e.value, RuntimeError)
    assert e.value.subject.endswith("nope.nrrd") and e.value.reason
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "fathom-scene/1", "volume": {"path": "x.nrrd"}, "colour": 1}')
    with pytest.raises(fathom.Error, match=r"bad.json.*unknown key 'colour'"):
        fathom.render_scene(bad)
    tf = tmp_path / "tf.json"
    tf.write_text('{"format": "fathom-tf/1", "color": [[0, 1, 1, 1]], "opacity": [[1, 0], [0, 1]]}')
    with pytest.raises(fathom.Error, match="tf.json"):
        fathom.TransferFunction.from_json(tf)


def test_override_errors(blob_scene):
    with pytest.raises(TypeError, match="unexpected keyword argument 'colour'"):
        fathom.render_scene(blob_scene, colour=1)
    with pytest.raises(TypeError, match="width"):
        fathom.render_scene(blob_scene, width="wide")
    with pytest.raises(fathom.Error, match="simpson"):
        fathom.render_scene(blob_scene, integrator="simpson")
    with pytest.raises(fathom.Error, match="--crop expects"):
        fathom.render_scene(blob_scene, crop=(1, 2, 3))
    with pytest.raises(fathom.Error, match="step"):
        fathom.render_scene(blob_scene, step=-1)
    with pytest.raises(ValueError, match="transparent"):
        fathom.render_scene(blob_scene, background="white")
    vol = fathom.Volume.from_array(blob())
    with pytest.raises(TypeError, match="TransferFunction"):
        fathom.render(vol, "ct-bone", fathom.Camera.orbit(0, 0, volume=vol))


def test_render_releases_the_gil():
    vol = fathom.Volume.from_array(blob((48, 48, 48)))
    tf = fathom.TransferFunction.preset("ct-soft-tissue", vol)
    cam = fathom.Camera.orbit(30, 20, volume=vol)
    started = threading.Event()
    out = {}

    def work():
        started.set()
        t = time.perf_counter()
        out["img"] = fathom.render(vol, tf, cam, width=64, height=64, integrator="reference", threads=1)
        out["seconds"] = time.perf_counter() - t

    th = threading.Thread(target=work)
    th.start()
    started.wait()
    ticks = 0
    while th.is_alive():  # runs only while the render thread does not hold the GIL
        ticks += 1
    th.join()
    assert out["seconds"] > 0.05, "the render was too quick to tell"
    assert ticks > 10000, f"the main thread ran {ticks} loops during a {out['seconds']:.2f} s render"


def test_tf_and_camera_api(tmp_path):
    names = fathom.TransferFunction.preset_names()
    assert {"ct-bone", "ct-skin", "ct-soft-tissue", "mr-default", "grayscale"} <= set(names)
    tf = fathom.TransferFunction.from_arrays(opacity=[[0, 0], [100, 0.5]], color=[[0, 1, 0.5, 0], [100, 1, 1, 1]],
                                             name="mine")
    assert tf.alpha_kind == "opacity" and tf.name == "mine"
    np.testing.assert_array_equal(tf.alpha_points, [[0, 0], [100, 0.5]])
    np.testing.assert_array_equal(tf.color_points, [[0, 1, 0.5, 0], [100, 1, 1, 1]])
    (tmp_path / "tf.json").write_text(tf.to_json())
    again = fathom.TransferFunction.from_json(tmp_path / "tf.json")
    np.testing.assert_array_equal(again.color_points, tf.color_points)
    with pytest.raises(fathom.Error, match="from_arrays"):
        fathom.TransferFunction.from_arrays(opacity=[[0, 2]], color=[[0, 1, 1, 1]])  # a > 1
    with pytest.raises(ValueError, match=r"\(N, 4\)"):
        fathom.TransferFunction.from_arrays(opacity=[[0, 1]], color=[[0, 1, 1]])
    scaled = fathom.TransferFunction.preset("grayscale", (0, 1000))
    assert scaled.alpha_points[-1, 0] == pytest.approx(1000)

    cam = fathom.Camera.look_at((0, -5, 0), (0, 0, 0))
    assert cam.forward == pytest.approx((0, 1, 0)) and cam.up == pytest.approx((0, 0, 1))
    again = fathom.Camera.from_matrix(cam.to_matrix())
    np.testing.assert_allclose(again.to_matrix(), cam.to_matrix(), atol=1e-15)
    o, d = cam.rays(5, 4)
    assert o.shape == d.shape == (4, 5, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=2), 1.0)
    with pytest.raises(fathom.Error):
        fathom.Camera.look_at((0, 0, 0), (0, 0, 0))
    with pytest.raises(ValueError, match="volume="):
        fathom.Camera.orbit(0, 0)
    ortho = fathom.Camera.orbit(0, 90, center=(0, 0, 0), radius=2, projection="orthographic")
    assert ortho.projection == "orthographic" and ortho.height == pytest.approx(4)
