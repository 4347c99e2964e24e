"""The garment model the simulator consumes: a triangulated 2D sewing pattern, its seams and
an initial 3D placement (all SI: metres)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

BOUNDARY_NAMES = ("hem", "neckline", "sleeve_left", "sleeve_right", "waist", "leg_left", "leg_right")


@dataclass
class PanelInfo:
    """One panel: its name, its boundary loop (vertex indices into Garment.rest, counter-
    clockwise in the pattern plane) and its fabric grain (warp) direction, radians from the
    pattern x axis. Panels built from a PatternSpec also record where each loop vertex lies on
    the spec's outline: loop_edge (B,) int32, the spec edge, and loop_t (B,), the arc-length
    fraction along it (PanelSpec.edge_points); None for panels of other origins."""
    name: str
    loop: np.ndarray          # (B,) int32
    grain: float = np.pi / 2  # rad
    loop_edge: np.ndarray | None = None
    loop_t: np.ndarray | None = None


@dataclass
class Garment:
    """A sewing pattern ready to sew and drape.

    rest:   (V, 2) float64, pattern (rest) coordinates, m. Panel p owns a contiguous range of
            vertices (see panel_vertex_start); panels are laid out side by side.
    faces:  (F, 3) int32, counter-clockwise in the pattern plane.
    x0:     (V, 3) float64, initial 3D placement, m (core frame: Y up, body faces +Z).
    seams:  (S, 2) int32, vertex pairs to sew (zero rest length), always between boundary
            vertices; a vertex may appear in several pairs (corners where seams meet).
    panel:  (V,) int32, panel id of each vertex.
    panels: list[PanelInfo].
    boundaries: name → (K,) int32 ordered vertex chain of an opening of the assembled garment
            (hem, neckline, sleeve_left, sleeve_right, waist, leg_left, leg_right — those present);
            a closed loop (first vertex not repeated); each sewn position is listed once.
    """
    rest: np.ndarray
    faces: np.ndarray
    x0: np.ndarray
    seams: np.ndarray
    panel: np.ndarray
    panels: list
    boundaries: dict = field(default_factory=dict)
    name: str = "garment"

    def __post_init__(self):
        self.rest = np.ascontiguousarray(self.rest, dtype=np.float64)
        self.faces = np.ascontiguousarray(self.faces, dtype=np.int32)
        self.x0 = np.ascontiguousarray(self.x0, dtype=np.float64)
        self.seams = np.ascontiguousarray(np.asarray(self.seams).reshape(-1, 2), dtype=np.int32)
        self.panel = np.ascontiguousarray(self.panel, dtype=np.int32)
        self.boundaries = {k: np.ascontiguousarray(v, dtype=np.int32) for k, v in self.boundaries.items()}
        for p in self.panels:
            p.loop = np.ascontiguousarray(p.loop, dtype=np.int32)
        V = len(self.rest)
        if self.rest.ndim != 2 or self.rest.shape[1] != 2:
            raise ValueError(f"rest: expected (V, 2), got {self.rest.shape}")
        if self.x0.shape != (V, 3):
            raise ValueError(f"x0: expected ({V}, 3), got {self.x0.shape}")
        if self.panel.shape != (V,):
            raise ValueError(f"panel: expected ({V},), got {self.panel.shape}")
        if self.faces.ndim != 2 or self.faces.shape[1] != 3:
            raise ValueError(f"faces: expected (F, 3), got {self.faces.shape}")
        for name, arr in (("faces", self.faces), ("seams", self.seams)):
            if arr.size and (arr.min() < 0 or arr.max() >= V):
                raise ValueError(f"{name}: index out of range [0, {V})")
        for k in self.boundaries:
            if k not in BOUNDARY_NAMES:
                raise ValueError(f"boundaries: unknown name {k!r} (expected one of {BOUNDARY_NAMES})")
        if len(self.panel) and (np.any(np.diff(self.panel) < 0) or self.panel.max() >= len(self.panels)):
            raise ValueError("panel: ids must be sorted (contiguous vertex ranges) and < len(panels)")

    @property
    def panel_vertex_start(self) -> np.ndarray:
        """(P+1,) int64: panel p owns vertices [start[p], start[p+1])."""
        return np.searchsorted(self.panel, np.arange(len(self.panels) + 1)).astype(np.int64)

    def face_grain(self) -> np.ndarray:
        """(F,) float64: each face's fabric grain (warp direction, rad from the pattern x axis)
        from its panel, for Cloth(grain=...). The PanelInfo default π/2 puts the warp along the
        pattern y axis (the panel's length); with equal warp/weft compliances that is the same
        energy as grain 0 (a quarter turn only swaps ε00 and ε11 and negates ε01)."""
        p = self.panel[self.faces[:, 0]] if len(self.faces) else np.zeros(0, np.int64)
        return np.array([self.panels[i].grain for i in p], dtype=np.float64)

    @property
    def panel_names(self) -> list:
        return [p.name for p in self.panels]

    def boundary_edges(self) -> np.ndarray:
        """(E, 2) int32: every panel's boundary edges (loop[i], loop[i+1]), in loop order."""
        out = [np.column_stack([p.loop, np.roll(p.loop, -1)]) for p in self.panels]
        return np.vstack(out).astype(np.int32) if out else np.zeros((0, 2), np.int32)

    def seam_edge_pairs(self) -> np.ndarray:
        """(K, 4) int32 rows (a0, a1, b0, b1): boundary edge a0→a1 is sewn to boundary edge
        b0→b1 with a0~b0 and a1~b1 (the edge pairs of the seam-length regularizer, Eq. 7).
        Each unordered pair appears once."""
        partners: dict = {}
        for i, j in self.seams:
            partners.setdefault(int(i), set()).add(int(j))
            partners.setdefault(int(j), set()).add(int(i))
        E = self.boundary_edges()
        eset = {(int(a), int(b)) for a, b in E} | {(int(b), int(a)) for a, b in E}
        seen = set()
        rows = []
        for a0, a1 in E:
            a0, a1 = int(a0), int(a1)
            for b0 in partners.get(a0, ()):
                for b1 in partners.get(a1, ()):
                    if b0 != b1 and (b0, b1) in eset:
                        key = frozenset([(min(a0, a1), max(a0, a1)), (min(b0, b1), max(b0, b1))])
                        if key in seen:
                            continue
                        seen.add(key)
                        rows.append((a0, a1, b0, b1))
        return np.asarray(rows, np.int32).reshape(-1, 4)

    def total_area(self) -> float:
        """Sum of the rest triangle areas (m²)."""
        a, b, c = self.rest[self.faces[:, 0]], self.rest[self.faces[:, 1]], self.rest[self.faces[:, 2]]
        return float(0.5 * np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]).sum())
