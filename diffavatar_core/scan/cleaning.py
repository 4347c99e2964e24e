"""Mesh cleaning for scans: duplicate-vertex merging, degenerate/duplicate triangle removal,
connected components and dropping of small floating fragments. Pure numpy/scipy (linear or
n log n in the mesh size; no per-element Python loops). Lengths in the units of V (m in the
core frame); every step keeps the surviving vertices and faces in their input order."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

#: Nearest distinct neighbours of a vertex looked at for merging (more within the tolerance only
#: in a collapsed cluster).
MERGE_NEIGHBOURS = 16


def merge_duplicate_vertices(V: np.ndarray, F: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Merges vertices closer than tol (transitively; a vertex with more than MERGE_NEIGHBOURS
    distinct points that close is joined to the nearest of them), keeping the lowest-index
    vertex of each group at its own position; O(N log N). V: (N, 3); F: (M, 3). Returns
    (V' (N', 3), F' (M, 3) remapped, old_to_new (N,)), N' ≤ N, survivors in input order."""
    n = V.shape[0]
    if tol <= 0 or n == 0:
        return V, F, np.arange(n)
    # Exact duplicates first (n log n), then, among the distinct points, each one's pairs within
    # tol from its MERGE_NEIGHBOURS nearest: all its pairs unless more points crowd within tol (a
    # collapsed cluster; what is left of it makes degenerate triangles, which cleaning drops).
    # query_pairs lists every pair: n²/2 of them for n vertices at one point (a hang).
    _, first, inverse = np.unique(V, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    m = len(first)
    k = min(MERGE_NEIGHBOURS, m)
    d, j = cKDTree(V[first]).query(V[first], k=k, distance_upper_bound=tol)
    d, j = d.reshape(m, k), j.reshape(m, k)
    near = np.isfinite(d) & (j != np.arange(m)[:, None])
    if not near.any() and m == n:
        return V, F, np.arange(n)
    G = sp.coo_matrix((np.ones(int(near.sum())), (np.nonzero(near)[0], j[near])), shape=(m, m))
    _, comp_unique = connected_components(G, directed=False)
    comp = comp_unique[inverse]
    rep = np.full(comp.max() + 1, n, dtype=np.int64)
    np.minimum.at(rep, comp, np.arange(n))      # lowest index of each group
    keep = np.zeros(n, bool)
    keep[rep] = True
    new_index = np.cumsum(keep) - 1
    old_to_new = new_index[rep[comp]]
    return V[keep], old_to_new[F], old_to_new


def triangle_areas(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(M,) triangle areas (units of V squared)."""
    e1 = V[F[:, 1]] - V[F[:, 0]]
    e2 = V[F[:, 2]] - V[F[:, 0]]
    return 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)


def degenerate_or_duplicate_faces(V: np.ndarray, F: np.ndarray, min_area: float) -> tuple[np.ndarray, int, int]:
    """Mask (M,) of faces to drop: a repeated vertex index or area ≤ min_area (degenerate), or
    the same vertex triple as an earlier face (duplicate). Returns (mask, #degenerate, #duplicate)."""
    rep = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 0] == F[:, 2])
    degenerate = rep | (triangle_areas(V, F) <= min_area)
    key = np.sort(F, axis=1)
    _, first = np.unique(key, axis=0, return_index=True)
    dup = np.ones(len(F), bool)
    dup[first] = False
    dup &= ~degenerate
    return degenerate | dup, int(degenerate.sum()), int(dup.sum())


def face_components(F: np.ndarray, n_vertices: int) -> tuple[int, np.ndarray]:
    """Connected components of a triangle mesh through shared vertices: (count, (M,) component
    id of each face)."""
    rows = np.concatenate([F[:, 0], F[:, 1]])
    cols = np.concatenate([F[:, 1], F[:, 2]])
    G = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_vertices, n_vertices))
    n, comp = connected_components(G, directed=False)
    return n, comp[F[:, 0]]


@dataclass(frozen=True)
class DroppedComponent:
    """A small connected part (area m², centroid m, core frame): removed as a floating fragment,
    or kept as a piece near the scan's large parts."""
    faces: int
    vertices: int
    area: float
    centroid: tuple[float, float, float]

    def describe(self) -> str:
        c = ", ".join(f"{x:.3f}" for x in self.centroid)
        return f"{self.faces} faces / {self.vertices} vertices, {self.area * 1e4:.3g} cm² at ({c}) m"


def small_components(V: np.ndarray, F: np.ndarray, min_fraction: float,
                     keep_fraction: float = 0.0) -> tuple[np.ndarray, list[DroppedComponent]]:
    """Faces of the connected parts whose area is below min_fraction × the largest part's area
    and, with keep_fraction > 0, none of whose vertices lies within keep_fraction × the largest
    part's bounding-box diagonal of a vertex of a larger part: such a small part near the large
    ones is a piece of the subject cut off by occlusion (a hand beyond a long sleeve's cuff, skin
    in a neckline), not a floating fragment. Relative, like min_fraction, so that a scan read in
    the wrong units is cleaned the same. Returns (mask (M,) of faces to drop, descriptions of the
    dropped parts, largest first)."""
    drop, dropped, _ = components_to_drop(V, F, min_fraction, keep_fraction)
    return drop, dropped


def components_to_drop(V: np.ndarray, F: np.ndarray, min_fraction: float, keep_fraction: float = 0.0):
    """small_components, also returning the descriptions of the small parts kept because they lie
    near the large parts: (drop mask (M,), dropped, kept near)."""
    n, comp = face_components(F, V.shape[0])
    area = triangle_areas(V, F)
    comp_area = np.bincount(comp, weights=area, minlength=n)
    has_faces = np.bincount(comp, minlength=n) > 0     # isolated vertices are no parts
    small = has_faces & (comp_area < min_fraction * comp_area.max())
    near = np.zeros(n, bool)
    if keep_fraction > 0 and small.any():
        large_v = np.unique(F[~small[comp]])
        largest = V[np.unique(F[comp == np.argmax(comp_area)])]
        keep_within = keep_fraction * float(np.linalg.norm(largest.max(axis=0) - largest.min(axis=0)))
        d, _ = cKDTree(V[large_v]).query(V[F[small[comp]]].reshape(-1, 3), distance_upper_bound=keep_within)
        close_faces = (d.reshape(-1, 3) < keep_within).any(axis=1)
        near[np.unique(comp[small[comp]][close_faces])] = True
    drop = (small & ~near)[comp]

    def describe(parts):
        out = []
        for c in parts[np.argsort(-comp_area[parts])]:
            fc = comp == c
            vids = np.unique(F[fc])
            w = area[fc]
            centers = V[F[fc]].mean(axis=1)
            centroid = (w @ centers) / w.sum() if w.sum() > 0 else centers.mean(axis=0)  # fc non-empty
            out.append(DroppedComponent(int(fc.sum()), len(vids), float(comp_area[c]),
                                        tuple(float(x) for x in centroid)))
        return out
    return drop, describe(np.flatnonzero(small & ~near)), describe(np.flatnonzero(near))


def compact(V: np.ndarray, F: np.ndarray, face_keep: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The sub-mesh of the kept faces with unreferenced vertices removed (order kept).
    Returns (V', F', kept_vertex_indices (N',) into V)."""
    Fk = F[face_keep]
    used = np.zeros(V.shape[0], bool)
    used[Fk.ravel()] = True
    new_index = np.cumsum(used) - 1
    return V[used], new_index[Fk], np.flatnonzero(used)
