"""Builds the Python package otmpm with the project's CMake, for `pip install .`
(pyproject.toml). The package is the one of python/otmpm, and beside its .py
files it holds what CMake installs for it: the module _otmpm, the library
(otmpm/lib), the otmpm command (otmpm/bin: otmpm.study and otmpm.pair run it)
and the scripts the command runs (otmpm/share/otmpm). RPATHs are relative,
so the package works wherever pip puts it.

Environment:
  OTMPM_PIP_BUILD_DIR  the CMake build folder (default: build-pip in the
                       source tree, beside build/: a second `pip install .`
                       rebuilds only what changed, and ccache with a base
                       folder serves it the files build/ compiled)
  OTMPM_CMAKE_ARGS     further CMake arguments (e.g. -DOTMPM_MPI=OFF)
  CMAKE_BUILD_PARALLEL_LEVEL  compile jobs (default: the number of cores)
"""
import os
import shlex
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

SOURCE = os.path.dirname(os.path.abspath(__file__))


class CMakeBuild(build_ext):
    """Configures, builds and installs the CMake project into the package folder of the wheel."""

    def build_extension(self, ext):
        build = os.environ.get("OTMPM_PIP_BUILD_DIR") or os.path.join(SOURCE, "build-pip")
        staging = os.path.join(os.path.abspath(self.build_temp), "otmpm-install")
        package = os.path.dirname(os.path.abspath(self.get_ext_fullpath(ext.name)))
        # the package's layout: otmpm/{*.py, _otmpm*.so, lib/, bin/, share/otmpm/}
        layout = ["-DOTMPM_PYTHON_INSTALL_DIR=.", "-DCMAKE_INSTALL_LIBDIR=otmpm/lib",
                  "-DCMAKE_INSTALL_BINDIR=otmpm/bin", "-DCMAKE_INSTALL_DATADIR=otmpm/share"]
        options = ["-DCMAKE_BUILD_TYPE=Release", "-DOTMPM_PYTHON=ON", "-DOTMPM_BUILD_TESTS=OFF",
                   "-DOTMPM_BUILD_BENCH=OFF", f"-DPython3_EXECUTABLE={sys.executable}"]
        extra = shlex.split(os.environ.get("OTMPM_CMAKE_ARGS", ""))
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL") or str(os.cpu_count() or 1)
        print(f"otmpm: building with CMake in {build} ({jobs} jobs; the first build takes minutes)", flush=True)
        subprocess.check_call(["cmake", "-S", SOURCE, "-B", build, *options, *layout, *extra])
        subprocess.check_call(["cmake", "--build", build, "-j", jobs, "--target", "otmpm_python", "otmpm_cli"])
        shutil.rmtree(staging, ignore_errors=True)
        subprocess.check_call(["cmake", "--install", build, "--prefix", staging])
        shutil.rmtree(package, ignore_errors=True)
        # the package folder only: not the C++ headers and CMake files (include/, lib/cmake)
        shutil.copytree(os.path.join(staging, "otmpm"), package, symlinks=True,
                        ignore=lambda folder, names: ["cmake"] if os.path.basename(folder) == "lib" else
                        ["__pycache__"])


# setuptools' own staging folders go beside the CMake build, not into build/ (scripts/test.sh's)
setup(ext_modules=[Extension("otmpm._otmpm", sources=[])], cmdclass={"build_ext": CMakeBuild},
      options={"build": {"build_base": os.path.join(SOURCE, "build-pip", "setuptools")}})
