"""Quality triangulation of a sewing-pattern panel (a simple polygon in metres).

The boundary points are kept exactly as given (so seam-paired edges keep the vertex counts
chosen for them); interior points start on an equilateral lattice of spacing h and are relaxed by
repulsive edge springs with Delaunay re-triangulation (the force scheme of Persson & Strang 2004,
written here from the paper). Interior points are held at least ``0.5 h`` away from every
boundary segment, which makes every boundary segment a Gabriel edge, hence present in the
Delaunay triangulation of boundary + interior points: the triangles whose centroid lies inside
the polygon then tile it exactly (area equal to the polygon's to rounding).

Quality is q = 3A / (l1² + l2² + l3²) (√3/4 ≈ 0.433 equilateral), as metrics.triangle_quality.
Only numpy and scipy.spatial.Delaunay (BSD) are used.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay


def polygon_area(P: np.ndarray) -> float:
    """Signed area (m²) of a closed polygon P (N, 2), positive when counter-clockwise."""
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def points_in_polygon(Q: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Even-odd inside test of points Q (M, 2) against the closed polygon P (N, 2)."""
    a = P
    b = np.roll(P, -1, axis=0)
    qx = Q[:, 0:1]
    qy = Q[:, 1:2]
    cond = (a[None, :, 1] > qy) != (b[None, :, 1] > qy)
    with np.errstate(divide="ignore", invalid="ignore"):
        xint = a[None, :, 0] + (qy - a[None, :, 1]) * (b[None, :, 0] - a[None, :, 0]) / (b[None, :, 1] - a[None, :, 1])
    crossings = cond & (qx < xint)
    return (np.count_nonzero(crossings, axis=1) % 2) == 1


def _segment_distance(Q: np.ndarray, P: np.ndarray):
    """Distance of each point Q (M, 2) to the closed polyline P and the closest points (M, 2)."""
    a = P[None, :, :]
    d = (np.roll(P, -1, axis=0) - P)[None, :, :]
    dd = np.maximum(np.sum(d * d, axis=2), 1e-300)
    t = np.clip(np.sum((Q[:, None, :] - a) * d, axis=2) / dd, 0.0, 1.0)
    c = a + t[..., None] * d
    dist2 = np.sum((Q[:, None, :] - c) ** 2, axis=2)
    k = np.argmin(dist2, axis=1)
    rows = np.arange(len(Q))
    return np.sqrt(dist2[rows, k]), c[rows, k]


def triangle_quality_2d(X: np.ndarray, F: np.ndarray) -> np.ndarray:
    """q = 3A / Σl² per triangle of a 2D mesh (dimensionless, 0.433 for equilateral)."""
    a, b, c = X[F[:, 0]], X[F[:, 1]], X[F[:, 2]]
    e0, e1, e2 = b - a, c - b, a - c
    area = 0.5 * np.abs(e0[:, 0] * (-e2[:, 1]) - e0[:, 1] * (-e2[:, 0]))
    s = np.sum(e0 ** 2, 1) + np.sum(e1 ** 2, 1) + np.sum(e2 ** 2, 1)
    return 3.0 * area / s


def _delaunay_inside(X: np.ndarray, boundary: np.ndarray):
    """Delaunay triangles of X whose centroid is inside the polygon. X starts with the
    boundary's points; interior points are strictly inside, so only triangles made of three
    boundary points can lie outside (when every boundary segment is a Delaunay edge)."""
    nb = len(boundary)
    tri = Delaunay(X).simplices.astype(np.int64)
    a, b, c = X[tri[:, 0]], X[tri[:, 1]], X[tri[:, 2]]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    scale2 = np.sum((b - a) ** 2, 1) + np.sum((c - a) ** 2, 1)
    tri = tri[np.abs(cross) > 1e-12 * scale2]          # flat slivers of collinear boundary points
    allb = np.all(tri < nb, axis=1)
    keep = np.ones(len(tri), bool)
    if np.any(allb):
        keep[allb] = points_in_polygon(X[tri[allb]].mean(axis=1), boundary)
    return tri[keep]


class _BoundaryIndex:
    """Distances to a closed polyline, computed exactly only for points near it."""

    def __init__(self, B: np.ndarray):
        from scipy.spatial import cKDTree
        self.B = B
        self.tree = cKDTree(B)
        self.half = 0.5 * float(np.max(np.linalg.norm(np.roll(B, -1, axis=0) - B, axis=1)))

    def near(self, Q: np.ndarray, radius: float):
        """(mask of points within `radius` of the polyline, their distances, closest points)."""
        dv, _ = self.tree.query(Q)
        cand = np.flatnonzero(dv <= radius + self.half)
        mask = np.zeros(len(Q), bool)
        dist = np.full(len(Q), np.inf)
        close = np.zeros_like(Q)
        if len(cand):
            d, c = _segment_distance(Q[cand], self.B)
            mask[cand] = d < radius
            dist[cand] = d
            close[cand] = c
        return mask, dist, close


def triangulate_polygon(boundary, h: float, iterations: int = 25, margin: float = 0.5):
    """Triangulates a simple polygon.

    boundary: (N, 2) m, the polygon's vertices in counter-clockwise order (not repeated at the
        end); kept as the first N output vertices, in order.
    h: target edge length (m); the boundary should be sampled at about h already.
    Returns (X (M, 2) float64 m, F (T, 3) int32), counter-clockwise triangles.
    Raises ValueError when the polygon is clockwise or degenerate, RuntimeError when the
    result would not tile the polygon exactly.
    """
    B = np.ascontiguousarray(boundary, dtype=np.float64)
    if B.ndim != 2 or B.shape[1] != 2 or len(B) < 3:
        raise ValueError(f"boundary: expected (N>=3, 2) points, got {B.shape}")
    if not h > 0:
        raise ValueError(f"h: expected a positive edge length in m, got {h}")
    area = polygon_area(B)
    if area <= 0:
        raise ValueError("boundary: polygon must be counter-clockwise with positive area")
    nb = len(B)
    seg = np.linalg.norm(np.roll(B, -1, axis=0) - B, axis=1)
    # local target size: the boundary spacing may differ from h on seam-matched edges
    # (equal counts on edges of different length); the interior follows h.
    lo, hi = B.min(0), B.max(0)
    dy = h * np.sqrt(3) / 2
    ys = np.arange(lo[1] + dy / 2, hi[1], dy)
    pts = []
    for j, y in enumerate(ys):
        off = (h / 2) * (j % 2)
        xs = np.arange(lo[0] + off + h / 4, hi[0], h)
        pts.append(np.column_stack([xs, np.full_like(xs, y)]))
    I = np.concatenate(pts) if pts else np.zeros((0, 2))
    if len(I):
        I = I[points_in_polygon(I, B)]
    # boundary spacing near each interior point sets how far it must stay from the boundary
    index = _BoundaryIndex(B)
    if len(I):
        too_close, _, _ = index.near(I, margin * h * 1.1)
        I = I[~too_close]
    if len(I) == 0:
        X = B.copy()
        F = _delaunay_inside(X, B)
    else:
        for _ in range(iterations):
            X = np.vstack([B, I])
            F = _delaunay_inside(X, B)
            E = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
            E = np.sort(E, axis=1)
            key = np.unique(E[:, 0] * len(X) + E[:, 1])
            E = np.column_stack([key // len(X), key % len(X)])
            vec = X[E[:, 1]] - X[E[:, 0]]
            L = np.linalg.norm(vec, axis=1)
            L0 = 1.2 * h
            f = np.maximum(L0 - L, 0.0) / np.maximum(L, 1e-300)
            fv = vec * f[:, None]
            force = np.zeros_like(X)
            np.add.at(force, E[:, 0], -fv)
            np.add.at(force, E[:, 1], fv)
            move = 0.2 * force[nb:]
            I = I + move
            # keep interior points inside and at least margin·h from the boundary
            # (a point can only have left the polygon by crossing near the boundary)
            near, d, c = index.near(I, 2.0 * h)
            inside = np.ones(len(I), bool)
            inside[near] = points_in_polygon(I[near], B)
            bad = (~inside) | (d < margin * h)
            if np.any(bad):
                dirn = I[bad] - c[bad]
                nrm = np.linalg.norm(dirn, axis=1, keepdims=True)
                nrm = np.where(nrm > 1e-300, nrm, 1.0)
                sgn = np.where(inside[bad], 1.0, -1.0)[:, None]
                I[bad] = c[bad] + sgn * dirn / nrm * (margin * h * 1.001)
                # points that could not be put back inside (narrow parts) are dropped
                sub = I[bad]
                ok = points_in_polygon(sub, B)
                _, d2, _ = index.near(sub, margin * h)
                keep = np.ones(len(I), bool)
                keep[np.flatnonzero(bad)] = ok & (d2 >= margin * h * 0.999)
                I = I[keep]
            if np.max(np.abs(move), initial=0.0) < 1e-4 * h:
                break
        X = np.vstack([B, I])
        F = _delaunay_inside(X, B)
        # drop interior points that ended up in no triangle (should not happen)
    used = np.zeros(len(X), bool)
    used[F.ravel()] = True
    if not used[:nb].all():
        raise RuntimeError("triangulation lost boundary vertices (polygon too narrow for h)")
    if not used.all():
        remap = -np.ones(len(X), np.int64)
        remap[used] = np.arange(used.sum())
        X = X[used]
        F = remap[F]
    # orient counter-clockwise
    a, b, c = X[F[:, 0]], X[F[:, 1]], X[F[:, 2]]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    F = np.where((cross < 0)[:, None], F[:, [0, 2, 1]], F)
    tri_area = 0.5 * np.abs(cross).sum()
    if abs(tri_area - area) > 1e-9 * area:
        raise RuntimeError(f"triangulation does not tile the polygon: area {tri_area} vs {area} m²")
    return X, np.ascontiguousarray(F, dtype=np.int32)
