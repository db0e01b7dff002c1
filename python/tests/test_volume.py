"""Volumes: the numpy view shares the C++ storage, axis order, dtypes, clear errors."""
import gc

import numpy as np
import pytest

import fathom
from conftest import ROOT, blob

DTYPES = ["uint8", "int8", "uint16", "int16", "uint32", "int32", "float32", "float64"]


def test_array_is_a_view_of_the_cpp_storage():
    v = fathom.Volume.from_array(blob())
    a, b = v.array, v.array
    assert np.shares_memory(a, b)  # two views, one buffer: the volume's own
    assert a.base is v  # the view keeps the volume alive
    assert a.flags.writeable and a.flags.c_contiguous
    a[...] = 7  # writing through the view changes what C++ reads
    assert v.value_range() == (7.0, 7.0)
    a[0, 0, 0] = 9
    assert v.value_range() == (7.0, 9.0)


def test_view_outlives_the_python_volume():
    v = fathom.Volume.from_array(np.arange(24, dtype=np.uint16).reshape(2, 3, 4))
    a = v.array
    del v
    gc.collect()
    assert a.tolist() == np.arange(24).reshape(2, 3, 4).tolist()


def test_from_array_copies_the_input_once():
    src = blob()
    v = fathom.Volume.from_array(src)
    assert not np.shares_memory(src, v.array)
    src[...] = 0
    assert v.value_range()[1] > 0


def test_loaded_volume_is_a_view_too():
    v = fathom.load_volume(ROOT / "data" / "lidc2.nrrd")
    a = v.array
    assert a.shape == (133, 256, 256) and v.dims == (256, 256, 133)  # numpy (nz, ny, nx); dims (x, y, z)
    assert a.dtype == np.uint8
    assert np.shares_memory(a, v.array)
    assert v.spacing == pytest.approx((1.40625, 1.40625, 2.5))
    assert (int(a.min()), int(a.max())) == tuple(int(x) for x in v.value_range())


@pytest.mark.parametrize("dtype", DTYPES)
def test_supported_dtypes_round_trip(dtype, tmp_path):
    a = (np.arange(60) % 50).astype(dtype).reshape(3, 4, 5)
    v = fathom.Volume.from_array(a, spacing=(0.5, 1, 2), origin=(1, 2, 3))
    assert v.dtype == np.dtype(dtype)
    assert v.array.dtype == np.dtype(dtype)
    np.testing.assert_array_equal(v.array, a)
    fathom.save_volume(tmp_path / "v.nrrd", v)
    w = fathom.load_volume(tmp_path / "v.nrrd")
    np.testing.assert_array_equal(w.array, a)
    assert w.spacing == pytest.approx((0.5, 1, 2)) and w.origin == pytest.approx((1, 2, 3))


def test_axis_convention_x_fastest():
    a = np.zeros((5, 3, 4), np.float32)  # nz=5, ny=3, nx=4
    a[3, 1, 1] = 1.0  # node (i=1, j=1, k=3)
    v = fathom.Volume.from_array(a, spacing=(1, 2, 3))
    assert v.dims == (4, 3, 5) and v.shape == (5, 3, 4)
    center, radius = v.bounds()
    assert center == pytest.approx((1.5, 2.0, 6.0))  # spacing·(dims−1)/2 along x, y, z
    # A ray along +z through node (1, 1, ·) at world (1, 2) meets the bright node; one at x = 2 sees nothing.
    tf = fathom.TransferFunction.from_arrays(extinction=[[0, 0], [1, 5]], color=[[0, 1, 1, 1]])

    def alpha_along_z(x, y):
        cam = fathom.Camera.look_at((x, y, -10), (x, y, 0), (0, 1, 0), projection="orthographic", height=1e-6)
        return fathom.render(v, tf, cam, width=1, height=1, integrator="alpha")[0, 0, 3]

    assert alpha_along_z(1, 2) > 0.5
    assert alpha_along_z(2, 2) == 0.0
    assert alpha_along_z(1, 4) == 0.0


def test_components_are_the_last_axis():
    rgb = np.random.default_rng(1).random((3, 4, 5, 3), dtype=np.float32)
    v = fathom.Volume.from_array(rgb)
    assert v.components == 3 and v.dims == (5, 4, 3) and v.array.shape == (3, 4, 5, 3)
    np.testing.assert_array_equal(v.array, rgb)


@pytest.mark.parametrize("dtype", ["float16", "int64", "uint64", "complex64", "bool", ">u2"])
def test_unsupported_dtype_is_a_type_error(dtype):
    with pytest.raises(TypeError, match="dtype .* is not supported"):
        fathom.Volume.from_array(np.zeros((2, 2, 2), dtype=dtype))


@pytest.mark.parametrize("shape", [(4,), (4, 4), (2, 2, 2, 2, 2), (2, 0, 2)])
def test_wrong_shape_is_a_value_error(shape):
    with pytest.raises(ValueError, match="shape"):
        fathom.Volume.from_array(np.zeros(shape, np.float32))


def test_non_contiguous_is_a_value_error():
    a = np.zeros((4, 4, 8), np.float32)
    for view in (a[:, :, ::2], a.transpose(2, 1, 0), np.asfortranarray(a)):
        with pytest.raises(ValueError, match="C-contiguous"):
            fathom.Volume.from_array(view)
    fathom.Volume.from_array(np.ascontiguousarray(a[:, :, ::2]))  # the fix the message names


def test_not_an_array_is_a_type_error():
    with pytest.raises(TypeError, match="numpy array"):
        fathom.Volume.from_array([[[1, 2], [3, 4]]])


def test_placement_properties():
    v = fathom.Volume.from_array(np.zeros((2, 2, 2), np.uint8))
    v.spacing = (1, 2, 3)
    v.origin = (4, 5, 6)
    assert v.spacing == (1, 2, 3) and v.origin == (4, 5, 6)
    np.testing.assert_array_equal(v.axes, np.diag([1.0, 2.0, 3.0]))
    with pytest.raises(ValueError):
        v.spacing = (1, 0, 1)
    with pytest.raises(fathom.Error, match="singular"):
        v.axes = np.zeros((3, 3))


def test_dicom_through_the_module_loads_gdcm_on_the_first_read(tmp_path):
    """DICOM goes through fathom-dicom.so beside the extension: GDCM is mapped
    only once a DICOM file is read, and its errors arrive as fathom.Error."""
    import subprocess
    import sys
    import zipfile

    from conftest import SHARED_DATA
    archive = SHARED_DATA / "sim_and_small_vtkdata" / "dicom_stack_cptac" / "data.zip"
    if not archive.exists():
        pytest.skip(f"{archive} not present (../shared/data beside the clone)")
    zipfile.ZipFile(archive).extractall(tmp_path)
    (tmp_path / "empty").mkdir()
    code = (
        "import sys, fathom\n"
        "gdcm = lambda: 'libgdcm' in open('/proc/self/maps').read()\n"
        "before = gdcm()\n"
        "try:\n"
        "    fathom.load_volume(sys.argv[2])\n"
        "except fathom.Error as e:\n"
        "    print('error', e)\n"
        "v = fathom.load_volume(sys.argv[1])\n"
        "print(before, gdcm(), v.array.shape)\n")
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path / "data"), str(tmp_path / "empty")],
                         check=True, capture_output=True, text=True).stdout.splitlines()
    assert out[0] == f"error {tmp_path / 'empty'}: no DICOM files in folder (it is empty)"
    assert out[1] == "False True (3, 512, 512)"
