"""Mesh file I/O at the edges of the core (trimesh underneath)."""
from __future__ import annotations

import pathlib

import numpy as np


def load_mesh(path: str | pathlib.Path) -> tuple[np.ndarray, np.ndarray]:
    """(V: (N, 3) float64, F: (M, 3) int64) of a triangle mesh file, vertices as stored (no
    merging, no reordering); raises ValueError naming the file if it holds no triangles."""
    import trimesh
    path = pathlib.Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    m = trimesh.load(str(path), force="mesh", process=False)
    if not hasattr(m, "faces") or len(m.faces) == 0:
        raise ValueError(f"{path}: holds no triangle mesh")
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


def save_mesh(path: str | pathlib.Path, V, F) -> None:
    """Writes a triangle mesh (format from the suffix: .obj, .ply, .stl ...)."""
    import trimesh
    trimesh.Trimesh(np.asarray(V), np.asarray(F), process=False).export(str(path))
