"""Gradients of a loss on the draped garment w.r.t. the Control (issue 4; paper §4.2).

Equilibrium adjoint (implemented): when φ depends only on the converged drape x*, the implicit
function theorem on ∇ₓE(x*, θ) = 0 gives dφ/dθ = −μᵀ ∂(∇ₓE)/∂θ with ∇ₓ²E μ = ∂φ/∂x — one
sparse LDLᵀ solve (cpp/adjoint/equilibrium_adjoint.hpp). It applies to a drape that converged
(DrapeResult.converged, residual ≈ 0) with the contact set held fixed; it does not apply to an
unconverged drape, to a loss on the trajectory, or across a change of the contact set.
The trajectory adjoint (supplement Eq. 1–4) is not implemented yet.
"""
from __future__ import annotations

import numpy as np

from . import _core, _validate
from .sim.cloth import Cloth


def equilibrium_gradient(cloth: Cloth, dphi_dx, progress=None, cancel=None) -> dict:
    """dφ/dθ at the cloth's current (converged) state for ∂φ/∂x = dphi_dx (V,3).

    Returns dict: rest (V,2) per m of pattern coordinate, stretch_compliance (G,3) per m/N,
    bend_stiffness (G,) per N·m, body_vertices (Vb,3) per m; solve_residual, dofs, wall_s.
    """
    g = _validate.points("dphi_dx", dphi_dx)
    if g.shape != cloth.x.shape:
        raise ValueError(f"dphi_dx: expected shape {cloth.x.shape}, got {g.shape}")
    params = getattr(cloth, "params", None)
    gravity = np.asarray(params.gravity if params is not None else (0.0, -9.81, 0.0), dtype=np.float64)
    return _core.equilibrium_adjoint(cloth.solver, np.ascontiguousarray(cloth.x), g, gravity, progress, cancel)
