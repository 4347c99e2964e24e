"""Co-optimization of pattern, material and body through the differentiable drape (paper §4.2).

θ = {control-cage handles ζ of every panel (Eq. 5: x̄ = W ζ) — or every pattern vertex, the
'without control cage' ablation —, log10 bending stiffness (one per garment or per panel), body
shape ν and pose ψ}. Each evaluation re-drapes from the previous equilibrium (Newton from the
warm start; a full XPBD + Newton drape only if that fails), evaluates
    φ = ρ L_boundary + σ L_interior + α L_seam(x̄) + β L_curvature(x̄) + γ |(ν, ψ) − (ν, ψ)_fit|²,
and gets dφ/dθ from the equilibrium adjoint (one sparse solve; the fast mode, exact at a
converged drape with a fixed contact set — see diffavatar_core/adjoint.py), chained through W
for ζ and through the skinning Jacobians for ν and ψ. Group Adam keeps the best iterate; an
iterate with an inverted rest triangle, a seam mismatch above the limit, an unconverged drape
or a non-finite value is rejected and the step size halved (optim.minimize). Units: m, N·m, rad."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..adjoint import equilibrium_gradient
from ..body.params import BodyParams
from ..loss import boundary_loss, garment_samples, interior_loss
from ..optim import minimize
from ..pattern.regularizers import CurvatureRegularizer, SeamLengthRegularizer
from .options import RecoverOptions


@dataclass
class CoOptResult:
    rest: np.ndarray             # (V, 2) m, the recovered pattern
    bend_stiffness: np.ndarray   # (G,) N·m, per material group (panel)
    body_params: BodyParams | None
    body_vertices: np.ndarray | None  # (Vb, 3) m, posed
    x: np.ndarray                # (V, 3) m, the drape of the recovered parameters
    history: list                # per accepted iteration: iteration, value, terms, lr
    iterations: int
    rejected: int
    stopped: str


def seam_mismatch_pct(g, rest) -> float:
    """Largest relative length difference of a sewn boundary edge pair, % of the longer one."""
    P = g.seam_edge_pairs()
    if not len(P):
        return 0.0
    la = np.linalg.norm(rest[P[:, 1]] - rest[P[:, 0]], axis=1)
    lb = np.linalg.norm(rest[P[:, 3]] - rest[P[:, 2]], axis=1)
    return float(100 * np.max(np.abs(la - lb) / np.maximum(np.maximum(la, lb), 1e-12)))


def co_optimize(cloth, garment, scan_points, scan_loops: dict, opts: RecoverOptions, cage=None,
                body_model=None, body_params: BodyParams | None = None, on_iteration=None,
                cancelled=lambda: False, cancel=None) -> CoOptResult:
    """cloth: the Cloth of `garment` (a pattern.Garment), already draped to equilibrium on the
    body; scan_points (N, 3) m: the scan's garment samples; scan_loops: opening name → (K, 3) m
    (matched by name to garment.boundaries); cage: a pattern.ControlCage (parametrization
    'cage'); body_model/body_params: co-optimize ν, ψ when given and opts.optimize_body."""
    g = garment
    faces = np.asarray(g.faces, np.int32)
    w, lr0 = opts.weights, opts.step_sizes
    scan_points = np.asarray(scan_points, np.float64)
    loops = {k: v for k, v in g.boundaries.items() if k in scan_loops}
    c0 = cloth.control
    ngroups = len(np.asarray(c0.bend_stiffness))
    seam_reg = SeamLengthRegularizer(g)
    curv_reg = CurvatureRegularizer(g)
    samples = garment_samples(cloth.x, faces, opts.samples, seed=0)
    use_body = bool(opts.optimize_body and body_model is not None and body_params is not None)
    if use_body:
        sl = body_model.param_slices()
        p0 = body_params.copy()
        K, J = body_model.num_shape, body_model.num_joints
    state = {"x": np.array(cloth.x)}

    def unpack(params):
        rest = cage.rest(params["handles"].reshape(-1, 2)) if cage is not None else params["handles"].reshape(-1, 2)
        if opts.bending == "fixed":
            bend = np.asarray(c0.bend_stiffness)
        else:
            bend = np.broadcast_to(10.0 ** params["log_bend"], (ngroups,)).copy()
        bp = None
        if use_body:
            bp = p0.copy()
            bp.shape[:] = params["shape"]
            bp.pose[:] = params["pose"].reshape(J, 3)
        return rest, bend, bp

    def drape_at(rest, bend, body_vertices):
        cloth.set_control(rest=rest, bend_stiffness=bend, body_vertices=body_vertices)  # ValueError: inverted
        cloth.state.x = state["x"]
        cloth.state.v = np.zeros_like(state["x"])
        _, res = cloth.refine(keep_anchor=False, residual_tol=opts.residual_tol, refine_iterations=80, cancel=cancel)
        if not res <= opts.residual_tol:
            cloth.state.x = state["x"]
            r = cloth.drape(max_steps=opts.drape_steps, iterations=opts.drape_iterations, min_steps=1,
                            residual_tol=opts.residual_tol, refine_iterations=120, raise_on_divergence=False,
                            cancel=cancel)
            if not r.converged:
                raise ValueError(f"drape did not converge: {r.message}")

    def evaluate(params):
        rest, bend, bp = unpack(params)
        mismatch = seam_mismatch_pct(g, rest)
        if mismatch > opts.max_seam_mismatch_pct:
            raise ValueError(f"seam mismatch {mismatch:.1f}% above the limit")
        bv = body_model.pose(bp) if use_body else None
        drape_at(rest, bend, bv)
        x = np.array(cloth.x)
        li = interior_loss(x, faces, samples, scan_points)
        lb = boundary_loss(x, loops, scan_loops) if loops else None
        ls, gs = seam_reg.value_and_grad(rest)
        lc, gc = curv_reg.value_and_grad(rest)
        dphi_dx = w.interior * li.grad + (w.boundary * lb.grad if lb is not None else 0.0)
        ga = equilibrium_gradient(cloth, dphi_dx, cancel=cancel)
        g_rest = ga["rest"] + w.seam * gs + w.curvature * gc
        terms = {"boundary": lb.value if lb is not None else 0.0, "interior": li.value, "seam": ls, "curvature": lc}
        value = (w.boundary * terms["boundary"] + w.interior * li.value + w.seam * ls + w.curvature * lc)
        grads = {"handles": (cage.grad_zeta(g_rest) if cage is not None else g_rest).reshape(-1)}
        if opts.bending != "fixed":
            gb = np.asarray(ga["bend_stiffness"]) * bend * np.log(10.0)
            grads["log_bend"] = gb if opts.bending == "panel" else np.array([gb.sum()])
        if use_body:
            gvec = body_model.vjp(bp, ga["body_vertices"])
            dnu, dpsi = bp.shape - p0.shape, (bp.pose - p0.pose).reshape(-1)
            prior = float(dnu @ dnu + dpsi @ dpsi)
            terms["body_prior"] = prior
            value += w.body_prior * prior
            grads["shape"] = gvec[sl["shape"]] + 2 * w.body_prior * dnu
            grads["pose"] = gvec[sl["pose"]] + 2 * w.body_prior * dpsi
        state["x"] = x
        return float(value), grads, terms

    params = {"handles": (cage.zeta0 if cage is not None else np.asarray(c0.rest)).reshape(-1).astype(np.float64)}
    lr = {"handles": lr0.handles}
    if opts.bending != "fixed":
        b0 = np.log10(np.maximum(np.asarray(c0.bend_stiffness), 1e-12))
        params["log_bend"] = b0 if opts.bending == "panel" else np.array([b0.mean()])
        lr["log_bend"] = lr0.log10_bending
    if use_body:
        params["shape"] = p0.shape.copy()
        params["pose"] = p0.pose.reshape(-1).copy()
        lr["shape"], lr["pose"] = lr0.shape, lr0.pose
    if opts.iterations == 0:
        value, _, terms = evaluate(params)
        history = [{"iteration": 0, "value": value, "terms": terms, "lr": lr}]
        if on_iteration:
            on_iteration(history[-1])
        best, it, rej, stopped = params, 0, 0, "max_iterations"
    else:
        res = minimize(evaluate, params, lr, max_iterations=opts.iterations, patience=opts.patience,
                       on_iteration=on_iteration, cancelled=cancelled)
        best, history, it, rej, stopped = res.params, res.history, res.iterations, res.rejected, res.stopped
    rest, bend, bp = unpack(best)
    drape_at(rest, bend, body_model.pose(bp) if use_body else None)   # the best iterate's equilibrium
    return CoOptResult(rest, bend, bp if use_body else body_params,
                       body_model.pose(bp) if use_body else None, np.array(cloth.x), history, it, rej, stopped)
