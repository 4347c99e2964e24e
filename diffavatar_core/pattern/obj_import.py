"""Import of a simulation-ready garment stored as an OBJ whose UV coordinates are its sewing
pattern (the paper's published templates; CLO / Marvelous Designer exports).

- pattern vertices are the distinct (position, uv) corner pairs of the faces;
- panels are the connected components of the UV mesh (UV islands);
- each panel's true scale is the ratio of its summed 3D to UV edge lengths (UVs are normalised);
- seams pair boundary vertices of different panels at the same 3D position;
- components whose 3D area is below ``min_area_fraction`` of the total (buttons, tags) are
  dropped with a warning.
The file's own triangulation is kept."""
from __future__ import annotations

import pathlib
import warnings

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .garment import Garment, PanelInfo
from .spec import _UnionFind


def _read_obj(path):
    V, T, corners = [], [], []
    with open(path, "r", errors="replace") as fh:
        for ln, line in enumerate(fh, 1):
            try:
                if line.startswith("v "):
                    V.append([float(x) for x in line.split()[1:4]])
                    if len(V[-1]) != 3:
                        raise ValueError("a vertex needs 3 coordinates")
                elif line.startswith("vt "):
                    T.append([float(x) for x in line.split()[1:3]])
                    if len(T[-1]) != 2:
                        raise ValueError("a UV needs 2 coordinates")
                elif line.startswith("f "):
                    toks = line.split()[1:]
                    c = []
                    for t in toks:
                        parts = t.split("/")
                        if len(parts) < 2 or not parts[1]:
                            raise ValueError(f"{path}: face without UV indices ({line.strip()})")
                        c.append((int(parts[0]), int(parts[1])))
                    if len(c) < 3:
                        raise ValueError("a face needs 3 or more vertices")
                    for k in range(1, len(c) - 1):     # fan-triangulate polygons
                        corners.append((c[0], c[k], c[k + 1]))
            except ValueError as exc:
                if str(exc).startswith(f"{path}:"):
                    raise
                raise ValueError(f"{path}:{ln}: {exc}: {line.strip()!r}") from None
    if not corners:
        raise ValueError(f"{path}: holds no faces")
    V = np.asarray(V, float).reshape(-1, 3)
    T = np.asarray(T, float).reshape(-1, 2)
    for what, A in (("vertex", V), ("UV", T)):
        bad = ~np.isfinite(A).all(axis=1)
        if bad.any():
            raise ValueError(f"{path}: {int(bad.sum())} {what} line(s) hold NaN or Inf (first: {what} "
                             f"{int(np.flatnonzero(bad)[0]) + 1})")
    C = np.asarray(corners, np.int64)   # (F, 3, 2) 1-based (or negative) indices
    for j, n, what in ((0, len(V), "vertex"), (1, len(T), "UV")):
        idx = C[..., j]
        out = (idx == 0) | (idx < -n) | (idx > n)
        if out.any():
            raise ValueError(f"{path}: {int(out.any(axis=1).sum())} face(s) refer to a {what} index that "
                             f"names no '{'v' if j == 0 else 'vt'}' line (first: {int(idx[out][0])}; "
                             f"{n} {what}(s) in the file)")
        C[..., j] = np.where(idx < 0, n + idx, idx - 1)
    return V, T, C


#: A triangle is collapsed in UV when its UV area is at most this × its longest UV edge² (or its
#: UV edges are all zero): an equilateral triangle has 0.43, a sliver of 1:1000 about 5e-4.
COLLAPSED_UV_RATIO = 1e-8
#: More collapsed UV triangles than this fraction of all, or every one of a panel, is a degenerate
#: UV pattern (refused). The paper's published dress has 11 of 39 055 (collinear border points).
MAX_COLLAPSED_UV_FRACTION = 0.01


def _check_uv_pattern(path, F, UV, P3, fl) -> None:
    """ValueError naming the file when the UVs cannot be a sewing pattern: a panel whose UVs all
    sit at one point or on one line, whose 3D triangles have no extent, or collapsed UV
    triangles beyond MAX_COLLAPSED_UV_FRACTION (their rest shape would have zero area: the
    simulation's rest matrices, and the panel's UV→3D scale, would be NaN or Inf)."""
    a, b, c = UV[F[:, 0]], UV[F[:, 1]], UV[F[:, 2]]
    area = 0.5 * np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    longest = np.max([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1),
                      np.linalg.norm(a - c, axis=1)], axis=0)
    collapsed = area <= COLLAPSED_UV_RATIO * longest ** 2
    hint = ("the UVs must lay out the sewing pattern: each panel flat in UV, its triangles of "
            "nonzero area (a file with its UVs zeroed or projected onto a line has none)")
    for comp in np.unique(fl):
        m = fl == comp
        if collapsed[m].all():
            uv = UV[np.unique(F[m])]
            shape = "one point" if np.ptp(uv, axis=0).max() == 0 else "a line"
            raise ValueError(f"{path}: degenerate UV pattern: the {int(m.sum())} triangles of a UV island "
                             f"(faces from {int(np.flatnonzero(m)[0]) + 1} on) are all collapsed: their UVs lie "
                             f"on {shape} — {hint}")
    n = int(collapsed.sum())
    if n > MAX_COLLAPSED_UV_FRACTION * len(F):
        raise ValueError(f"{path}: degenerate UV pattern: {n} of {len(F)} triangles have (near) zero area in UV "
                         f"(collapsed UVs; more than {100 * MAX_COLLAPSED_UV_FRACTION:g}% allowed; first: face "
                         f"{int(np.flatnonzero(collapsed)[0]) + 1}) — {hint}")
    e3 = np.linalg.norm(np.cross(P3[F[:, 1]] - P3[F[:, 0]], P3[F[:, 2]] - P3[F[:, 0]]), axis=1)
    for comp in np.unique(fl):
        m = fl == comp
        if not (e3[m] > 0).any():
            raise ValueError(f"{path}: degenerate 3D layout: the {int(m.sum())} triangles of a UV island "
                             f"(faces from {int(np.flatnonzero(m)[0]) + 1} on) have zero area in 3D (the 'v' "
                             f"positions give each panel's scale)")


def _boundary_loops(F: np.ndarray) -> list:
    """Boundary loops (vertex lists, following the faces' orientation) of a triangle mesh."""
    E = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    key = {}
    for a, b in E:
        key[(int(a), int(b))] = key.get((int(a), int(b)), 0) + 1
    nxt = {}
    for (a, b) in key:
        if (b, a) not in key:
            nxt.setdefault(a, []).append(b)
    loops, used = [], set()
    for s in list(nxt):
        for first in nxt[s]:
            if (s, first) in used:
                continue
            loop, a, b = [s], s, first
            while True:
                used.add((a, b))
                if b == s:
                    break
                loop.append(b)
                cands = [c for c in nxt.get(b, []) if (b, c) not in used]
                if not cands:
                    break
                a, b = b, cands[0]
            loops.append(loop)
    return loops


def load_obj_pattern(path, units_in_meter: float | None = None, min_area_fraction: float = 0.003,
                     nominal_height: float = 0.7) -> Garment:
    """Garment from an OBJ with a UV sewing pattern.

    units_in_meter: file units per metre (100 for cm). None: 100 when the garment's height
    (Y extent) is 20–300 units, otherwise the garment is rescaled to ``nominal_height`` m
    with a warning (files stored at an arbitrary scale).
    """
    path = pathlib.Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    V, T, C = _read_obj(path)
    pairs = C.reshape(-1, 2)
    uniq, inv = np.unique(pairs, axis=0, return_inverse=True)
    F = inv.reshape(-1, 3).astype(np.int64)
    P3 = V[uniq[:, 0]]
    UV = T[uniq[:, 1]]
    height = float(np.ptp(P3[:, 1]))
    if units_in_meter is None:
        if 20.0 <= height <= 300.0:
            units_in_meter = 100.0
        else:
            units_in_meter = height / nominal_height
            warnings.warn(f"{path.name}: height {height:.3g} units is not plausible in cm; "
                          f"rescaled to {nominal_height} m")
    P3 = P3 / units_in_meter
    n = len(uniq)
    # UV islands
    E = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    A = coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(n, n))
    ncomp, label = connected_components(A, directed=False)
    fl = label[F[:, 0]]
    _check_uv_pattern(path, F, UV, P3, fl)
    area3 = 0.5 * np.linalg.norm(np.cross(P3[F[:, 1]] - P3[F[:, 0]], P3[F[:, 2]] - P3[F[:, 0]]), axis=1)
    comp_area = np.bincount(fl, weights=area3, minlength=ncomp)
    keep = np.flatnonzero(comp_area >= min_area_fraction * comp_area.sum())
    dropped = ncomp - len(keep)
    if dropped:
        warnings.warn(f"{path.name}: dropped {dropped} tiny component(s) "
                      f"({comp_area.sum() - comp_area[keep].sum():.4f} m² of {comp_area.sum():.4f} m²)")
    # order panels by position (top to bottom, then x) for reproducible names
    cen = np.array([P3[label == c].mean(0) for c in keep])
    keep = keep[np.lexsort((cen[:, 0], -cen[:, 1]))]
    rest, faces, x0, panel, infos = [], [], [], [], []
    offset, xcursor = 0, 0.0
    for i, c in enumerate(keep):
        vid = np.flatnonzero(label == c)
        remap = -np.ones(n, np.int64)
        remap[vid] = np.arange(len(vid))
        Fc = remap[F[fl == c]]
        e = np.vstack([Fc[:, [0, 1]], Fc[:, [1, 2]], Fc[:, [2, 0]]])
        uv = UV[vid]
        p = P3[vid]
        s = np.linalg.norm(p[e[:, 0]] - p[e[:, 1]], axis=1).sum() / \
            np.linalg.norm(uv[e[:, 0]] - uv[e[:, 1]], axis=1).sum()
        X = uv * s
        a, b, cc = X[Fc[:, 0]], X[Fc[:, 1]], X[Fc[:, 2]]
        if np.sum((b - a)[:, 0] * (cc - a)[:, 1] - (b - a)[:, 1] * (cc - a)[:, 0]) < 0:
            Fc = Fc[:, [0, 2, 1]]          # counter-clockwise in the pattern plane
        loops = _boundary_loops(Fc)
        loop = max(loops, key=len)          # outer boundary of the panel
        X = X - X.min(0) + np.array([xcursor, 0.0])
        xcursor = X[:, 0].max() + 0.05
        rest.append(X)
        faces.append(Fc + offset)
        x0.append(p)
        panel.append(np.full(len(vid), i, np.int32))
        infos.append(PanelInfo(f"panel_{i}", offset + np.asarray(loop), np.pi / 2))
        offset += len(vid)
    rest, x0 = np.vstack(rest), np.vstack(x0)
    panel = np.concatenate(panel)
    # seams: boundary vertices of different panels at the same 3D position
    bverts = np.concatenate([p.loop for p in infos])
    tol = 1e-6 * float(np.ptp(x0, axis=0).max())
    tree = cKDTree(x0[bverts])
    pairs = tree.query_pairs(tol, output_type="ndarray")
    seams = bverts[pairs] if len(pairs) else np.zeros((0, 2), np.int64)
    seams = seams[panel[seams[:, 0]] != panel[seams[:, 1]]]
    seams = np.unique(np.sort(seams, axis=1), axis=0)
    g = Garment(rest=rest, faces=np.vstack(faces), x0=x0, seams=seams, panel=panel, panels=infos,
                name=path.stem)
    g.boundaries = _name_openings(g)
    return g


def _name_openings(g: Garment) -> dict:
    """Names the openings of an assembled top (Y up): the lowest is the hem, the highest the
    neckline, the others sleeves by side (+X is the body's left). Other garments: {}."""
    weld = _UnionFind(len(g.rest))
    for a, b in g.seams:
        weld.union(int(a), int(b))
    root = weld.find
    # an edge belongs to an opening when no other panel has the same welded edge
    count = {}
    for p in g.panels:
        L = p.loop
        for a, b in zip(L, np.roll(L, -1)):
            k = frozenset((root(int(a)), root(int(b))))
            count[k] = count.get(k, 0) + 1
    open_adj = {}
    for k, c in count.items():
        if c == 1 and len(k) == 2:
            a, b = tuple(k)
            open_adj.setdefault(a, []).append(b)
            open_adj.setdefault(b, []).append(a)
    loops, seen = [], set()
    for s in open_adj:
        if s in seen:
            continue
        loop, prev, cur = [s], None, s
        seen.add(s)
        while True:
            nxts = [v for v in open_adj[cur] if v != prev and v not in seen]
            if not nxts:
                break
            prev, cur = cur, nxts[0]
            seen.add(cur)
            loop.append(cur)
        if len(loop) >= 3:
            loops.append(np.asarray(loop, np.int32))
    if len(loops) not in (2, 4):
        return {}
    ys = [g.x0[L, 1].mean() for L in loops]
    order = np.argsort(ys)
    out = {"hem": loops[order[0]], "neckline": loops[order[-1]]}
    if len(loops) == 4:
        mid = [loops[k] for k in order[1:3]]
        xs = [g.x0[L, 0].mean() for L in mid]
        out["sleeve_left"] = mid[int(np.argmax(xs))]
        out["sleeve_right"] = mid[int(np.argmin(xs))]
    return out
