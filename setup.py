"""DiffAvatar asset service: the C++ core (diffavatar_core._core, built with CMake), its Python
API/CLI (diffavatar_core) and the ROS 2 node (diffavatar_ros).

`make demo` / `make test` set everything up (scripts/bootstrap.sh); this file serves
`pip install .` and the editable install made by that script.
"""
import os
import pathlib
import shutil
import subprocess
import sys

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = pathlib.Path(__file__).resolve().parent


class CMakeBuild(build_ext):
    """Builds diffavatar_core/_core*.so with CMake + Ninja (or make) and places it in the package."""

    def build_extension(self, ext):
        core = ROOT / "diffavatar_core"
        build_dir = ROOT / "build" / "core"
        if os.environ.get("DIFFAVATAR_SKIP_CMAKE") != "1":
            generator = ["-G", "Ninja"] if shutil.which("ninja") else []
            if not (build_dir / "CMakeCache.txt").exists():
                subprocess.check_call(["cmake", "-S", str(core), "-B", str(build_dir), *generator,
                                       "-DCMAKE_BUILD_TYPE=Release", f"-DPython_EXECUTABLE={sys.executable}"])
            subprocess.check_call(["cmake", "--build", str(build_dir), "-j", str(os.cpu_count() or 2)])
        built = sorted(core.glob("_core*.so"))
        if not built:
            raise RuntimeError("diffavatar_core/_core*.so was not built")
        target = pathlib.Path(self.get_ext_fullpath(ext.name))
        if target.resolve() != built[-1].resolve():
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(built[-1], target)


setup(
    name="diffavatar",
    version="0.1.0",
    description="Simulation-ready garment, material and body recovery from segmented scans "
                "(DiffAvatar, CVPR 2024) as a ROS 2 asset service",
    license="Apache-2.0",
    python_requires=">=3.10",
    packages=["diffavatar_core", "diffavatar_core.commands", "diffavatar_core.pipeline",
              "diffavatar_core.scan", "diffavatar_ros"],
    package_data={"diffavatar_core": ["data/*"]},
    ext_modules=[Extension("diffavatar_core._core", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/diffavatar"]),
        ("share/diffavatar", ["package.xml"]),
        ("share/diffavatar/config", [str(p.relative_to(ROOT)) for p in sorted((ROOT / "config").glob("*.yaml"))]),
    ],
    entry_points={"console_scripts": ["diffavatar = diffavatar_core.cli:main",
                                      "diffavatar-node = diffavatar_ros.node:main"]},
    zip_safe=False,
)
