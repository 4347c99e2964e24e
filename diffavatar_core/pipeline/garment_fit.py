"""Garment recovery through the differentiable drape (paper §4.2), the core of the pipeline:
fit the sewing pattern (and bending stiffness) so the draped garment matches a scan's garment
points and boundary loops. Gradients come from the equilibrium adjoint (one sparse solve per
iteration, warm-started re-drapes), the loss is ρ L_boundary + σ L_interior (paper §4.2.5).

Pattern parametrisation (until the control cage with mean value coordinates is wired in): one
2×2 linear map per panel about its rest centroid, x̄ = c_p + (I + A_p)(x̄₀ − c_p) — width,
length and shear of every panel. Units: m; bending as log10 of N·m."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..adjoint import equilibrium_gradient
from ..loss import boundary_loss, garment_samples, interior_loss
from ..optim import minimize
from ..sim.cloth import Cloth


@dataclass
class GarmentFitResult:
    rest: np.ndarray            # (V,2) m, the recovered pattern
    bend_stiffness: np.ndarray  # (G,) N·m
    panel_maps: np.ndarray      # (P,2,2) I + A_p
    x: np.ndarray               # (V,3) m, the drape of the recovered pattern
    loss_initial: float
    loss_final: float
    history: list
    stopped: str


def fit_garment(cloth: Cloth, faces, panel_of_vertex, garment_loops: dict, scan_points, scan_loops: dict,
                rho: float = 1.0, sigma: float = 1.0, fit_bending: bool = True, max_iterations: int = 30,
                lr_affine: float = 0.02, lr_log_bend: float = 0.1, samples: int = 2000,
                drape_kw: dict | None = None, on_iteration=None, cancelled=lambda: False) -> GarmentFitResult:
    """cloth: a draped Cloth built from the template; faces (F,3); panel_of_vertex (V,) ints;
    garment_loops: name → vertex chain; scan_points (N,3) m and scan_loops: name → (K,3) m."""
    faces = np.asarray(faces, dtype=np.int32)
    panel = np.asarray(panel_of_vertex, dtype=np.int64)
    if panel.shape != (len(cloth.x),):
        raise ValueError(f"panel_of_vertex: expected ({len(cloth.x)},), got {panel.shape}")
    scan_points = np.asarray(scan_points, dtype=np.float64)
    c0 = cloth.control
    rest0 = np.array(c0.rest)
    npanel = int(panel.max()) + 1
    centres = np.array([rest0[panel == p].mean(axis=0) for p in range(npanel)])
    rel0 = rest0 - centres[panel]
    kw = dict(max_steps=600, min_steps=1, residual_tol=1e-7, refine_iterations=80)
    kw.update(drape_kw or {})
    gsamples = garment_samples(cloth.x, faces, samples, seed=0)
    state = {"x": np.array(cloth.x)}

    def unpack(params):
        maps = np.eye(2)[None] + params["affine"].reshape(npanel, 2, 2)
        rest = centres[panel] + np.einsum("vij,vj->vi", maps[panel], rel0)
        bend = 10.0 ** params["log_bend"] if fit_bending else np.array(c0.bend_stiffness)
        return maps, rest, bend

    def evaluate(params):
        maps, rest, bend = unpack(params)
        if np.any(np.linalg.det(maps) <= 0.2):
            raise ValueError("a panel map degenerates")
        cloth.set_control(rest=rest, bend_stiffness=bend)  # raises ValueError on inverted triangles
        # a small change of θ moves the equilibrium a little: re-solve from the last one
        cloth.reequilibrate(state["x"], kw["residual_tol"], kw["refine_iterations"], kw["max_steps"])
        x = np.array(cloth.x)
        li = interior_loss(x, faces, gsamples, scan_points)
        lb = boundary_loss(x, garment_loops, scan_loops)
        value = rho * lb.value + sigma * li.value
        g = equilibrium_gradient(cloth, rho * lb.grad + sigma * li.grad)
        grest = g["rest"]
        gaff = np.zeros((npanel, 2, 2))
        np.add.at(gaff, panel, np.einsum("vi,vj->vij", grest, rel0))
        grads = {"affine": gaff.reshape(-1)}
        if fit_bending:
            grads["log_bend"] = g["bend_stiffness"] * bend * np.log(10.0)
        state["x"] = x
        return value, grads, {"boundary": lb.value, "interior": li.value}

    params = {"affine": np.zeros(npanel * 4)}
    lr = {"affine": lr_affine}
    if fit_bending:
        params["log_bend"] = np.log10(np.array(c0.bend_stiffness))
        lr["log_bend"] = lr_log_bend
    res = minimize(evaluate, params, lr, max_iterations=max_iterations, on_iteration=on_iteration,
                   cancelled=cancelled)
    maps, rest, bend = unpack(res.params)
    cloth.set_control(rest=rest, bend_stiffness=bend)
    cloth.state.x = state["x"]
    cloth.refine(keep_anchor=False, residual_tol=kw["residual_tol"], refine_iterations=kw["refine_iterations"])
    return GarmentFitResult(rest, np.asarray(bend), maps, np.array(cloth.x), res.history[0]["value"],
                            res.value, res.history, res.stopped)
