"""Scan-guided equilibrium: a fold state of the garment chosen by the scan.

A drape's folds are one of many equilibria of the same pattern and material; which one the
cloth lands in depends on where it started (the template layout, the previous iterate's drape),
and on a coarse mesh that choice moves the Chamfer distance to the scan more than the pattern
does (BENCHMARKS.md, the truth-outline floor). Here the cloth is first pulled toward the scan
surface by springs (stiffness κ_g·m per vertex, κ_g in 1/s²; the target of each vertex is its
closest point on the scan, re-found `rounds` times), then released: Newton to equilibrium of
the garment's own energy with the usual static-friction anchors (κ = 1/s², tied to the guided
positions). The result is an equilibrium of the same parameters as every other drape, nearer
to the scan's folds where the physics allows them. A vertex whose closest scan point is farther
than `capture` (m) — over a hole in the scan, past an opening — is tied to itself instead.
Units: m, 1/s²."""
from __future__ import annotations

import numpy as np

from .. import _core

GUIDE_ROUNDS = 3   # closest points re-found after each guided solve (they move with the cloth)


def scan_targets(x, scan_vertices, scan_faces, capture: float) -> np.ndarray:
    """(V, 3) m: each garment vertex's closest point on the scan mesh, or the vertex itself when
    that point is farther than capture (m)."""
    x = np.ascontiguousarray(x, np.float64)
    _, _, cp = _core.closest_points_on_mesh(np.ascontiguousarray(scan_vertices, np.float64),
                                            np.ascontiguousarray(scan_faces, np.int32), x)
    near = np.linalg.norm(cp - x, axis=1) < capture
    return np.where(near[:, None], cp, x)


def guided_equilibrium(cloth, scan_vertices, scan_faces, stiffness: float, capture: float = 0.03,
                       residual_tol: float = 1e-7, refine_iterations: int = 120, rounds: int = GUIDE_ROUNDS,
                       cancel=None) -> None:
    """Moves `cloth` (a sim.Cloth at its current control) from its current state to a scan-guided
    equilibrium (module doc). Raises ValueError when the released equilibrium misses
    residual_tol or leaves a vertex deeper in the body than 10% of the collision thickness."""
    if not (np.isfinite(stiffness) and stiffness > 0):
        raise ValueError(f"stiffness: expected a positive number (1/s²), got {stiffness}")
    for _ in range(max(int(rounds), 1)):
        target = scan_targets(cloth.x, scan_vertices, scan_faces, capture)
        cloth.refine(anchor=target, anchor_stiffness=stiffness, residual_tol=residual_tol,
                     refine_iterations=refine_iterations, cancel=cancel)
    _, res = cloth.refine(keep_anchor=False, anchor_stiffness=1.0, residual_tol=residual_tol,
                          refine_iterations=refine_iterations, cancel=cancel)
    pen = float(cloth.solver.max_penetration(np.asarray(cloth.x)))
    if res <= residual_tol and pen > 0.0:   # a vertex pulled into the body: contacts re-detected
        _, res, pen = cloth.reseat_contacts(residual_tol, refine_iterations, anchor_stiffness=1.0, cancel=cancel)
    if not res <= residual_tol:
        raise ValueError(f"the released guided drape stopped at residual {res:.3g}")
    if pen > 0.1 * cloth.model.thickness:
        raise ValueError(f"the released guided drape leaves a vertex {1e3 * pen:.2f} mm inside the body")
