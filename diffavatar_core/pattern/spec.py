"""Parametric pattern description (panels of straight and Bézier edges, seams between edges,
a 3D placement per panel) and its assembly into a triangulated Garment."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .garment import Garment, PanelInfo
from .triangulate import polygon_area, triangulate_polygon


@dataclass
class Placement:
    """Maps panel coordinates (u, v) (m) to 3D (m): flat, or wrapped around a cylinder whose
    axis is parallel to ``ey`` at distance ``radius`` behind the sheet (behind = −ex×ey):

        x(u, v) = origin + R sin θ · ex + (v − v0) · ey − R (1 − cos θ) · (ex × ey),  θ = (u − u0)/R

    (R = inf: the flat sheet origin + (u − u0) ex + (v − v0) ey). ex, ey: orthonormal (3,).
    Optional fold over the shoulders: above v − v0 = fold_at the sheet bends backwards (−ex×ey)
    around a horizontal axis of radius fold_radius: the length s beyond fold_at goes to height
    fold_at + r sin(s/r) and depth r (1 − cos(s/r)) (s/r capped at 90°)."""
    origin: np.ndarray
    ex: np.ndarray
    ey: np.ndarray
    u0: float = 0.0
    v0: float = 0.0
    radius: float = np.inf
    fold_at: float = np.inf
    fold_radius: float = 0.2

    def __call__(self, uv: np.ndarray) -> np.ndarray:
        ex = np.asarray(self.ex, float) / np.linalg.norm(self.ex)
        ey = np.asarray(self.ey, float)
        ey = ey - ex * np.dot(ex, ey)
        ey /= np.linalg.norm(ey)
        n = np.cross(ex, ey)
        u = uv[:, 0] - self.u0
        v = uv[:, 1] - self.v0
        if np.isinf(self.radius):
            a, c = u, np.zeros_like(u)
        else:
            R = float(self.radius)
            a, c = R * np.sin(u / R), R * (1.0 - np.cos(u / R))
        if np.isfinite(self.fold_at):
            r = float(self.fold_radius)
            sv = np.clip(v - self.fold_at, 0.0, None)
            phi = np.minimum(sv / r, np.pi / 2)
            extra = sv - phi * r                     # beyond a quarter turn: straight back
            v = np.where(sv > 0, self.fold_at + r * np.sin(phi), v)
            c = c + np.where(sv > 0, r * (1 - np.cos(phi)) + extra, 0.0)
        return np.asarray(self.origin, float)[None, :] + a[:, None] * ex + v[:, None] * ey - c[:, None] * n


@dataclass
class PanelSpec:
    """A panel: corner vertices (K, 2) m in counter-clockwise order; edge k runs from vertex k
    to vertex k+1 (mod K). curves[k]: Bézier control points of edge k ((1, 2) quadratic or
    (2, 2) cubic, absolute panel coordinates, m). boundary[k]: the garment opening edge k
    belongs to ('hem', 'neckline', ...). grain: warp direction, rad from the panel x axis."""
    name: str
    vertices: np.ndarray
    placement: Placement
    curves: dict = field(default_factory=dict)
    boundary: dict = field(default_factory=dict)
    grain: float = np.pi / 2

    def edge_polyline(self, k: int, n: int) -> np.ndarray:
        """(n+1, 2) points along edge k, uniformly spaced in arc length (m)."""
        return self.edge_points(k, np.linspace(0.0, 1.0, n + 1))

    def edge_points(self, k: int, t: np.ndarray) -> np.ndarray:
        """Points (len(t), 2) m of edge k at the arc-length fractions t ∈ [0, 1]."""
        V = np.asarray(self.vertices, float)
        a, b = V[k], V[(k + 1) % len(V)]
        t = np.asarray(t, float)
        ctrl = self.curves.get(k)
        if ctrl is None:
            return a + t[:, None] * (b - a)
        if isinstance(ctrl, Arc):
            return ctrl.points(t)
        P = np.vstack([a, np.asarray(ctrl, float).reshape(-1, 2), b])
        dense = bezier(P, np.linspace(0, 1, max(64 * len(t), 4097)))
        s = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
        ts = np.interp(t * s[-1], s, np.linspace(0, 1, len(dense)))
        out = bezier(P, ts)
        out[t <= 0.0] = a               # the corners exactly
        out[t >= 1.0] = b
        return out

    def edge_length(self, k: int) -> float:
        pts = self.edge_polyline(k, 64)
        return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


@dataclass
class Arc:
    """A circular arc edge: centre (2,) m, radius m, from angle a0 to a1 (rad, signed sweep)."""
    center: np.ndarray
    radius: float
    a0: float
    a1: float

    def points(self, t: np.ndarray) -> np.ndarray:
        ang = self.a0 + (self.a1 - self.a0) * np.asarray(t, float)
        return np.asarray(self.center, float) + self.radius * np.column_stack([np.cos(ang), np.sin(ang)])


def bezier(P: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Points of the Bézier curve with control points P (d+1, 2) at parameters t (N,)."""
    from math import comb
    d = len(P) - 1
    t = np.asarray(t, float)[:, None]
    return sum(comb(d, i) * t ** i * (1 - t) ** (d - i) * P[i] for i in range(d + 1))


@dataclass
class SeamSpec:
    """Sews edge ``edge_a`` of panel ``panel_a`` to edge ``edge_b`` of ``panel_b``. With
    reverse=True (the usual case for two panels both counter-clockwise, facing each other)
    the start of edge a meets the end of edge b."""
    panel_a: str
    edge_a: int
    panel_b: str
    edge_b: int
    reverse: bool = True


@dataclass
class PatternSpec:
    name: str
    panels: list
    seams: list


class _UnionFind:
    def __init__(self, n):
        self.p = list(range(n))

    def find(self, i):
        while self.p[i] != i:
            self.p[i] = self.p[self.p[i]]
            i = self.p[i]
        return i

    def union(self, a, b):
        self.p[self.find(a)] = self.find(b)


def build_garment(spec: PatternSpec, edge_length: float = 0.012, gap: float = 0.05) -> Garment:
    """Samples every edge (seam-paired edges with equal segment counts), triangulates every
    panel to the target edge length (m), sews and places it. Panels are laid out along the
    pattern x axis separated by ``gap`` (m)."""
    if not edge_length > 0:
        raise ValueError(f"edge_length: expected a positive length in m, got {edge_length}")
    names = [p.name for p in spec.panels]
    if len(set(names)) != len(names):
        raise ValueError("panels: names must be unique")
    pid = {n: i for i, n in enumerate(names)}
    keys = [(i, k) for i, p in enumerate(spec.panels) for k in range(len(p.vertices))]
    kid = {key: j for j, key in enumerate(keys)}
    uf = _UnionFind(len(keys))
    for s in spec.seams:
        for pn in (s.panel_a, s.panel_b):
            if pn not in pid:
                raise ValueError(f"seams: unknown panel {pn!r}")
        uf.union(kid[(pid[s.panel_a], s.edge_a)], kid[(pid[s.panel_b], s.edge_b)])
    lengths = np.array([spec.panels[i].edge_length(k) for i, k in keys])
    groups: dict = {}
    for j in range(len(keys)):
        groups.setdefault(uf.find(j), []).append(j)
    fractions = _edge_fractions(spec, keys, kid, groups, lengths, edge_length, pid)
    nseg = np.array([len(fractions[j]) - 1 for j in range(len(keys))], int)

    rest, faces, x0, panel, infos = [], [], [], [], []
    edge_vertices = {}   # (panel, edge) → (n+1,) global vertex ids
    offset = 0
    xcursor = 0.0
    for i, p in enumerate(spec.panels):
        K = len(p.vertices)
        loop_pts, loop_edge, loop_t = [], [], []
        for k in range(K):
            t = np.asarray(fractions[kid[(i, k)]], float)
            loop_pts.append(p.edge_points(k, t)[:-1])
            loop_edge.append(np.full(len(t) - 1, k, np.int32))
            loop_t.append(t[:-1])
        B = np.vstack(loop_pts)
        if polygon_area(B) <= 0:
            raise ValueError(f"panel {p.name!r}: vertices must be counter-clockwise")
        X, F = triangulate_polygon(B, edge_length)
        start = 0
        for k in range(K):
            n = int(nseg[kid[(i, k)]])
            idx = (start + np.arange(n + 1)) % len(B)
            edge_vertices[(i, k)] = offset + idx
            start += n
        shift = xcursor - X[:, 0].min()
        Xl = X + np.array([shift, -X[:, 1].min()])
        xcursor = Xl[:, 0].max() + gap
        rest.append(Xl)
        faces.append(F + offset)
        x0.append(p.placement(X))
        panel.append(np.full(len(X), i, np.int32))
        infos.append(PanelInfo(p.name, offset + np.arange(len(B)), p.grain, np.concatenate(loop_edge),
                               np.concatenate(loop_t)))
        offset += len(X)
    seams = []
    for s in spec.seams:
        a = edge_vertices[(pid[s.panel_a], s.edge_a)]
        b = edge_vertices[(pid[s.panel_b], s.edge_b)]
        seams.append(np.column_stack([a, b[::-1] if s.reverse else b]))
    seams = np.unique(np.vstack(seams), axis=0) if seams else np.zeros((0, 2), np.int32)
    # named openings: chain the named edges through the sewn (welded) positions
    V = offset
    weld = _UnionFind(V)
    for a, b in seams:
        weld.union(int(a), int(b))
    boundaries = {}
    for bname in sorted({nm for p in spec.panels for nm in p.boundary.values()}):
        chains = [edge_vertices[(i, k)] for i, p in enumerate(spec.panels)
                  for k, nm in p.boundary.items() if nm == bname]
        boundaries[bname] = _chain(chains, weld)
    return Garment(rest=np.vstack(rest), faces=np.vstack(faces), x0=np.vstack(x0),
                   seams=seams, panel=np.concatenate(panel), panels=infos,
                   boundaries=boundaries, name=spec.name)


GRADING = 0.25     # growth of the boundary spacing per unit length away from a short edge


def _edge_fractions(spec, keys, kid, groups, lengths, h, pid):
    """Arc-length fractions (n+1,) at which every panel edge is sampled. The spacing is the
    target h, except near a corner whose other edge is sampled finer (a short edge, or a seam
    partner's grading): there it starts at that spacing and grows by GRADING per unit length
    (a fine segment next to a long one would force a sliver at the corner). Seam-sewn edges
    share one set of fractions (mirrored where sewn in reverse), hence equal vertex counts at
    matching relative positions."""
    ncorner = {i: len(p.vertices) for i, p in enumerate(spec.panels)}
    L = {key: lengths[j] for j, key in enumerate(keys)}
    corner = {}
    for i, K in ncorner.items():
        for v in range(K):
            corner[(i, v)] = min(h, L[(i, (v - 1) % K)], L[(i, v)])
    # orientation of every edge relative to its group's first member (seams may sew reversed)
    adj: dict = {}
    for s in spec.seams:
        a, b = kid[(pid[s.panel_a], s.edge_a)], kid[(pid[s.panel_b], s.edge_b)]
        adj.setdefault(a, []).append((b, s.reverse))
        adj.setdefault(b, []).append((a, s.reverse))
    flips = []
    for members in groups.values():
        flip = {members[0]: False}
        stack = [members[0]]
        while stack:
            j = stack.pop()
            for o, rev in adj.get(j, []):
                if o not in flip:
                    flip[o] = flip[j] != rev
                    stack.append(o)
        flips.append(flip)
    t = np.linspace(0.0, 1.0, 4001)
    for _ in range(8):   # corner spacings propagate through seams and along panels
        out = {}
        for members, flip in zip(groups.values(), flips):
            rho = np.zeros_like(t)
            for j in members:
                i, k = keys[j]
                Lj = L[(i, k)]
                s0, s1 = corner[(i, k)], corner[(i, (k + 1) % ncorner[i])]
                tt = 1.0 - t if flip.get(j, False) else t
                size = np.minimum(h, np.minimum(s0 + GRADING * tt * Lj, s1 + GRADING * (1 - tt) * Lj))
                rho = np.maximum(rho, Lj / size)
            if np.ptp(rho) <= 1e-12 * rho.max():           # uniform: equal arc-length segments
                n = max(1, int(np.ceil(rho[0] - 0.25)))
                f = np.linspace(0.0, 1.0, n + 1)
            else:
                Phi = np.concatenate([[0.0], np.cumsum(0.5 * (rho[1:] + rho[:-1]) * np.diff(t))])
                n = max(1, int(np.ceil(Phi[-1] - 0.25)))
                f = np.interp(np.linspace(0.0, Phi[-1], n + 1), Phi, t)
                f[0], f[-1] = 0.0, 1.0
            for j in members:
                out[j] = 1.0 - f[::-1] if flip.get(j, False) else f
        changed = False
        for j, (i, k) in enumerate(keys):
            f, Lj = out[j], L[(i, k)]
            for v, first in ((k, f[1] * Lj), ((k + 1) % ncorner[i], (1.0 - f[-2]) * Lj)):
                if first < 0.9 * corner[(i, v)]:
                    corner[(i, v)] = first
                    changed = True
        if not changed:
            break
    return out


def _chain(chains: list, weld: _UnionFind) -> np.ndarray:
    """Joins open vertex chains whose ends are welded together into one ordered chain (each
    welded position once; a closed loop does not repeat its first vertex)."""
    chains = [list(map(int, c)) for c in chains]
    out = chains.pop(0)
    while chains:
        tail = weld.find(out[-1])
        for j, c in enumerate(chains):
            if weld.find(c[0]) == tail:
                out += c[1:]
                break
            if weld.find(c[-1]) == tail:
                out += c[::-1][1:]
                break
        else:
            raise ValueError("boundary edges of one opening do not form a chain")
        chains.pop(j)
    if len(out) > 1 and weld.find(out[-1]) == weld.find(out[0]):
        out = out[:-1]
    return np.asarray(out, np.int32)
