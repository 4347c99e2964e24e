"""Pattern regularizers of paper §4.2.5, with exact gradients w.r.t. the rest pattern
coordinates (V, 2) m; through the control cage, ∂/∂ζ = Wᵀ ∂/∂x̄ (ControlCage.grad_zeta).

- Seam length (Eq. 7): for every pair of sewn boundary edges a = (a0, a1), b = (b0, b1),
      L_seam = Σ (‖p_a1 − p_a0‖² − ‖p_b1 − p_b0‖² − δ̄)²        (m⁴)
  with δ̄ = 0 (paper: sewn edges of equal length) or, with ``keep_template_ease``, the template's
  own difference (patterns whose sewn edges are eased by design keep that ease).
- Boundary curvature (Eq. 8, Wang 2018): at each boundary vertex i of each panel loop, with
  e_i1 = p_{i+1} − p_i, e_i2 = p_{i−1} − p_i and the template's ē, the best scaled rotation
  T_i = a I + b J (J the 90° rotation) of  min ‖e_1 − T ē_1‖² + ‖e_2 − T ē_2‖²  is
      a = Σ_k ē_k·e_k / Σ_k ‖ē_k‖²,   b = Σ_k (Jē_k)·e_k / Σ_k ‖ē_k‖²,
  linear in e, and
      L_curv = Σ_i w_i ‖(e_i1 − T_i ē_i1) + (e_i2 − T_i ē_i2)‖²        (m²).
Both are zero at the template (for L_seam: when its sewn edges have equal length, or with
keep_template_ease) and invariant to rigid motions of a panel (L_curv also to its scaling)."""
from __future__ import annotations

import numpy as np

from .. import _validate as val
from .garment import Garment

_J = np.array([[0.0, -1.0], [1.0, 0.0]])


class SeamLengthRegularizer:
    """Eq. 7 over g.seam_edge_pairs()."""

    def __init__(self, g: Garment, keep_template_ease: bool = False):
        self.pairs = g.seam_edge_pairs()
        self.n = len(g.rest)
        self.delta = np.zeros(len(self.pairs))
        if keep_template_ease:
            self.delta = self._diff(g.rest)[0]

    def _diff(self, X):
        P = self.pairs
        ea = X[P[:, 1]] - X[P[:, 0]]
        eb = X[P[:, 3]] - X[P[:, 2]]
        return np.sum(ea * ea, 1) - np.sum(eb * eb, 1), ea, eb

    def value_and_grad(self, rest) -> tuple[float, np.ndarray]:
        """(L_seam in m⁴, ∂L/∂rest (V, 2) in m³)."""
        X = val.points("rest", rest, dims=2)
        if len(X) != self.n:
            raise ValueError(f"rest: expected {self.n} vertices, got {len(X)}")
        d, ea, eb = self._diff(X)
        r = d - self.delta
        G = np.zeros_like(X)
        ga = (4.0 * r)[:, None] * ea      # ∂/∂ea of r² = 2r · 2ea
        gb = (-4.0 * r)[:, None] * eb
        P = self.pairs
        np.add.at(G, P[:, 1], ga)
        np.add.at(G, P[:, 0], -ga)
        np.add.at(G, P[:, 3], gb)
        np.add.at(G, P[:, 2], -gb)
        return float(np.sum(r * r)), G


class CurvatureRegularizer:
    """Eq. 8 over every vertex of every panel's boundary loop, w.r.t. the template rest."""

    def __init__(self, g: Garment, template_rest=None, weights=None):
        T = g.rest if template_rest is None else val.points("template_rest", template_rest, dims=2)
        idx = []
        for p in g.panels:
            L = p.loop
            idx.append(np.column_stack([L, np.roll(L, -1), np.roll(L, 1)]))  # i, i+1, i-1
        self.idx = np.vstack(idx)
        self.n = len(g.rest)
        self.w = np.ones(len(self.idx)) if weights is None else np.asarray(weights, float).reshape(-1)
        if self.w.shape != (len(self.idx),):
            raise ValueError(f"weights: expected ({len(self.idx)},) one per boundary vertex, got {self.w.shape}")
        i, j, k = self.idx.T
        self.eb1 = T[j] - T[i]
        self.eb2 = T[k] - T[i]
        self.norm2 = np.sum(self.eb1 ** 2, 1) + np.sum(self.eb2 ** 2, 1)
        if np.any(self.norm2 <= 0):
            raise ValueError("template_rest: a boundary vertex has two zero-length edges")

    def value_and_grad(self, rest) -> tuple[float, np.ndarray]:
        """(L_curv in m², ∂L/∂rest (V, 2) in m)."""
        X = val.points("rest", rest, dims=2)
        if len(X) != self.n:
            raise ValueError(f"rest: expected {self.n} vertices, got {len(X)}")
        i, j, k = self.idx.T
        e1, e2 = X[j] - X[i], X[k] - X[i]
        eb1, eb2, N = self.eb1, self.eb2, self.norm2
        Jb1, Jb2 = eb1 @ _J.T, eb2 @ _J.T
        a = (np.sum(eb1 * e1, 1) + np.sum(eb2 * e2, 1)) / N
        b = (np.sum(Jb1 * e1, 1) + np.sum(Jb2 * e2, 1)) / N
        sb = eb1 + eb2
        Jsb = Jb1 + Jb2
        r = (e1 + e2) - a[:, None] * sb - b[:, None] * Jsb
        w = self.w
        value = float(np.sum(w * np.sum(r * r, 1)))
        gr = 2.0 * w[:, None] * r
        ga = -np.sum(gr * sb, 1) / N
        gbb = -np.sum(gr * Jsb, 1) / N
        g1 = gr + ga[:, None] * eb1 + gbb[:, None] * Jb1
        g2 = gr + ga[:, None] * eb2 + gbb[:, None] * Jb2
        G = np.zeros_like(X)
        np.add.at(G, j, g1)
        np.add.at(G, k, g2)
        np.add.at(G, i, -(g1 + g2))
        return value, G
