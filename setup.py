"""Builds the rephoto Python package offline: `python3 -m pip install --no-build-isolation .`

Why setuptools driving CMake: scikit-build-core is not packaged in Debian 12 and PyPI may be
unreachable; setuptools, wheel and pybind11 are Debian packages. The extension is one CMake
target (python/CMakeLists.txt) of the same build as the library and CLI, so it is built with
exactly their flags. REPHOTO_BUILD_DIR selects the CMake build folder (default:
build/python-ext); pointing it at an existing build (scripts/test.sh uses ./build) reuses its
compiled libraries, so installing takes seconds.
"""
import os
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent


def project_version() -> str:
    for line in (ROOT / "CMakeLists.txt").read_text().splitlines():
        if line.startswith("project(rephoto VERSION"):
            return line.split("VERSION")[1].split()[0]
    raise RuntimeError("CMakeLists.txt: no project version")


class CMakeBuild(build_ext):
    def build_extension(self, ext: Extension) -> None:
        build_dir = Path(os.environ.get("REPHOTO_BUILD_DIR", ROOT / "build" / "python-ext"))
        if not build_dir.is_absolute():
            build_dir = ROOT / build_dir
        # The real interpreter, not the venv link: the build folder outlives venvs.
        configure = ["cmake", "-S", str(ROOT), "-B", str(build_dir),
                     "-DREPHOTO_BUILD_PYTHON=ON", f"-DPython_EXECUTABLE={os.path.realpath(sys.executable)}"]
        if not (build_dir / "CMakeCache.txt").exists():
            configure += ["-G", "Ninja", "-DCMAKE_BUILD_TYPE=Release",
                          "-DREPHOTO_BUILD_TESTS=OFF", "-DREPHOTO_BUILD_BENCHMARKS=OFF"]
        subprocess.run(configure, check=True, stdout=subprocess.DEVNULL)
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL", "2")
        subprocess.run(["cmake", "--build", str(build_dir), "--target", "_rephoto", "-j", jobs],
                       check=True)
        built = next((build_dir / "python" / "rephoto").glob("_rephoto*.so"))
        target = Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(built, target)


setup(
    name="rephoto",
    version=project_version(),
    description="Evaluate 3D reconstructions by virtual rephotography (C++ library bindings)",
    packages=["rephoto"],
    package_dir={"": "python"},
    ext_modules=[Extension("rephoto._rephoto", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    python_requires=">=3.9",
    install_requires=["numpy"],
    extras_require={"pandas": ["pandas"], "plot": ["matplotlib"]},
    zip_safe=False,
)
