"""Interior samples of a garment region: area-uniform surface points (the C++ sampler,
diffavatar_core.metrics.sample_surface) at least a margin away from every boundary loop, so
the interior loss does not double-count what the boundary loss matches."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .. import metrics


def _densify(loops: list[np.ndarray], spacing: float) -> np.ndarray:
    """Points along the closed polylines, every segment split into pieces ≤ spacing (m)."""
    if not loops:
        return np.zeros((0, 3))
    A = np.concatenate(loops)
    D = np.concatenate([np.roll(P, -1, axis=0) - P for P in loops])
    k = np.maximum(1, np.ceil(np.linalg.norm(D, axis=1) / spacing).astype(np.int64))
    seg = np.repeat(np.arange(len(A)), k)
    t = (np.arange(k.sum()) - np.repeat(np.cumsum(k) - k, k)) / np.repeat(k, k)
    return A[seg] + t[:, None] * D[seg]


def interior_samples(V: np.ndarray, F: np.ndarray, loops: list[np.ndarray], n: int, margin: float,
                     seed: int = 0, max_rounds: int = 8) -> np.ndarray:
    """Up to n area-uniform samples (n×3, m) of the surface (V (N, 3) m, F (M, 3)) whose
    distance to every polyline of `loops` (each (K, 3), closed) is at least `margin` (m).
    Deterministic for a seed; fewer than n only if the band within `margin` of the boundary
    covers almost all of the surface (the caller warns)."""
    spacing = margin / 4.0
    dense = _densify(loops, spacing) if margin > 0 else np.zeros((0, 3))
    tree = cKDTree(dense) if len(dense) else None
    Fi = np.ascontiguousarray(F, dtype=np.int32)
    Vd = np.ascontiguousarray(V, dtype=np.float64)
    kept = []
    total = 0
    for r in range(max_rounds):
        P, _ = metrics.sample_surface(Vd, Fi, 2 * n, seed=seed + r)
        if tree is not None:
            d, _ = tree.query(P)
            P = P[d >= margin + 0.5 * spacing]  # true distance ≥ KD distance − spacing/2
        kept.append(P)
        total += len(P)
        if total >= n:
            break
    return np.concatenate(kept)[:n]
