"""Boundary loops of a garment region and their classification as the garment's openings.

Frame: the core's (m, Y up, the body faces +Z, +X is the body's left). A loop is an ordered
(K, 3) array of points, closed implicitly (last → first), oriented along the winding of its
adjacent triangles and starting at its front-most point (largest Z)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: A loop is "roughly horizontal" when its plane normal is within ~45° of the Y axis.
HORIZONTAL_MIN_NY = 0.7
#: The hem (and a skirt's hem) must be at least this fraction of the longest opening candidate.
HEM_MIN_PERIMETER_FRACTION = 0.5
#: Loops whose centroid is within this fraction of the garment's half-width from its vertical
#: axis are "central" (neckline, waist); further out they are "lateral" (sleeves).
CENTRAL_MAX_OFFSET = 0.25


def boundary_loops(F: np.ndarray, V: np.ndarray | None = None) -> list[np.ndarray]:
    """Ordered vertex-index loops (each (K,) int64) of the edges used by exactly one triangle of
    F (M, 3), following the triangles' winding (majority vote where it is inconsistent).

    Where loops touch at a vertex (a "bowtie", common along noisy label borders) and V (N, 3)
    is given, the walk keeps to the hole it is going around: of the unused boundary edges
    leaving the vertex it takes the first one met turning from the arrival edge through the
    hole (counter-clockwise about the vertex normal), so touching holes come out as separate
    loops. Without V, or where the winding is inconsistent, it takes the first unused edge; a
    walk that cannot close is returned as the open chain it found."""
    if len(F) == 0:
        return []
    F = np.asarray(F, dtype=np.int64)
    he = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    n = int(F.max()) + 1
    key = np.minimum(he[:, 0], he[:, 1]) * n + np.maximum(he[:, 0], he[:, 1])   # undirected edge id
    order = np.argsort(key, kind="stable")
    ks = key[order]
    starts = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    counts = np.diff(np.r_[starts, len(ks)])
    bhe = he[np.sort(order[starts[counts == 1]])]   # directed boundary half-edges, face order
    if len(bhe) == 0:
        return []
    directed = set(map(tuple, bhe.tolist()))
    adj: dict[int, list[tuple[int, int]]] = {}
    out_count: dict[int, int] = {}
    for e, (a, b) in enumerate(bhe.tolist()):
        adj.setdefault(a, []).append((b, e))
        adj.setdefault(b, []).append((a, e))
        out_count[a] = out_count.get(a, 0) + 1
    normals = None
    if V is not None and any(c > 1 for c in out_count.values()):
        fn = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])   # area-weighted
        normals = np.zeros((n, 3))
        for k in range(3):
            np.add.at(normals, F[:, k], fn)
    used = np.zeros(len(bhe), bool)
    loops = []
    for e0 in range(len(bhe)):
        if used[e0]:
            continue
        used[e0] = True
        start, prev, cur = int(bhe[e0, 0]), int(bhe[e0, 0]), int(bhe[e0, 1])
        forward = True                               # arrived along the winding
        loop = [start]
        while cur != start:
            loop.append(cur)
            cands = [(v, e) for v, e in adj[cur] if not used[e]]
            outs = [(v, e) for v, e in cands if bhe[e, 0] == cur]
            if len(outs) > 1 and normals is not None and forward:
                nxt = min(outs, key=lambda c: _ccw_angle(V, normals[cur], cur, prev, c[0]))
            else:
                nxt = outs[0] if outs else (cands[0] if cands else None)
            if nxt is None:
                break
            used[nxt[1]] = True
            forward = bool(bhe[nxt[1], 0] == cur)
            prev, cur = cur, nxt[0]
        lp = np.asarray(loop, dtype=np.int64)
        agree = sum((int(a), int(b)) in directed for a, b in zip(lp, np.roll(lp, -1)))
        if 2 * agree < len(lp):
            lp = lp[::-1].copy()
        loops.append(lp)
    return loops


def _ccw_angle(V: np.ndarray, normal: np.ndarray, v: int, a: int, x: int) -> float:
    """Angle in [0, 2π) turning counter-clockwise about `normal` from the direction v→a to
    v→x (both projected onto the plane normal to `normal`)."""
    nrm = normal / (np.linalg.norm(normal) or 1.0)
    d1 = V[a] - V[v]
    d2 = V[x] - V[v]
    d1 = d1 - (d1 @ nrm) * nrm
    d2 = d2 - (d2 @ nrm) * nrm
    ang = np.arctan2(np.cross(d1, d2) @ nrm, d1 @ d2)
    return float(ang % (2 * np.pi))


def start_at_front(loop: np.ndarray, V: np.ndarray) -> np.ndarray:
    """The loop rotated to start at its front-most vertex (largest Z, then lowest index)."""
    z = V[loop, 2]
    i = int(np.lexsort((loop, -z))[0])
    return np.roll(loop, -i)


@dataclass(frozen=True)
class LoopGeometry:
    """Shape descriptors of a closed polyline P (K, 3) in m: perimeter (m), centroid (length-
    weighted, m), unit normal of its vector area (sign follows the loop's orientation)."""
    perimeter: float
    centroid: np.ndarray
    normal: np.ndarray

    @classmethod
    def of(cls, P: np.ndarray) -> "LoopGeometry":
        Q = np.roll(P, -1, axis=0)
        seg = np.linalg.norm(Q - P, axis=1)
        per = float(seg.sum())
        mid = 0.5 * (P + Q)
        c = (seg @ mid) / per if per > 0 else P.mean(axis=0)
        va = 0.5 * np.cross(P - c, Q - c).sum(axis=0)
        nrm = np.linalg.norm(va)
        if nrm > 1e-12 * max(per, 1e-300) ** 2:
            n = va / nrm
        else:  # figure-of-eight or straight: least-variance direction
            n = np.linalg.svd(P - c, full_matrices=False)[2][-1]
        return cls(per, c, n)

    @property
    def horizontal(self) -> bool:
        return abs(float(self.normal[1])) >= HORIZONTAL_MIN_NY


def classify_loops(loops: list[np.ndarray], openings: tuple[str, ...], garment_V: np.ndarray,
                   min_opening_perimeter: float) -> tuple[dict[str, int], list[int]]:
    """Matches loops (each (K, 3) points, m, core frame) to the garment's opening names.

    Loops shorter than min_opening_perimeter (m) are never openings. Rules (Y up, +X left):
    hem: among horizontal loops at least HEM_MIN_PERIMETER_FRACTION of the longest candidate,
    the lowest; neckline (upper/dress) and waist: the highest central loop (centroid within
    CENTRAL_MAX_OFFSET × half-width of the garment's vertical axis), for a skirt or pants
    horizontal; sleeve_left/right: the most lateral non-central loop on +X / -X; leg_left/right:
    the lowest loop below mid-height on the +X / -X side of the axis. garment_V (N, 3) gives the
    axis (x-centre of its bounding box), half-width and height.
    Returns ({opening name: loop index}, indices of the loops matched to nothing).
    """
    geo = [LoopGeometry.of(P) for P in loops]
    cand = [i for i, g in enumerate(geo) if g.perimeter >= min_opening_perimeter]
    lo, hi = garment_V.min(axis=0), garment_V.max(axis=0)
    axis_x = 0.5 * (lo[0] + hi[0])
    half_w = max(0.5 * (hi[0] - lo[0]), 1e-12)
    mid_y = 0.5 * (lo[1] + hi[1])
    dx = {i: float(geo[i].centroid[0] - axis_x) for i in cand}
    cy = {i: float(geo[i].centroid[1]) for i in cand}
    central = {i for i in cand if abs(dx[i]) <= CENTRAL_MAX_OFFSET * half_w}
    found: dict[str, int] = {}
    free = set(cand)

    def take(name, pool, key):
        pool = [i for i in pool if i in free]
        if name in openings and pool and name not in found:
            i = min(pool, key=key)
            found[name] = i
            free.discard(i)

    if "hem" in openings and cand:
        longest = max(geo[i].perimeter for i in cand)
        take("hem", [i for i in cand if geo[i].horizontal
                     and geo[i].perimeter >= HEM_MIN_PERIMETER_FRACTION * longest], key=lambda i: cy[i])
    need_horizontal = "leg_left" in openings or "neckline" not in openings   # pants, skirt
    top_pool = [i for i in central if geo[i].horizontal or not need_horizontal]
    take("neckline", top_pool, key=lambda i: -cy[i])
    take("waist", top_pool, key=lambda i: -cy[i])
    take("sleeve_left", [i for i in cand if i not in central and dx[i] > 0], key=lambda i: -dx[i])
    take("sleeve_right", [i for i in cand if i not in central and dx[i] < 0], key=lambda i: dx[i])
    take("leg_left", [i for i in cand if cy[i] < mid_y and dx[i] > 0], key=lambda i: cy[i])
    take("leg_right", [i for i in cand if cy[i] < mid_y and dx[i] < 0], key=lambda i: cy[i])
    holes = [i for i in range(len(loops)) if i not in found.values()]
    return found, holes
