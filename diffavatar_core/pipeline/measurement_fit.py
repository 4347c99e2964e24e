"""Template measurement fit: a built-in template's own measurements (length, ease, sleeve
length, ...) fitted to the scan before the free-form co-optimization of the cage handles.

Every cage handle ζ_h lies on the template's outline at a known place: spec edge k, arc-length
fraction t along it (PanelInfo.loop_edge / loop_t). ζ(m) puts each handle at the same place on
the outline of the template re-specified with measurements m (templates.template_spec), on the
template's own mesh — no re-triangulation, so the drape is carried along warm-started like any
other iterate. Then
    φ(m) = φ(ζ(m), bending and body held),   dφ/dm = (∂ζ/∂m)ᵀ dφ/dζ,
with dφ/dζ from the adjoint (coopt.CoOptObjective) and ∂ζ/∂m by central differences of the
outline (analytic curves, no simulation). A few measurements move the whole outline
consistently — both sides of every seam, the sleeve cap solved to the armhole — a move the
handle-wise optimizer only approaches over many small steps and may stop short of (a t-shirt's
panels 65–67 cm long where the truth is 64: docs/pipeline.md). Units: m."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..lbfgs import minimize_lbfgs
from ..pattern.templates import FIT_MEASUREMENTS, template_measurements, template_spec

FD_STEP = 1e-4   # m: central-difference step of ∂ζ/∂m (the outline is smooth in m; ζ is linear in most)


class MeasurementMap:
    """ζ(m) (H, 2) m for the cage of `garment`, a built-in template `name` built on `landmarks`
    with the default measurements overridden by `measurements` (m; e.g. template_sizing's):
    handles(values0) == cage.zeta0. names: the fitted measurements (default
    templates.FIT_MEASUREMENTS[name]). Raises ValueError for a template without a parametric
    outline (a template file) or a garment not built from its spec."""

    def __init__(self, name: str, landmarks, garment, cage, names=None, measurements=None):
        if name not in FIT_MEASUREMENTS:
            raise ValueError(f"measurement fit: no parametric measurements for template {name!r} "
                             f"(built-ins: {sorted(FIT_MEASUREMENTS)})")
        self.name, self.landmarks, self.cage = name, landmarks, cage
        self.names = tuple(FIT_MEASUREMENTS[name] if names is None else names)
        m0 = template_measurements(name, landmarks, **(measurements or {}))
        self.values0 = np.array([float(getattr(m0, n)) for n in self.names])
        self.panel = np.asarray(cage.handle_panel)
        self.edge = np.empty(len(cage.handles), np.int32)
        self.t = np.empty(len(cage.handles))
        for p, info in enumerate(garment.panels):
            if info.loop_edge is None or info.loop_t is None:
                raise ValueError(f"measurement fit: panel {info.name!r} carries no outline parameters "
                                 f"(not built from the template's spec)")
            where = {int(v): j for j, v in enumerate(info.loop)}
            for h in np.flatnonzero(self.panel == p):
                j = where[int(cage.handles[h])]
                self.edge[h], self.t[h] = info.loop_edge[j], info.loop_t[j]
        # each panel's pattern-plane layout offset (build_garment's), constant in m
        self.offset = np.asarray(cage.zeta0, float) - self._on_outline(self.values0)

    def _on_outline(self, values) -> np.ndarray:
        spec = template_spec(self.name, self.landmarks, **dict(zip(self.names, map(float, values))))
        out = np.empty((len(self.edge), 2))
        for p in np.unique(self.panel):
            for k in np.unique(self.edge[self.panel == p]):
                sel = np.flatnonzero((self.panel == p) & (self.edge == k))
                out[sel] = spec.panels[p].edge_points(int(k), self.t[sel])
        return out

    def handles(self, values) -> np.ndarray:
        """(H, 2) m: the cage handles on the outline of measurements `values` (m, in self.names
        order). Raises ValueError when the template cannot be specified with them."""
        values = np.asarray(values, float).reshape(-1)
        if values.shape != self.values0.shape or not np.all(np.isfinite(values)) or np.any(values < 0):
            raise ValueError(f"measurements: expected {len(self.names)} non-negative finite values "
                             f"({', '.join(self.names)}), got {values}")
        return self._on_outline(values) + self.offset

    def parameters(self, zeta, vertices: bool) -> np.ndarray:
        """The co-optimization's 'handles' parameter vector for handles zeta (H, 2) m: zeta itself,
        or with the 'without control cage' parametrization (vertices) every rest vertex, W zeta."""
        return (self.cage.rest(zeta) if vertices else np.asarray(zeta, float)).reshape(-1)

    def jacobian(self, values, step: float = FD_STEP) -> np.ndarray:
        """(H·2, M) ∂ζ/∂m by central differences."""
        values = np.asarray(values, float).reshape(-1)
        J = np.empty((2 * len(self.edge), len(values)))
        for i in range(len(values)):
            e = np.zeros(len(values))
            e[i] = step
            J[:, i] = (self.handles(values + e) - self.handles(values - e)).reshape(-1) / (2 * step)
        return J


@dataclass
class MeasurementFitResult:
    names: tuple
    values0: np.ndarray          # (M,) m, the template's measurements (the fit's start)
    values: np.ndarray           # (M,) m, fitted (the last accepted L-BFGS iterate; values0 if none)
    handles: np.ndarray          # (H, 2) m, ζ(values)
    value0: float                # φ at the template (the fit's start)
    value: float                 # φ at the fitted measurements
    iterations: int
    stopped: str
    history: list = field(default_factory=list)
    rounds: list = field(default_factory=list)   # per fit run: {'start_m', 'fitted_m', 'loss_start', 'loss_fitted', 'iterations'}

    def __post_init__(self):
        if not self.rounds:
            self.rounds = [self._round()]

    def _round(self) -> dict:
        return {"start_m": [float(v) for v in self.values0], "fitted_m": [float(v) for v in self.values],
                "loss_start": self.value0, "loss_fitted": self.value, "iterations": self.iterations}

    def then(self, other: "MeasurementFitResult") -> "MeasurementFitResult":
        """This fit followed by `other` (started from this one's values, e.g. at another bending):
        the template's values and φ from this one, the fitted ones from `other`, the iterations and
        rounds of both."""
        return MeasurementFitResult(self.names, self.values0, other.values, other.handles, self.value0, other.value,
                                    self.iterations + other.iterations, other.stopped, self.history + other.history,
                                    self.rounds + other.rounds)

    def to_json(self) -> dict:
        return {"names": list(self.names), "template_m": [float(v) for v in self.values0],
                "fitted_m": [float(v) for v in self.values], "loss_template": self.value0,
                "loss_fitted": self.value, "iterations": self.iterations, "stopped": self.stopped,
                "rounds": self.rounds}


def measurement_objective(obj, mmap: MeasurementMap, held: dict, values):
    """(φ, {'measurements': dφ/dm (M,)}, terms) of CoOptObjective `obj` at the handles ζ(values),
    the other parameter groups `held` (a parameter dict without 'handles'). With obj's
    'without control cage' parametrization the rest vertices are W ζ(values)."""
    vertices = obj.cage is None
    value, grads, terms = obj({"handles": mmap.parameters(mmap.handles(values), vertices), **held})
    gz = grads["handles"]
    if vertices:   # dφ/dζ = Wᵀ dφ/dx̄ (Eq. 5)
        gz = mmap.cage.grad_zeta(gz.reshape(-1, 2))
    return value, {"measurements": mmap.jacobian(values).T @ np.asarray(gz).reshape(-1)}, terms


def fit_measurements(obj, mmap: MeasurementMap, params: dict, iterations: int, step: float,
                     on_iteration=None, cancelled=lambda: False, start=None) -> MeasurementFitResult:
    """Minimizes φ(ζ(m)) over the measurements m with L-BFGS (step: m per unit move), the other
    parameter groups of `params` (a CoOptObjective parameter dict) held, from the template's
    measurements or `start` (m, mmap.names order). obj: the CoOptObjective, whose cloth is at
    the start's drape; accepted iterates become its warm starts (commit), as in the
    co-optimization, and the cloth ends at the fitted pattern and its drape. Raises ValueError
    when φ cannot be evaluated at the start."""
    held = {g: v for g, v in params.items() if g != "handles"}
    m0 = mmap.values0.copy() if start is None else np.asarray(start, float).reshape(-1).copy()

    def evaluate(p):
        return measurement_objective(obj, mmap, held, p["measurements"])

    res = minimize_lbfgs(evaluate, {"measurements": m0}, {"measurements": step},
                         max_iterations=iterations, patience=obj.opts.patience, on_iteration=on_iteration,
                         cancelled=cancelled, on_accept=obj.commit, reevaluate=obj.opts.reevaluations,
                         reevaluate_tol=obj.opts.reevaluate_tol, on_revert=obj.revert)
    values = np.asarray(res.params["measurements"], float)   # the last accepted iterate: the warm start's
    if res.stopped != "cancelled":   # the cloth at the result, not at a last trial L-BFGS did not take
        obj.restore({"handles": mmap.parameters(mmap.handles(values), obj.cage is None), **held})
    return MeasurementFitResult(mmap.names, m0.copy(), values, mmap.handles(values),
                                float(res.history[0]["value"]), float(res.value), res.iterations, res.stopped,
                                res.history)


__all__ = ["MeasurementMap", "MeasurementFitResult", "fit_measurements", "measurement_objective"]
