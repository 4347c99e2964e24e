"""Adam with per-group step sizes, step rejection and best-iterate tracking — the outer loop of
the recovery (paper §4.2.1: "We use gradient descent to optimize these variables over multiple
iterations").

Parameters come in named groups (e.g. 'cage' handles in m, 'log_bending' in log10 N·m, 'shape'
coefficients) because their scales differ by orders of magnitude; each group has its own step
size. An iteration whose proposed parameters are rejected by the caller (inverted rest
triangles, a drape that did not converge, a NaN, or a loss increase beyond a tolerance) is not
taken: all step sizes are halved and the step is re-proposed from the last accepted iterate."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np


@dataclass
class AdamState:
    m: dict = field(default_factory=dict)
    v: dict = field(default_factory=dict)
    t: int = 0


class GroupAdam:
    """Adam (Kingma & Ba 2015) over a dict of named parameter arrays."""

    def __init__(self, lr: dict, beta1: float = 0.9, beta2: float = 0.999, eps: float = 1e-12):
        if not lr or any(not (np.isfinite(v) and v > 0) for v in lr.values()):
            raise ValueError(f"lr: every group needs a positive finite step size, got {lr}")
        self.lr = dict(lr)
        self.beta1, self.beta2, self.eps = beta1, beta2, eps
        self.state = AdamState()

    def propose(self, params: dict, grads: dict) -> dict:
        """The next parameters (does not commit the moment estimates; see accept())."""
        t = self.state.t + 1
        out, self._pending = {}, {}
        for name, p in params.items():
            g = np.asarray(grads[name], dtype=np.float64)
            if g.shape != np.shape(p):
                raise ValueError(f"grads[{name!r}]: shape {g.shape} != parameter shape {np.shape(p)}")
            if not np.all(np.isfinite(g)):
                raise FloatingPointError(f"gradient of group {name!r} is not finite")
            m = self.beta1 * self.state.m.get(name, 0.0) + (1 - self.beta1) * g
            v = self.beta2 * self.state.v.get(name, 0.0) + (1 - self.beta2) * g * g
            mhat, vhat = m / (1 - self.beta1 ** t), v / (1 - self.beta2 ** t)
            out[name] = np.asarray(p, dtype=np.float64) - self.lr[name] * mhat / (np.sqrt(vhat) + self.eps)
            self._pending[name] = (m, v)
        return out

    def accept(self) -> None:
        for name, (m, v) in self._pending.items():
            self.state.m[name], self.state.v[name] = m, v
        self.state.t += 1

    def shrink(self, factor: float = 0.5) -> None:
        for k in self.lr:
            self.lr[k] *= factor


@dataclass
class OptimizeResult:
    params: dict            # best accepted parameters
    value: float            # their loss
    history: list           # per accepted iteration: dict(iteration, value, terms, lr)
    iterations: int         # accepted iterations
    rejected: int           # rejected proposals
    stopped: str            # 'max_iterations' | 'converged' | 'step_size' | 'cancelled'


def minimize(evaluate: Callable[[dict], tuple], params: dict, lr: dict, *, max_iterations: int = 50,
             rel_tol: float = 1e-4, patience: int = 5, max_rejections: int = 8, min_lr_factor: float = 1e-3,
             accept_increase: float = 0.25, on_iteration: Callable | None = None,
             cancelled: Callable[[], bool] = lambda: False) -> OptimizeResult:
    """Minimizes with GroupAdam. `evaluate(params)` returns (value, grads, terms) or raises
    ValueError/FloatingPointError for an invalid point (then that proposal is rejected).
    A proposal whose loss rises by more than `accept_increase` × the current loss is rejected
    too. When the loss has not improved by `rel_tol` (relative) for `patience` iterations the step
    sizes are halved. Stops after `max_iterations` accepted steps, when step sizes fell below
    `min_lr_factor` of their start ('converged' on a plateau, 'step_size' after rejections), or
    when `cancelled()`; the best iterate is returned."""
    opt = GroupAdam(lr)
    lr0 = dict(lr)
    value, grads, terms = evaluate(params)
    if not np.isfinite(value):
        raise FloatingPointError("the initial loss is not finite")
    best = (value, {k: np.array(v, dtype=np.float64) for k, v in params.items()})
    history = [{"iteration": 0, "value": value, "terms": terms, "lr": dict(opt.lr)}]
    if on_iteration:
        on_iteration(history[-1])
    accepted = rejected = stale = 0
    since_best_ref = value
    stopped = "max_iterations"
    while accepted < max_iterations:
        if cancelled():
            stopped = "cancelled"
            break
        proposal = opt.propose(params, grads)
        try:
            new_value, new_grads, new_terms = evaluate(proposal)
            ok = np.isfinite(new_value) and new_value <= value + accept_increase * abs(value)
        except (ValueError, FloatingPointError):
            ok = False
        if not ok:
            rejected += 1
            opt.shrink(0.5)
            if rejected > max_rejections * (accepted + 1) or all(opt.lr[k] < min_lr_factor * lr0[k] for k in lr0):
                stopped = "step_size"
                break
            continue
        opt.accept()
        accepted += 1
        params, value, grads, terms = proposal, new_value, new_grads, new_terms
        if value < best[0]:
            best = (value, {k: np.array(v) for k, v in params.items()})
        history.append({"iteration": accepted, "value": value, "terms": terms, "lr": dict(opt.lr)})
        if on_iteration:
            on_iteration(history[-1])
        if value < since_best_ref * (1 - rel_tol):
            since_best_ref, stale = value, 0
        else:
            stale += 1
        if stale >= patience:  # plateau: refine the step, stop once it is negligible
            opt.shrink(0.5)
            stale = 0
            if all(opt.lr[k] < min_lr_factor * lr0[k] for k in lr0):
                stopped = "converged"
                break
    return OptimizeResult(best[1], best[0], history, accepted, rejected, stopped)
