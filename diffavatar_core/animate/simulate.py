"""Dynamic simulation of a draped garment on a moving body: per frame the body is posed by the
motion, its vertices become the collider (Control.body_vertices) and the garment takes
`substeps` XPBD steps of 1/(fps·substeps) s. Units: m, s."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .motions import motion_pose


@dataclass
class AnimationResult:
    garment: np.ndarray  # (T, V, 3) m
    body: np.ndarray     # (T, Vb, 3) m
    fps: float
    max_penetration: float  # m, over all frames
    max_distance: float     # m, farthest garment vertex from the body surface over all frames


def animate(cloth, body_model, params, motion, frames: int, fps: float = 30.0, substeps: int = 4,
            cycles: float = 1.0, iterations: int = 60, progress=None, cancel=None) -> AnimationResult:
    """cloth: a Cloth already draped on body_model.pose(params); motion: a MOTIONS name or a
    keyframe callable; `cycles` motion periods over the frames."""
    from .. import surface_distances
    if frames < 1 or fps <= 0 or substeps < 1:
        raise ValueError("frames, fps and substeps must be positive")
    base = np.array(params.pose)
    G, B = [], []
    worst_pen = worst_far = 0.0
    dt = 1.0 / (fps * substeps)
    for f in range(frames):
        if cancel is not None and cancel.cancelled():
            from .. import Cancelled
            raise Cancelled("animation")
        params.pose = base + motion_pose(body_model.joint_names, motion, cycles * f / frames)
        X = body_model.pose(params)
        cloth.set_control(body_vertices=X)
        cloth.step(substeps, dt=dt, iterations=iterations, damping=1.0)
        x = np.array(cloth.x)
        if not np.all(np.isfinite(x)):
            raise FloatingPointError(f"animation: non-finite garment positions at frame {f}")
        worst_pen = max(worst_pen, cloth.solver.max_penetration(x))
        worst_far = max(worst_far, float(surface_distances(x, X, body_model.faces).max()))
        G.append(x)
        B.append(X)
        if progress:
            progress(f + 1, frames)
    params.pose = base
    return AnimationResult(np.array(G), np.array(B), fps, worst_pen, worst_far)
