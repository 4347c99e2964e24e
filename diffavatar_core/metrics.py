"""Geometric metrics: triangle conditioning quality (paper Table 1, Shewchuk 2002) and
symmetric Chamfer distances. All distances are in the input's units."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import _core
from . import _validate as val


def triangle_quality(vertices, faces) -> np.ndarray:
    """q = 3A / (l1² + l2² + l3²) per triangle: √3/4 ≈ 0.433 equilateral, 0 degenerate.

    vertices: (V, 3) or (V, 2) (a 2D pattern); faces: (F, 3) indices. Returns (F,) floats.
    Degenerate faces are allowed here (that is what the metric measures).
    """
    V = np.asarray(vertices, dtype=np.float64)
    dims = V.shape[1] if V.ndim == 2 else 3
    V = val.points("vertices", V, dims=dims if dims in (2, 3) else 3)
    if dims == 2:
        V = np.ascontiguousarray(np.column_stack([V, np.zeros(len(V))]))
    F = np.asarray(faces)
    if F.ndim != 2 or F.shape[1] != 3 or F.shape[0] == 0:
        raise ValueError(f"faces: expected shape (F, 3) with F > 0, got {F.shape}")
    if F.min() < 0 or F.max() >= len(V):
        raise ValueError(f"faces: index out of range [0, {len(V)})")
    return _core.triangle_quality(V, np.ascontiguousarray(F, dtype=np.int32))


@dataclass(frozen=True)
class MeshQuality:
    """Summary of triangle_quality over a mesh (dimensionless; best possible 0.433)."""
    min: float
    mean: float

    def as_dict(self) -> dict:
        return {"mesh_quality_min": self.min, "mesh_quality_avg": self.mean}


def mesh_quality(vertices, faces) -> MeshQuality:
    """Minimum and mean triangle quality of a mesh."""
    q = triangle_quality(vertices, faces)
    return MeshQuality(float(q.min()), float(q.mean()))


def sample_surface(vertices, faces, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """n area-uniform random points on the surface and the triangle each lies in (seeded)."""
    V, F = val.mesh("vertices", vertices, "faces", faces)
    return _core.sample_surface(V, F, val.positive_int("n", n), int(seed))


def nearest_point_distances(a, b, progress=None, cancel=None) -> np.ndarray:
    """Distance from each point of a (N, 3) to its nearest point of b (M, 3)."""
    return _core.nearest_point_distances(val.points("a", a), val.points("b", b), progress, cancel)


def surface_distances(points, vertices, faces, progress=None, cancel=None) -> np.ndarray:
    """Distance from each of points (N, 3) to the nearest point on the triangle mesh surface."""
    V, F = val.mesh("vertices", vertices, "faces", faces)
    return _core.surface_distances(val.points("points", points), V, F, progress, cancel)


def chamfer_points(a, b, progress=None, cancel=None) -> float:
    """Symmetric Chamfer distance between point sets: ½(mean NN(a→b) + mean NN(b→a))."""
    return _core.chamfer_points(val.points("a", a), val.points("b", b), progress, cancel)


def chamfer_meshes(va, fa, vb, fb, samples: int = 20000, seed: int = 0, progress=None, cancel=None) -> float:
    """Symmetric Chamfer distance between two surfaces: `samples` area-uniform points on each,
    each measured to the nearest point of the other *surface*; the two means averaged.
    A mesh against itself gives 0; units of the inputs."""
    VA, FA = val.mesh("va", va, "fa", fa)
    VB, FB = val.mesh("vb", vb, "fb", fb)
    return _core.chamfer_meshes(VA, FA, VB, FB, val.positive_int("samples", samples), int(seed),
                                progress, cancel)
