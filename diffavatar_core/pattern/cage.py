"""Control cage of a garment pattern (paper §4.2.2): per panel, handles on the boundary loop
(convex-hull corners and turns sharper than a threshold) and mean value coordinates W, computed
once in C++, so that the rest pattern is  x̄ = W ζ  (ζ: handle positions, m) and a gradient
w.r.t. x̄ maps to ζ by Wᵀ (paper Eq. 5)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .. import _core
from .. import _validate as val
from .garment import Garment


def cage_handles(loop_xy, angle_threshold_deg: float = 10.0) -> np.ndarray:
    """Positions in the loop (int32, ascending) of the handle vertices of one boundary loop
    (#B×2, m): convex-hull corners and vertices where the loop turns by more than the
    threshold (degrees)."""
    P = val.points("loop_xy", loop_xy, dims=2)
    if len(P) < 3:
        raise ValueError(f"loop_xy: needs at least 3 points, got {len(P)}")
    return np.asarray(_core.cage_handles(P, float(angle_threshold_deg)), np.int32)


def mean_value_coordinates(cage_xy, points_xy) -> np.ndarray:
    """(#N, #H) mean value coordinates of points (#N×2, m) w.r.t. the closed polygon cage
    (#H×2, m, in order); rows sum to 1 and Σ_i W[n, i] cage[i] = points[n]."""
    C = val.points("cage_xy", cage_xy, dims=2)
    if len(C) < 3:
        raise ValueError(f"cage_xy: needs at least 3 vertices, got {len(C)}")
    P = val.points("points_xy", points_xy, dims=2)
    return np.asarray(_core.mean_value_coordinates(C, P))


@dataclass
class ControlCage:
    """handles: (H,) int32 garment vertex indices of the handles (panel by panel, each panel's
    in loop order); handle_panel: (H,) int32; W: (V, H) scipy CSR, block diagonal by panel;
    zeta0: (H, 2) m, the template's handle positions (W zeta0 = garment.rest)."""
    handles: np.ndarray
    handle_panel: np.ndarray
    W: sp.csr_matrix
    zeta0: np.ndarray

    def rest(self, zeta) -> np.ndarray:
        """Rest pattern x̄ = W ζ (V, 2) m for handle positions ζ (H, 2) m."""
        Z = val.points("zeta", zeta, dims=2)
        if Z.shape != self.zeta0.shape:
            raise ValueError(f"zeta: expected {self.zeta0.shape}, got {Z.shape}")
        return np.asarray(self.W @ Z)

    def grad_zeta(self, grad_rest) -> np.ndarray:
        """Chain rule of Eq. 5: ∂L/∂ζ = Wᵀ ∂L/∂x̄, (H, 2) from (V, 2)."""
        G = val.points("grad_rest", grad_rest, dims=2)
        return np.asarray(self.W.T @ G)


def build_cage(g: Garment, angle_threshold_deg: float = 10.0, seam_consistent: bool = True) -> ControlCage:
    """The control cage of every panel of g and its mean value coordinates. With
    seam_consistent, a vertex sewn to a handle is a handle too (repeated until stable), so the
    two sides of a seam are cut into the same pieces and deform together."""
    is_handle = np.zeros(len(g.rest), bool)
    for info in g.panels:
        is_handle[info.loop[cage_handles(g.rest[info.loop], angle_threshold_deg)]] = True
    if seam_consistent and len(g.seams):
        while True:
            a, b = g.seams[:, 0], g.seams[:, 1]
            new = is_handle.copy()
            new[b[is_handle[a]]] = True
            new[a[is_handle[b]]] = True
            if np.array_equal(new, is_handle):
                break
            is_handle = new
    rows, cols, vals, handles, hpanel = [], [], [], [], []
    start = g.panel_vertex_start
    h0 = 0
    for p, info in enumerate(g.panels):
        loop = info.loop
        hv = loop[is_handle[loop]]
        verts = np.arange(start[p], start[p + 1])
        Wp = mean_value_coordinates(g.rest[hv], g.rest[verts])
        r, c = np.nonzero(Wp)
        rows.append(verts[r])
        cols.append(h0 + c)
        vals.append(Wp[r, c])
        handles.append(hv)
        hpanel.append(np.full(len(hv), p, np.int32))
        h0 += len(hv)
    W = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(len(g.rest), h0))
    H = np.concatenate(handles).astype(np.int32)
    return ControlCage(H, np.concatenate(hpanel), W, g.rest[H].copy())
