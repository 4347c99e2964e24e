"""Gradients of a loss on the draped garment w.r.t. the Control (issue 4; paper §4.2).

Equilibrium adjoint (implemented): when φ depends only on the converged drape x*, the implicit
function theorem on ∇ₓE(x*, θ) = 0 gives dφ/dθ = −μᵀ ∂(∇ₓE)/∂θ with ∇ₓ²E μ = ∂φ/∂x — one
sparse LDLᵀ solve (cpp/adjoint/equilibrium_adjoint.hpp). It applies to a drape that converged
(DrapeResult.converged, residual ≈ 0) with the contact set held fixed; it does not apply to an
unconverged drape, to a loss on the trajectory, or across a change of the contact set.
Trajectory adjoint (supplement Eq. 1–4): the exact reverse pass of a number of XPBD steps
(every projection reversed, colour by colour), for a loss on the final positions/velocities,
w.r.t. the same controls plus the initial positions and velocities. Checkpointing stores every
k-th state and recomputes in between, bounding memory (cpp/adjoint/trajectory_adjoint.hpp); by
default k is the smallest (fastest) whose peak fits a memory budget (checkpoint_interval).
"""
from __future__ import annotations

import math

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


def trajectory_memory_mb(cloth: Cloth, steps: int, checkpoint_every: int, iterations: int) -> float:
    """Upper bound (MB) of the trajectory adjoint's peak_tape_mb for this cloth: one step's tape
    (per sweep a record of every projection: 12 doubles per triangle, 14 per hinge, 9 per seam,
    4 per contact, at most one contact per vertex; sim/sweep_tape.hpp) plus, per stored state —
    ceil(steps/k) checkpoints and up to k segment starts — positions and velocities (2 × 3V
    doubles) and its contacts (8 bytes each)."""
    steps = _validate.positive_int("steps", steps)
    iterations = _validate.positive_int("iterations", iterations)
    k = min(_validate.positive_int("checkpoint_every", checkpoint_every), steps)
    m = cloth.model
    V, nf, nh, ns = int(m.num_vertices), len(m.faces), len(m.hinges), len(m.seams)
    tape = iterations * (12 * nf + 14 * nh + 9 * ns + 4 * V) * 8 + 8 * V
    state = 2 * 3 * V * 8 + 8 * V
    return (tape + (math.ceil(steps / k) + k) * state) / 2**20


def checkpoint_interval(cloth: Cloth, steps: int, iterations: int, memory_budget_mb: float = 2048.0) -> int:
    """The checkpoint interval k the trajectory adjoint uses when none is given: the smallest k
    whose peak (trajectory_memory_mb) fits memory_budget_mb (MB). The smallest is the fastest:
    k = 1 runs each step twice forward (the checkpointing pass and the recording replay) and
    once in reverse; every k > 1 adds the segment re-run ((k − 1)/k of a step per step).
    Raises ValueError when no k fits (the tape of one step alone, or the checkpoints at
    k ≈ √steps, exceed the budget)."""
    steps = _validate.positive_int("steps", steps)
    if not (memory_budget_mb > 0):
        raise ValueError(f"memory_budget_mb must be > 0, got {memory_budget_mb}")
    # the peak falls with k while ceil(steps/k) > k, so the first fit is searched up to ~√steps
    best_k, best = 1, math.inf
    for k in range(1, steps + 1):
        mb = trajectory_memory_mb(cloth, steps, k, iterations)
        if mb <= memory_budget_mb:
            return k
        if mb < best:
            best_k, best = k, mb
        elif k * k > steps:
            break
    raise ValueError(f"trajectory adjoint: {steps} steps need at least {best:.0f} MB (k = {best_k}) for this "
                     f"{cloth.model.num_vertices}-vertex garment, over the memory budget of {memory_budget_mb:.0f} MB; "
                     "raise memory_budget_mb, take fewer steps or fewer sweeps per step")


class TrajectoryRun:
    """A recorded forward run (record_trajectory): the final state, and the checkpoints its
    gradient() reverses. Positions in m, velocities in m/s. Valid while the cloth's control and
    sweep plan are those it was recorded with; gradient() raises ValueError otherwise."""

    def __init__(self, cloth: Cloth, ckpt, params):
        self._cloth, self._ckpt, self._params = cloth, ckpt, params

    @property
    def x_final(self) -> np.ndarray:
        return self._ckpt.x_final

    @property
    def v_final(self) -> np.ndarray:
        return self._ckpt.v_final

    @property
    def steps(self) -> int:
        return self._ckpt.steps

    @property
    def checkpoint_every(self) -> int:
        return self._ckpt.checkpoint_every

    @property
    def checkpoint_mb(self) -> float:
        return self._ckpt.checkpoint_mb

    @property
    def wall_s(self) -> float:
        return self._ckpt.wall_s

    def gradient(self, dphi_dx, dphi_dv=None, progress=None, cancel=None) -> dict:
        """dφ/dθ for ∂φ/∂x_T = dphi_dx, ∂φ/∂v_T = dphi_dv (V,3): the backward half only (the
        recorded run is replayed step by step, not simulated again). Returns the dict of
        trajectory_gradient. May be called again with another loss."""
        gx = _validate.points("dphi_dx", dphi_dx)
        gv = np.zeros_like(gx) if dphi_dv is None else _validate.points("dphi_dv", dphi_dv)
        if gx.shape != self.x_final.shape or gv.shape != self.x_final.shape:
            raise ValueError(f"dphi_dx/dphi_dv: expected shape {self.x_final.shape}")
        out = _core.trajectory_backward(self._cloth.solver, self._ckpt, gx, gv, progress, cancel)
        out["checkpoint_every"] = self.checkpoint_every
        return out


def _trajectory_setup(cloth, steps, checkpoint_every, dt, iterations, gravity, damping, contact_radius,
                      memory_budget_mb):
    steps = _validate.positive_int("steps", steps)
    iterations = _validate.positive_int("iterations", iterations)
    if checkpoint_every is None:
        k = checkpoint_interval(cloth, steps, iterations, memory_budget_mb)
    else:
        k = _validate.positive_int("checkpoint_every", checkpoint_every)
    return steps, k, _sim_params(dt, iterations, gravity, damping, contact_radius, 50.0)


def record_trajectory(cloth: Cloth, steps: int, checkpoint_every: int | None = None, dt: float = 1 / 120,
                      iterations: int = 100, gravity=(0, -9.81, 0), damping: float = 4.0,
                      contact_radius: float = 0.01, progress=None, cancel=None,
                      memory_budget_mb: float = 2048.0) -> TrajectoryRun:
    """The forward half of the trajectory adjoint: `steps` XPBD steps from the cloth's current
    state (left unchanged), keeping every k-th state (k as in trajectory_gradient). Evaluate the
    loss on run.x_final, then run.gradient(∂φ/∂x_T): for a loss that is not linear in x_T (a
    Chamfer distance) this saves the second forward simulation trajectory_gradient would run."""
    steps, k, p = _trajectory_setup(cloth, steps, checkpoint_every, dt, iterations, gravity, damping,
                                    contact_radius, memory_budget_mb)
    return TrajectoryRun(cloth, _core.trajectory_forward(cloth.solver, cloth.state, p, steps, k, progress, cancel), p)


def trajectory_gradient(cloth: Cloth, steps: int, dphi_dx, dphi_dv=None, checkpoint_every: int | None = None,
                        dt: float = 1 / 120, iterations: int = 100, gravity=(0, -9.81, 0), damping: float = 4.0,
                        contact_radius: float = 0.01, progress=None, cancel=None,
                        memory_budget_mb: float = 2048.0) -> dict:
    """dφ/dθ for φ(x_T, v_T) after `steps` XPBD steps from the cloth's current state (which is
    left unchanged), forward and backward in one call (record_trajectory + gradient, for a loss
    whose ∂φ/∂x_T is known beforehand). dphi_dx, dphi_dv: (V,3). checkpoint_every: store every
    k-th state and re-run in between; None chooses the fastest k whose peak fits
    memory_budget_mb (MB; checkpoint_interval). Returns dict: rest, stretch_compliance,
    bend_stiffness, body_vertices, x0 (V,3), v0 (V,3), x_final (V,3) m, peak_tape_mb (checkpoints
    + one segment + one step's tape), step_tape_mb (the largest step's tape), checkpoint_every
    (the k used), wall_s."""
    steps, k, p = _trajectory_setup(cloth, steps, checkpoint_every, dt, iterations, gravity, damping,
                                    contact_radius, memory_budget_mb)
    gx = _validate.points("dphi_dx", dphi_dx)
    gv = np.zeros_like(gx) if dphi_dv is None else _validate.points("dphi_dv", dphi_dv)
    if gx.shape != cloth.x.shape or gv.shape != cloth.x.shape:
        raise ValueError(f"dphi_dx/dphi_dv: expected shape {cloth.x.shape}")
    out = _core.trajectory_adjoint(cloth.solver, cloth.state, p, steps, gx, gv, k, progress, cancel)
    out["checkpoint_every"] = k
    return out
