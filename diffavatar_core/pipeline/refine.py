"""Coarse-to-fine output: the co-optimization runs on a coarse triangulation (its cost grows
superlinearly with the mesh), and the recovered pattern is carried to a production-resolution
mesh of the same template through the control cage — x̄ = W ζ (paper Eq. 5) is a deformation of
the pattern plane, so the fine mesh's vertices take the mean value coordinates of the *same*
cage (at the template's handle positions ζ₀) and the recovered handles ζ. Linear precision of
MVC makes this exact at ζ = ζ₀ (the fine template maps to itself). The fine drape is warm-
started from the coarse equilibrium (each fine vertex at the coarse draped position of its
pattern location) and draped by XPBD until it stands still (pipeline/recovery._fine_output,
Cloth.settle). Lengths in m."""
from __future__ import annotations

import numpy as np

from .. import _core
from ..pattern.cage import ControlCage, mean_value_coordinates
from ..pattern.garment import Garment
from ..sim.drape_job import SUBSTEPS


def transfer_pattern(coarse: Garment, cage: ControlCage, zeta, fine: Garment) -> np.ndarray:
    """The fine template's rest coordinates (V_f, 2) m under the recovered handles ζ (H, 2) m of
    the coarse template's cage. coarse and fine: the same template at two edge lengths (same
    panels, in the same order and pattern-plane layout)."""
    if len(coarse.panels) != len(fine.panels):
        raise ValueError(f"fine template has {len(fine.panels)} panels, the coarse one {len(coarse.panels)}")
    zeta = np.asarray(zeta, np.float64).reshape(-1, 2)
    out = np.empty_like(fine.rest)
    start = fine.panel_vertex_start
    for p in range(len(fine.panels)):
        sel = np.flatnonzero(cage.handle_panel == p)
        verts = np.arange(start[p], start[p + 1])
        W = mean_value_coordinates(cage.zeta0[sel], fine.rest[verts])
        out[verts] = W @ zeta[sel]
    return out


def transfer_positions(coarse: Garment, x_coarse, fine: Garment) -> np.ndarray:
    """(V_f, 3) m: every fine vertex at the coarse drape's position of its template pattern
    location (barycentric in the coarse panel's triangle closest to it in the pattern plane)."""
    x_coarse = np.asarray(x_coarse, np.float64)
    lift = 10.0 * (1.0 + np.ptp(coarse.rest, axis=0).max())   # panels apart in a third coordinate
    Pc = np.column_stack([coarse.rest, lift * coarse.panel])
    Pf = np.column_stack([fine.rest, lift * fine.panel])
    tri, bary, _ = _core.closest_points_on_mesh(np.ascontiguousarray(Pc), coarse.faces, np.ascontiguousarray(Pf))
    tri, bary = np.asarray(tri), np.asarray(bary)
    return np.einsum("nk,nkd->nd", bary, x_coarse[coarse.faces[tri]])


def push_outside(x, body_vertices, body_faces, thickness: float, smooth: bool = False) -> np.ndarray:
    """x (V, 3) m with every vertex closer to the body than `thickness` (m) — or inside it — along
    its contact plane's normal at its closest body point (_core.contact_planes; smooth: the
    interpolated normal, else the closest face's, sim/contact_kernel.hpp) moved to that point +
    thickness along that normal. The coarse drape's chords cut through the body's curvature by
    millimetres, and Newton from a deeply penetrating start does not converge."""
    x = np.array(x, np.float64)
    bv = np.ascontiguousarray(body_vertices, np.float64)
    bf = np.ascontiguousarray(body_faces, np.int32)
    _, cp, n = _core.contact_planes(bv, bf, x, bool(smooth))
    near = ((x - cp) * n).sum(1) < thickness
    x[near] = cp[near] + thickness * n[near]
    return x


def settle_carried(cloth, x0, body_vertices, body_faces, max_steps: int, sweeps: int,
                   displacement_tol: float = 5e-4, cancel=None, friction: float = 0.0, substeps: int = SUBSTEPS,
                   damping: float = 4.0):
    """`cloth` (a sim.Cloth of a fine mesh) reset to x0 (V, 3) m — a coarse drape carried to its
    vertices (transfer_positions) — pushed out of the body, then draped by XPBD (single-
    precision sweeps, `substeps` substeps, `sweeps` sweeps per step) until it stands still:
    Cloth.settle, no vertex moving more than displacement_tol (m) in 0.5 s; friction: Coulomb μ
    of the cloth on the body (sim/friction_kernel.hpp; 0 = frictionless); damping: the drape's
    velocity drag (1/s, Cloth.settle). Returns its
    SettleResult. Shared by the fine output (recovery) and the fine ground truth (synthetic)."""
    cloth.reset(push_outside(x0, body_vertices, body_faces, float(cloth.model.thickness),
                             bool(cloth.model.smooth_contact)))
    return cloth.settle(max_steps=max_steps, displacement_tol=displacement_tol, iterations=sweeps,
                        substeps=substeps, fast=True, cancel=cancel, friction=friction, damping=damping)
