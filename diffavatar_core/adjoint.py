"""Gradients of a loss on the draped garment w.r.t. the Control (issue 4; paper §4.2).

Equilibrium adjoint (implemented): when φ depends only on the converged drape x*, the implicit
function theorem on ∇ₓE(x*, θ) = 0 gives dφ/dθ = −μᵀ ∂(∇ₓE)/∂θ with ∇ₓ²E μ = ∂φ/∂x — one
sparse LDLᵀ solve (cpp/adjoint/equilibrium_adjoint.hpp). It applies to a drape that converged
(DrapeResult.converged, residual ≈ 0) with the contact set held fixed; it does not apply to an
unconverged drape, to a loss on the trajectory, or across a change of the contact set.
Trajectory adjoint (supplement Eq. 1–4): the exact reverse pass of a number of XPBD steps
(every projection reversed, colour by colour), for a loss on the final positions/velocities,
w.r.t. the same controls plus the initial positions and velocities. Checkpointing stores every
k-th state and recomputes in between, bounding memory (cpp/adjoint/trajectory_adjoint.hpp).
"""
from __future__ import annotations

import numpy as np

from . import _core, _validate
from .sim.cloth import Cloth, _sim_params


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


def trajectory_gradient(cloth: Cloth, steps: int, dphi_dx, dphi_dv=None, checkpoint_every: int = 1,
                        dt: float = 1 / 120, iterations: int = 100, gravity=(0, -9.81, 0), damping: float = 4.0,
                        contact_radius: float = 0.01, progress=None, cancel=None) -> dict:
    """dφ/dθ for φ(x_T, v_T) after `steps` XPBD steps from the cloth's current state (which is
    left unchanged). dphi_dx, dphi_dv: (V,3). Returns dict: rest, stretch_compliance,
    bend_stiffness, body_vertices, x0 (V,3), v0 (V,3), x_final (V,3) m, peak_tape_mb (checkpoints +
    one segment + one step's tape), step_tape_mb (the largest step's tape), wall_s."""
    steps = _validate.positive_int("steps", steps)
    k = _validate.positive_int("checkpoint_every", checkpoint_every)
    gx = _validate.points("dphi_dx", dphi_dx)
    gv = np.zeros_like(gx) if dphi_dv is None else _validate.points("dphi_dv", dphi_dv)
    if gx.shape != cloth.x.shape or gv.shape != cloth.x.shape:
        raise ValueError(f"dphi_dx/dphi_dv: expected shape {cloth.x.shape}")
    p = _sim_params(dt, iterations, gravity, damping, contact_radius, 50.0)
    return _core.trajectory_adjoint(cloth.solver, cloth.state, p, steps, gx, gv, k, progress, cancel)
