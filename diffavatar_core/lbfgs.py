"""L-BFGS with a backtracking (Armijo) line search over named parameter groups — the "or better"
of the outer loop (paper §4.2.1 uses gradient descent). The recovery objective is deterministic
(fixed surface samples, an equilibrium per evaluation), so a quasi-Newton model of its curvature
takes far fewer drapes than Adam to reach the same loss.

Groups are scaled by their step sizes (u = θ / s per group), so one unit of u is a sensible move
of every group (e.g. 4 mm of a cage handle, 0.1 decade of bending stiffness); the inverse Hessian
model (Nocedal & Wright 2006, Alg. 7.4) works in u. An evaluation that raises ValueError /
FloatingPointError (an inverted rest triangle, an unconverged drape, a NaN) counts as a failed
trial and the step is halved, exactly like an Armijo failure. Same result type as optim.minimize."""
from __future__ import annotations

from typing import Callable

import numpy as np

from .optim import OptimizeResult


def _flatten(params: dict, names) -> np.ndarray:
    return np.concatenate([np.asarray(params[k], np.float64).reshape(-1) for k in names])


def _unflatten(u: np.ndarray, like: dict, names) -> dict:
    out, i = {}, 0
    for k in names:
        shape = np.shape(like[k])
        n = int(np.prod(shape)) if shape else 1
        out[k] = u[i:i + n].reshape(shape).copy()
        i += n
    return out


def minimize_lbfgs(evaluate: Callable[[dict], tuple], params: dict, step: dict, *, max_iterations: int = 50,
                   rel_tol: float = 1e-4, patience: int = 5, memory: int = 8, max_step: float = 4.0,
                   c1: float = 1e-4, max_backtracks: int = 6, on_iteration: Callable | None = None,
                   cancelled: Callable[[], bool] = lambda: False, on_accept: Callable | None = None,
                   reevaluate: bool = False, precondition: dict | None = None,
                   on_revert: Callable | None = None, reevaluate_tol: float = 0.0) -> OptimizeResult:
    """Minimizes evaluate(params) -> (value, grads, terms). step: per-group scale (the unit move;
    e.g. m for handles). A step is at most `max_step` units in any component. Stops after
    `max_iterations` accepted steps, when `patience` successive steps improved the loss by less
    than `rel_tol` (relative; 'converged'), when the line search fails twice in a row from a
    reset model ('step_size'), or when `cancelled()`. The history holds one entry per accepted
    step (iteration, value, terms, lr = the step length taken, in group units × scale).

    on_accept() is called when a point becomes the current iterate. reevaluate (True or a count
    N): the objective depends on its evaluation history (the recovery's equilibria are anchored to
    the current iterate's drape), so an accepted point is evaluated again after on_accept() — up to
    N times, each from the previous one's drape, until φ changes by no more than reevaluate_tol
    (relative) — and the line search compares trials with the last value: the same anchor on both
    sides of the comparison. A trial whose re-evaluation fails (its drape does not re-drape from
    itself) is rejected like a failed trial, after one on_revert() per on_accept() of that trial.

    precondition: {group: P} with P(v) a symmetric positive definite linear operator on the group's
    flattened vector (in step units; mean eigenvalue ~1): the initial inverse Hessian H₀ of the
    two-loop recursion (identity for the other groups), i.e. the metric of the first, steepest-
    descent step and of every restart (e.g. pattern.sobolev.SobolevMetric for the handles)."""
    names = sorted(params)
    if any(not (np.isfinite(step.get(k, np.nan)) and step[k] > 0) for k in names):
        raise ValueError(f"step: every group needs a positive finite scale, got {step}")
    scale = np.concatenate([np.full(np.size(params[k]), float(step[k])) for k in names])
    bounds = np.cumsum([0] + [int(np.size(params[k])) for k in names])
    if precondition and set(precondition) - set(names):
        raise ValueError(f"precondition: unknown group(s) {sorted(set(precondition) - set(names))}")
    pre = {names.index(k): op for k, op in (precondition or {}).items()}

    def H0(v):
        if not pre:
            return v
        out = v.copy()
        for i, op in pre.items():
            out[bounds[i]:bounds[i + 1]] = op(v[bounds[i]:bounds[i + 1]])
        return out

    def f(u):
        p = _unflatten(u * scale, params, names)
        value, grads, terms = evaluate(p)
        g = _flatten(grads, names) * scale
        if not (np.isfinite(value) and np.all(np.isfinite(g))):
            raise FloatingPointError("non-finite loss or gradient")
        return float(value), g, terms

    u = _flatten(params, names) / scale
    value, g, terms = f(u)
    if on_accept:
        on_accept()
    history = [{"iteration": 0, "value": value, "terms": terms, "lr": dict(step)}]
    if on_iteration:
        on_iteration(history[-1])
    S, Y = [], []
    accepted = rejected = stale = 0
    stopped, failed_resets = "max_iterations", 0
    ref = value
    while accepted < max_iterations:
        if cancelled():
            stopped = "cancelled"
            break
        # two-loop recursion: d = −H g
        q, alphas = g.copy(), []
        for s, y in reversed(list(zip(S, Y))):
            a = (s @ q) / (y @ s)
            alphas.append(a)
            q -= a * y
        r = H0(q)
        gamma = (S[-1] @ Y[-1]) / (Y[-1] @ H0(Y[-1])) if S else 1.0 / max(np.abs(r).max(), 1e-300)
        r = gamma * r
        for (s, y), a in zip(zip(S, Y), reversed(alphas)):
            r += s * (a - (y @ r) / (y @ s))
        d = -r
        if not g @ d < 0:   # not a descent direction (numerical): restart from steepest descent
            S, Y = [], []
            d = -H0(g)
            d /= max(np.abs(d).max(), 1e-300)
        big = np.abs(d).max()
        if big > max_step:
            d *= max_step / big
        alpha, ok = 1.0, False
        for _ in range(max_backtracks + 1):
            if cancelled():
                break
            try:
                v_new, g_new, t_new = f(u + alpha * d)
                ok = v_new <= value + c1 * alpha * (g @ d)
            except (ValueError, FloatingPointError):
                ok = False
            if ok and reevaluate:   # the trial becomes the anchor; it must re-evaluate from itself
                v_re, g_re, t_re, commits = v_new, g_new, t_new, 0
                for _ in range(int(reevaluate)):
                    if on_accept:
                        on_accept()
                    commits += 1
                    try:
                        v_prev, (v_re, g_re, t_re) = v_re, f(u + alpha * d)
                    except (ValueError, FloatingPointError):
                        ok = False
                        for _ in range(commits):
                            if on_revert:
                                on_revert()
                        break
                    if abs(v_re - v_prev) <= reevaluate_tol * abs(v_prev):
                        break
            if ok:
                break
            rejected += 1
            alpha *= 0.5
        if cancelled() and not ok:
            stopped = "cancelled"
            break
        if not ok:
            if not S:       # already steepest descent with a fresh model
                failed_resets += 1
                if failed_resets >= 2:
                    stopped = "step_size"
                    break
            S, Y = [], []
            continue
        failed_resets = 0
        s_k, y_k = alpha * d, g_new - g
        if s_k @ y_k > 1e-10 * np.linalg.norm(s_k) * np.linalg.norm(y_k):
            S.append(s_k)
            Y.append(y_k)
            if len(S) > memory:
                S.pop(0)
                Y.pop(0)
        u, value, g, terms = u + s_k, v_new, g_new, t_new
        if reevaluate:
            value, g, terms = v_re, g_re, t_re
        if on_accept:
            on_accept()
        accepted += 1
        taken = np.abs(s_k).max()
        history.append({"iteration": accepted, "value": value, "terms": terms,
                        "lr": {k: float(step[k] * taken) for k in names}})
        if on_iteration:
            on_iteration(history[-1])
        if value < ref * (1 - rel_tol):
            ref, stale = value, 0
        else:
            stale += 1
            if stale >= patience:
                stopped = "converged"
                break
    # Armijo steps decrease the loss (re-evaluated values may rise a little): the last iterate is
    # the one the caller's state (warm starts) belongs to
    return OptimizeResult(_unflatten(u * scale, params, names), value, history, accepted, rejected, stopped)
