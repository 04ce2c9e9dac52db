"""Builds the extension mgcloth._mgcloth with the project's CMake (only the Python target) for the interpreter
running this script, and puts it in the wheel next to python/mgcloth/. Used by `pip install --no-build-isolation .`;
the metadata is in pyproject.toml.

Environment:
  MGCLOTH_BUILD_DIR    CMake build folder (default: a folder under setuptools' build/ temp; kept between
                       installs, so a reinstall rebuilds only what changed)
  MGCLOTH_CMAKE_ARGS   extra configure arguments, e.g. "-DMGCLOTH_CUDA=OFF"
  CMAKE_BUILD_PARALLEL_LEVEL   parallel jobs (default: all cores)
"""
import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        build_dir = Path(os.environ.get("MGCLOTH_BUILD_DIR") or Path(self.build_temp).resolve() / "cmake")
        configure = [
            "cmake", "-S", str(ROOT), "-B", str(build_dir), "-DCMAKE_BUILD_TYPE=Release",
            "-DMGCLOTH_PYTHON=ON", f"-DPython3_EXECUTABLE={sys.executable}",
            "-DMGCLOTH_BUILD_TESTS=OFF", "-DMGCLOTH_BUILD_BENCH=OFF",
            *shlex.split(os.environ.get("MGCLOTH_CMAKE_ARGS", "")),
        ]
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL") or str(os.cpu_count() or 1)
        subprocess.run(configure, check=True)
        subprocess.run(["cmake", "--build", str(build_dir), "--target", "mgcloth_python", "-j", jobs], check=True)
        built = sorted((build_dir / "python" / "mgcloth").glob("_mgcloth*.so"))
        if not built:
            raise RuntimeError(f"the CMake build left no _mgcloth*.so in {build_dir / 'python' / 'mgcloth'}")
        target = Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(built[-1], target)


setup(
    ext_modules=[Extension("mgcloth._mgcloth", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    # setuptools' own build/ would land in the CMake build folder of the same name.
    options={"build": {"build_base": "build/pip"}},
)
