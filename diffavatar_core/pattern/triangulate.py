"""Quality triangulation of a sewing-pattern panel (a simple polygon in metres).

The boundary points are kept exactly as given (so seam-paired edges keep the vertex counts
chosen for them). The wanted edge length is a size field: the target h, or less near boundary
vertices whose spacing is shorter (growing by GRADING per unit distance from them). Interior
points start on an equilateral lattice (thinned to the size field's density) and are relaxed by
repulsive edge springs with Delaunay re-triangulation (the force scheme of Persson & Strang 2004,
written here from the paper). Interior points are held about half the local size away from the
boundary and outside every boundary segment's diametral circle, which makes every boundary
segment a Gabriel edge, hence present in the Delaunay triangulation of boundary + interior
points: the triangles whose centroid lies inside the polygon then tile it exactly (area equal
to the polygon's to rounding). A clean-up pass then removes the remaining poor triangles:
quality-maximising moves of their interior vertices (each to the best of its neighbours'
centroid, its star's optimal-Delaunay position and small trial moves), merging of interior
vertices that are too close, and insertion of circumcentres (Ruppert style) where a poor
triangle has no movable vertex, re-triangulating (Delaunay flips) after each round.

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


GRADING = 0.3        # growth of the size field per unit distance from a finely spaced boundary
Q_TARGET = 0.31      # clean-up aim (the guarantee tested is 0.30)


class _BoundaryIndex:
    """Distances to a closed polyline, computed exactly only for points near it."""

    def __init__(self, B: np.ndarray):
        from scipy.spatial import cKDTree
        self.B = B
        self.tree = cKDTree(B)
        self.seg = np.linalg.norm(np.roll(B, -1, axis=0) - B, axis=1)
        self.mid = 0.5 * (B + np.roll(B, -1, axis=0))
        self.mid_tree = cKDTree(self.mid)
        self.half = 0.5 * float(np.max(self.seg))

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

    def in_diametral(self, Q: np.ndarray, slack: float = 1.02, k: int = 8) -> np.ndarray:
        """Points inside (slack × radius) the diametral circle of one of the k boundary
        segments with the nearest midpoints."""
        if len(Q) == 0:
            return np.zeros(0, bool)
        k = min(k, len(self.mid))
        _, idx = self.mid_tree.query(Q, k=k)
        idx = idx.reshape(len(Q), k)
        r = 0.5 * slack * self.seg[idx]
        d2 = np.sum((self.mid[idx] - Q[:, None, :]) ** 2, axis=2)
        return np.any(d2 < r * r, axis=1)


class _SizeField:
    """h(x) = min(h, min_i ℓ_i + GRADING·|x − b_i|) over boundary vertices b_i of local spacing ℓ_i."""

    def __init__(self, B: np.ndarray, h: float):
        seg = np.linalg.norm(np.roll(B, -1, axis=0) - B, axis=1)
        ell = 0.5 * (seg + np.roll(seg, 1))
        small = ell < h * 0.999
        self.h = h
        self.P = B[small]
        self.l = ell[small]
        self.hmin = float(min(h, self.l.min())) if len(self.l) else h
        if len(self.P):
            from scipy.spatial import cKDTree
            self.tree = cKDTree(self.P)

    @property
    def uniform(self) -> bool:
        return len(self.P) == 0

    def __call__(self, Q: np.ndarray) -> np.ndarray:
        out = np.full(len(Q), self.h)
        if self.uniform or len(Q) == 0:
            return out
        # only points within (h − min ℓ)/GRADING of a fine boundary vertex are below h; the
        # minimum is taken over their K nearest fine vertices (the field is a target, not a bound)
        K = min(24, len(self.P))
        d, j = self.tree.query(Q, k=K, distance_upper_bound=(self.h - self.hmin) / GRADING)
        d, j = d.reshape(len(Q), K), j.reshape(len(Q), K)
        hit = np.isfinite(d)
        lj = np.where(hit, self.l[np.minimum(j, len(self.P) - 1)], np.inf)
        return np.minimum(self.h, np.min(lj + GRADING * np.where(hit, d, np.inf), axis=1))


def _lattice(lo, hi, s):
    dy = s * np.sqrt(3) / 2
    ys = np.arange(lo[1] + dy / 2, hi[1], dy)
    pts = []
    for j, y in enumerate(ys):
        off = (s / 2) * (j % 2)
        xs = np.arange(lo[0] + off + s / 4, hi[0], s)
        pts.append(np.column_stack([xs, np.full_like(xs, y)]))
    return np.concatenate(pts) if pts else np.zeros((0, 2))


def _edges(F: np.ndarray, n: int) -> np.ndarray:
    E = np.sort(np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    key = np.unique(E[:, 0].astype(np.int64) * n + E[:, 1])
    return np.column_stack([key // n, key % n])


class _Constraint:
    """Where interior points may be: inside the polygon, at least margin × size from the
    boundary and outside every boundary segment's diametral circle."""

    def __init__(self, B, index, size, margin):
        self.B, self.index, self.size, self.margin = B, index, size, margin

    def ok(self, Q: np.ndarray) -> np.ndarray:
        if len(Q) == 0:
            return np.zeros(0, bool)
        r = self.margin * self.size(Q)
        near, d, _ = self.index.near(Q, float(r.max()) * 2.0 + 1e-12)
        good = np.ones(len(Q), bool)
        if np.any(near):
            good[near] = points_in_polygon(Q[near], self.B) & (d[near] >= r[near])
        far = ~near
        if np.any(far):
            good[far] = points_in_polygon(Q[far], self.B)
        cand = np.flatnonzero(good & (d < 2 * self.index.half + 1e-12))
        if len(cand):
            good[cand] = ~self.index.in_diametral(Q[cand])
        return good

    def repair(self, I: np.ndarray) -> np.ndarray:
        """Moves offending points back to margin × size along the normal; drops hopeless ones."""
        good = self.ok(I)
        if good.all():
            return I
        bad = np.flatnonzero(~good)
        Q = I[bad]
        _, d, c = self.index.near(Q, np.inf)
        inside = points_in_polygon(Q, self.B)
        dirn = Q - c
        nrm = np.linalg.norm(dirn, axis=1, keepdims=True)
        nrm = np.where(nrm > 1e-300, nrm, 1.0)
        sgn = np.where(inside, 1.0, -1.0)[:, None]
        r = self.margin * self.size(Q) * 1.02
        _, k = self.index.mid_tree.query(c)
        r = np.maximum(r, 0.52 * self.index.seg[k])
        Q = c + sgn * dirn / nrm * r[:, None]
        I = I.copy()
        I[bad] = Q
        keep = np.ones(len(I), bool)
        keep[bad] = self.ok(Q)
        return I[keep]


def triangulate_polygon(boundary, h: float, iterations: int = 40, margin: float = 0.45):
    """Triangulates a simple polygon.

    boundary: (N, 2) m, the polygon's vertices in counter-clockwise order (not repeated at the
        end); kept as the first N output vertices, in order.
    h: target edge length (m); the boundary should be sampled at about h already (finer
        spacing is followed: the interior grades from it to h).
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
    size = _SizeField(B, h)
    index = _BoundaryIndex(B)
    con = _Constraint(B, index, size, margin)
    lo, hi = B.min(0), B.max(0)
    if size.uniform:
        I = _lattice(lo, hi, h)
    else:   # a lattice at the finest size, thinned to the size field's density (seeded)
        s0 = max(size.hmin, h / 8)
        I = _lattice(lo, hi, s0)
        if len(I):
            I = I[points_in_polygon(I, B)]
            keep = np.random.default_rng(0).random(len(I)) < (s0 / size(I)) ** 2
            I = I[keep]
    if len(I):
        I = I[con.ok(I)]
    if len(I):
        Xlast = None
        for _ in range(iterations):
            X = np.vstack([B, I])
            sz = size(I)
            if Xlast is None or len(X) != len(Xlast) or \
                    np.max(np.linalg.norm(X[nb:] - Xlast[nb:], axis=1) / sz) > 0.1:
                F = _delaunay_inside(X, B)       # re-triangulate once points moved enough
                E = _edges(F, len(X))
                Xlast = X.copy()
            vec = X[E[:, 1]] - X[E[:, 0]]
            L = np.linalg.norm(vec, axis=1)
            hm = size(0.5 * (X[E[:, 0]] + X[E[:, 1]])) if not size.uniform else np.full(len(E), h)
            L0 = hm * 1.2 * np.sqrt(np.sum(L ** 2) / np.sum(hm ** 2))
            f = np.maximum(L0 - L, 0.0) / np.maximum(L, 1e-300)
            fv = vec * f[:, None]
            force = np.zeros_like(X)
            np.add.at(force, E[:, 0], -fv)
            np.add.at(force, E[:, 1], fv)
            move = 0.2 * force[nb:]
            rel = np.max(np.linalg.norm(move, axis=1) / sz, initial=0.0)
            I = con.repair(I + move)
            if rel < 1e-3 or len(I) == 0:
                break
    X = np.vstack([B, I]) if len(I) else B.copy()
    X, F = _cleanup(X, nb, B, size, con)
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


def _star_quality(X, p, tris, v):
    """min quality of the triangles `tris` (T, 3) with vertex v moved to p."""
    Y = X[tris].copy()
    Y[tris == v] = p
    a, b, c = Y[:, 0], Y[:, 1], Y[:, 2]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    s = np.sum((b - a) ** 2, 1) + np.sum((c - b) ** 2, 1) + np.sum((a - c) ** 2, 1)
    return float(np.min(1.5 * cross / s))      # signed: inverted triangles count as negative


def _circumcenter(P):
    a, b, c = P
    d = 2 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]))
    if abs(d) < 1e-300:
        return P.mean(0)
    ux = ((a @ a) * (b[1] - c[1]) + (b @ b) * (c[1] - a[1]) + (c @ c) * (a[1] - b[1])) / d
    uy = ((a @ a) * (c[0] - b[0]) + (b @ b) * (a[0] - c[0]) + (c @ c) * (b[0] - a[0])) / d
    return np.array([ux, uy])


def _cleanup(X, nb, B, size, con, rounds: int = 12):
    """Removes triangles of quality below Q_TARGET (see the module doc); returns (X, F)."""
    F = _delaunay_inside(X, B)
    for _ in range(rounds):
        q = triangle_quality_2d(X, F)
        bad = np.flatnonzero(q < Q_TARGET)
        if len(bad) == 0:
            break
        X = X.copy()
        # vertex → incident triangles
        order = np.argsort(F.ravel(), kind="stable")
        vsorted = F.ravel()[order]
        starts = np.searchsorted(vsorted, np.arange(len(X) + 1))
        tri_of = order // 3
        moved = set()
        insert, remove = [], set()
        for t in bad[np.argsort(q[bad])]:
            tri = F[t]
            if q[t] >= Q_TARGET:
                continue
            improved = False
            # 1. merge two interior vertices that are too close
            for a_, b_ in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
                if a_ >= nb and b_ >= nb and a_ not in remove and b_ not in remove:
                    m = 0.5 * (X[a_] + X[b_])
                    if np.linalg.norm(X[a_] - X[b_]) < 0.55 * size(m[None])[0] and con.ok(m[None])[0]:
                        X[a_] = m
                        remove.add(int(b_))
                        improved = True
                        break
            if improved:
                continue
            # 2. move its interior vertices to the best position for their stars
            for v in tri:
                if v < nb or v in remove:
                    continue
                tris = F[tri_of[starts[v]:starts[v + 1]]]
                nbr = np.unique(tris[tris != v])
                best_p, best_q = X[v].copy(), _star_quality(X, X[v], tris, v)
                cands = [X[nbr].mean(0)]
                # ODT: area-weighted circumcentres of the star
                cc = np.array([_circumcenter(X[tr]) for tr in tris])
                ar = np.abs(np.array([_star_quality(X, X[v], tr[None], v) for tr in tris]))
                if ar.sum() > 0:
                    cands.append((cc * ar[:, None]).sum(0) / ar.sum())
                r = 0.15 * np.min(np.linalg.norm(X[nbr] - X[v], axis=1))
                for ang in np.linspace(0, 2 * np.pi, 8, endpoint=False):
                    cands.append(X[v] + r * np.array([np.cos(ang), np.sin(ang)]))
                C = np.asarray(cands)
                okc = con.ok(C)
                for cpt, okk in zip(C, okc):
                    if not okk:
                        continue
                    qq = _star_quality(X, cpt, tris, v)
                    if qq > best_q + 1e-9:
                        best_p, best_q = cpt, qq
                if not np.array_equal(best_p, X[v]):
                    X[v] = best_p
                    moved.add(int(v))
                    improved = True
            if improved:
                continue
            # 3. insert the circumcentre (Ruppert), if it is a legal interior point
            c = _circumcenter(X[tri])
            if con.ok(c[None])[0]:
                insert.append(c)
            else:
                cen = X[tri].mean(0)
                if con.ok(cen[None])[0]:
                    insert.append(cen)
        keep = np.ones(len(X), bool)
        if remove:
            keep[list(remove)] = False
        X = X[keep]
        if insert:
            X = np.vstack([X, np.asarray(insert)])
        F = _delaunay_inside(X, B)
    return X, F
