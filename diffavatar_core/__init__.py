"""DiffAvatar core: differentiable XPBD cloth simulation and asset recovery (C++ core + thin
Python layer). Usable without ROS. SI units inside (m, kg, s); convert at the edges.
"""
import os

# OpenMP threads that sleep instead of spinning between parallel regions: on a shared 2-core
# machine spinning workers steal the CPU from the thread with the work (a 1,167-vertex t-shirt:
# 20 XPBD steps 7.5 s spinning vs 1.8–2.4 s passive, same run). Set before libgomp loads with
# _core; an explicit OMP_WAIT_POLICY in the environment wins.
os.environ.setdefault("OMP_WAIT_POLICY", "passive")

from . import _core  # noqa: E402
from ._core import CancelToken, Cancelled, ProgressEvent  # noqa: E402
from .metrics import (chamfer_meshes, chamfer_points, mesh_quality, nearest_point_distances,
                      sample_surface, surface_distances, triangle_quality)

__all__ = [
    "CancelToken", "Cancelled", "ProgressEvent",
    "chamfer_meshes", "chamfer_points", "mesh_quality", "nearest_point_distances",
    "sample_surface", "surface_distances", "triangle_quality",
    "set_num_threads", "num_threads",
]


def set_num_threads(n: int) -> None:
    """Sets the number of OpenMP threads the core uses (results are deterministic for a fixed count)."""
    if int(n) < 1:
        raise ValueError(f"num_threads must be >= 1, got {n}")
    _core.set_num_threads(int(n))


def num_threads() -> int:
    """The number of OpenMP threads the core uses."""
    return _core.openmp_max_threads()
