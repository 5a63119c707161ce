"""Builds the `sonar3d` Python package with the project's CMake (pyproject.toml, docs/python.md).

    python3 -m pip install --no-build-isolation .

The extension sonar3d/_sonar3d is the CMake target `sonar3d_python`, linked against the static
sonar3d module libraries so the installed package depends only on Debian's shared libraries.
Environment:
  CMAKE_ARGS                  extra CMake arguments, e.g. "-DCMAKE_CXX_COMPILER_LAUNCHER=ccache"
  CMAKE_BUILD_PARALLEL_LEVEL  compile jobs (default: all cores)
  SONAR3D_CMAKE_BUILD_DIR     reuse this configured CMake build directory (e.g. build/) instead of
                              configuring a new one under build/pip/ (it must be configured for
                              this interpreter: -DPython3_EXECUTABLE)
"""
import os
import re
import shlex
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = os.path.dirname(os.path.abspath(__file__))


def project_version():
    with open(os.path.join(ROOT, "CMakeLists.txt"), encoding="utf-8") as f:
        m = re.search(r"project\(\s*sonar3d\s+VERSION\s+([0-9.]+)", f.read())
    if not m:
        raise RuntimeError("no project(sonar3d VERSION x.y.z) in CMakeLists.txt")
    return m.group(1)


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        if shutil.which("cmake") is None:
            raise RuntimeError("cmake not found: run scripts/install-deps.sh (Debian: cmake)")
        build_dir = os.environ.get("SONAR3D_CMAKE_BUILD_DIR")
        if build_dir:
            build_dir = os.path.abspath(build_dir)
            if not os.path.isfile(os.path.join(build_dir, "CMakeCache.txt")):
                raise RuntimeError("SONAR3D_CMAKE_BUILD_DIR=%s is not a configured CMake build"
                                   % build_dir)
        else:
            build_dir = os.path.abspath(os.path.join(self.build_temp, "cmake"))
            args = [
                "-DCMAKE_BUILD_TYPE=Release",
                "-DBUILD_SHARED_LIBS=OFF",
                "-DSONAR3D_BUILD_TESTS=OFF",
                "-DSONAR3D_BUILD_BENCH=OFF",
                "-DSONAR3D_BUILD_PYTHON=ON",
                "-DPython3_EXECUTABLE=" + sys.executable,
            ] + shlex.split(os.environ.get("CMAKE_ARGS", ""))
            subprocess.check_call(["cmake", "-S", ROOT, "-B", build_dir] + args)
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL") or str(os.cpu_count() or 1)
        subprocess.check_call(["cmake", "--build", build_dir, "--target", "sonar3d_python",
                               "--parallel", jobs])
        built = os.path.join(build_dir, "python", "sonar3d")
        suffix = self.get_ext_filename("x")[1:]  # .cpython-311-x86_64-linux-gnu.so
        names = [n for n in os.listdir(built) if n.startswith("_sonar3d.") and n.endswith(suffix)]
        if len(names) != 1:
            raise RuntimeError("expected one _sonar3d*%s in %s (built for another Python? "
                               "configure with -DPython3_EXECUTABLE=%s), found %s"
                               % (suffix, built, sys.executable, names))
        target = self.get_ext_fullpath(ext.name)
        os.makedirs(os.path.dirname(target), exist_ok=True)
        shutil.copyfile(os.path.join(built, names[0]), target)


os.makedirs(os.path.join(ROOT, "build", "pip"), exist_ok=True)
setup(
    version=project_version(),
    packages=["sonar3d"],
    package_dir={"sonar3d": "python/sonar3d"},
    ext_modules=[Extension("sonar3d._sonar3d", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    # Keep setuptools' own build files apart from the CMake build directory build/.
    options={"build": {"build_base": "build/pip"}, "egg_info": {"egg_base": "build/pip"}},
    zip_safe=False,
)
