"""Mesh file I/O at the edges of the core (trimesh underneath)."""
from __future__ import annotations

import pathlib

import numpy as np


def load_mesh(path: str | pathlib.Path) -> tuple[np.ndarray, np.ndarray]:
    """(V: (N, 3) float64, F: (M, 3) int64) of a triangle mesh file, vertices as stored (no
    merging, no reordering); raises ValueError naming the file if it cannot be read or holds no
    triangles. A file starting with the PLY magic line is read as PLY whatever its name (a PLY
    saved as .obj read as OBJ held no triangles), as the scan reader reads it
    (scan.ply_reader.read_ply: faces and triangle strips; a face of fewer than 3 vertices is
    refused, not dropped)."""
    import trimesh
    path = pathlib.Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    if path.is_dir():
        raise ValueError(f"{path}: is a directory, not a mesh file")
    with open(path, "rb") as fh:
        is_ply = fh.read(5).startswith((b"ply\n", b"ply\r\n"))
    if is_ply:
        from .scan.ply_reader import read_ply
        ply = read_ply(path)   # ScanError (a ValueError) naming the file and the problem
        F = ply.faces
        if len(F) == 0:
            raise ValueError(f"{path}: holds no triangle mesh")
        return ply.vertices, F
    try:
        m = trimesh.load(str(path), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise ValueError(f"{path}: cannot be read as a triangle mesh ({type(exc).__name__}: {exc})") from None
    if not hasattr(m, "faces") or len(m.faces) == 0:
        raise ValueError(f"{path}: holds no triangle mesh")
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


def save_mesh(path: str | pathlib.Path, V, F) -> None:
    """Writes a triangle mesh (format from the suffix: .obj, .ply, .stl ...)."""
    import trimesh
    trimesh.Trimesh(np.asarray(V), np.asarray(F), process=False).export(str(path))
