"""Builds fathom's Python module with CMake for `pip install --no-build-isolation .` (docs/python.md).

The module (target fathom_python) is built in build-pip/ (configured with the tests off),
or, when FATHOM_BUILD_DIR names an existing CMake build tree, there without reconfiguring it.
"""
import os
import pathlib
import re
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = pathlib.Path(__file__).resolve().parent
VERSION = re.search(r"project\(fathom VERSION ([0-9.]+)", (ROOT / "CMakeLists.txt").read_text()).group(1)


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        build = os.environ.get("FATHOM_BUILD_DIR")
        if build:
            build = pathlib.Path(build).resolve()
            if not (build / "CMakeCache.txt").exists():
                sys.exit(f"FATHOM_BUILD_DIR={build} is not a configured CMake build tree")
        else:
            build = ROOT / "build-pip"
            subprocess.check_call(["cmake", "-S", str(ROOT), "-B", str(build), "-G", "Ninja",
                                   "-DCMAKE_BUILD_TYPE=Release", "-DFATHOM_BUILD_TESTS=OFF",
                                   "-DFATHOM_BUILD_PYTHON=ON", f"-DPython3_EXECUTABLE={sys.executable}"])
        subprocess.check_call(["cmake", "--build", str(build), "--target", "fathom_python",
                               "--parallel", str(os.cpu_count() or 1)])
        built = sorted((build / "python" / "fathom").glob("_fathom*.so"))
        if not built:
            sys.exit(f"no _fathom module in {build}/python/fathom")
        target = pathlib.Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(built[-1], target)
        # fathom's OpenVDB and DICOM modules, loaded from beside the extension
        for module in ("fathom-vdb.so", "fathom-dicom.so"):
            shutil.copy2(build / "python" / "fathom" / module, target.parent / module)


setup(
    version=VERSION,
    packages=["fathom"],
    package_dir={"fathom": "python/fathom"},
    ext_modules=[Extension("fathom._fathom", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    # setuptools' own build folder, away from CMake's build/.
    options={"build": {"build_base": "build-pip/setuptools"}},
    zip_safe=False,
)
