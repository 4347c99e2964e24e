"""Co-optimization of pattern, material and body through the differentiable drape (paper §4.2).

θ = {control-cage handles ζ of every panel (Eq. 5: x̄ = W ζ) — or every pattern vertex, the
'without control cage' ablation —, log10 bending stiffness (one per garment or per panel),
optionally log10 stretch compliances (warp, weft, shear; one set), body shape ν and pose ψ}.
Each evaluation re-drapes from the previous equilibrium (Newton from the warm start; a full
XPBD + Newton drape only if that fails; every `fresh_every` iterations also a drape from the
template layout, a re-drape from the template's initial drape and a scan-guided drape
(guided_drape.py), each kept as the warm start when its φ is lower, and the bending × 10^±1
re-draped and guided, kept with its drape when φ is 2% lower: try_bending), evaluates
    φ = ρ L_boundary + σ L_interior + α L_seam(x̄) + β L_curvature(x̄)
        + δ L_body(ν, ψ) + γ |(ν, ψ) − (ν, ψ)_fit|²,
(L_body: the scan's visible body points to the posed body surface, full scans only — without it
the body drifts to explain garment misfit),
and gets dφ/dθ from the equilibrium adjoint (one sparse solve; the fast mode, exact at a
converged drape with a fixed contact set — see diffavatar_core/adjoint.py), chained through W
for ζ and through the skinning Jacobians for ν and ψ. L-BFGS (lbfgs.py; or group Adam, optim.py):
an iterate with an inverted rest triangle, a seam mismatch above the limit, an unconverged drape
or a non-finite value is rejected and the step halved. L_length is zero within ± the scan
perimeter's tolerance (loss.boundary_length_loss). Units: m, N·m, rad."""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from .._core import Cancelled
from ..adjoint import equilibrium_gradient
from ..body.params import BodyParams
from ..loss import body_data_loss, boundary_length_loss, boundary_loss, garment_samples, interior_loss, polyline_length
from ..lbfgs import minimize_lbfgs
from ..optim import minimize
from ..pattern.regularizers import CurvatureRegularizer, SeamLengthRegularizer
from ..pattern.sobolev import SobolevMetric
from .bending_range import bending_range
from .candidate_workers import run_on_twins, worker_count
from .guided_drape import guided_equilibrium
from .measurement_fit import fit_measurements
from .options import RecoverOptions

BENDING_RANGE = (1e-7, 1e-3)   # N·m: bending candidates (try_bending) outside it are not tried: about
# Kawabata B = 0.001 … 10 gf·cm²/cm (1 gf·cm²/cm ≈ 9.8e-5 N·m), the softest silks to stiffer than heavy denim
FRESH_JITTER = 0.003   # m: normal noise on the template layout of a fresh drape other than the first (fresh_min)


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
    fresh_kept: int = 0          # fresh drapes (fresh_every) that became the warm start
    guided_kept: int = 0         # scan-guided drapes (guided_stiffness) that became the warm start
    measurement_fit: object = None  # measurement_fit.MeasurementFitResult of the first stage, or None
    stretch_compliance: np.ndarray | None = None  # (G, 3) m/N [warp, weft, shear] of the returned drape
    stop_reason: str = ""        # stopped 'invalid_start': why the stage's start did not re-drape
    initial_kept: int = 0        # re-drapes from the template's initial drape (try_initial) that became the warm start
    bending_kept: int = 0        # bending candidates (try_bending) that became the iterate and its warm start
    bending_search: dict | None = None  # the bending searched after the first measurement fit (search_bending), or None
    bending_range: dict | None = None   # the bendings judged alike the recovered one (bending_range.py), or None


def seam_mismatch_pct(g, rest) -> float:
    """Largest relative length difference of a sewn boundary edge pair, % of the longer one."""
    P = g.seam_edge_pairs()
    if not len(P):
        return 0.0
    la = np.linalg.norm(rest[P[:, 1]] - rest[P[:, 0]], axis=1)
    lb = np.linalg.norm(rest[P[:, 3]] - rest[P[:, 2]], axis=1)
    return float(100 * np.max(np.abs(la - lb) / np.maximum(np.maximum(la, lb), 1e-12)))


class CoOptObjective:
    """φ(θ) and dφ/dθ of the co-optimization. cloth: the Cloth of `garment` (a pattern.Garment),
    draped to equilibrium on the body; scan_points (N, 3) m: the scan's garment samples;
    scan_loops: opening name → (K, 3) m (matched by name to garment.boundaries); cage: a
    pattern.ControlCage (parametrization 'cage', else every rest vertex is a parameter);
    body_model/body_params: ν, ψ are parameters when given and opts.optimize_body;
    body_points (N, 3) m: the scan's body-labelled points (full scans; None or empty: no L_body);
    scan_mesh (V (N, 3) m, F (M, 3)): the scan's garment surface, for scan-guided drapes
    (try_guided; None: none) and, with opts.interior_to 'surface', the target of the garment
    samples in L_interior (None: they go to the nearest of scan_points).
    Parameter groups: handles ((H·2,) m), log_bend ((1,) or (G,) log10 N·m), log_stretch ((3,)
    log10 m/N, opts.stretch 'garment'), shape ((K,)), pose ((J·3,) rad)."""

    def __init__(self, cloth, garment, scan_points, scan_loops: dict, opts: RecoverOptions, cage=None,
                 body_model=None, body_params: BodyParams | None = None, cancel=None, body_points=None,
                 scan_mesh=None):
        self.cloth, self.g, self.opts, self.cage, self.cancel = cloth, garment, opts, cage, cancel
        # converted once: every guided drape queries it several times
        self.scan_mesh = None if scan_mesh is None else (np.ascontiguousarray(scan_mesh[0], np.float64),
                                                         np.ascontiguousarray(scan_mesh[1], np.int32))
        self.faces = np.asarray(garment.faces, np.int32)
        self.scan_points = np.asarray(scan_points, np.float64)
        self.scan_loops = scan_loops
        self.loops = {k: v for k, v in garment.boundaries.items() if k in scan_loops}
        # scan opening perimeters (m) and how far they are trusted (± m)
        spacing = opts.edge_length if opts.length_measure == "resampled" else 0.0
        self.scan_lengths = {k: polyline_length(scan_loops[k], spacing, opts.length_smoothing) for k in self.loops}
        self.length_tol = {k: max(opts.length_tolerance_min, 0.01 * opts.length_tolerance_pct * L)
                           for k, L in self.scan_lengths.items()}
        self.c0 = cloth.control
        self.ngroups = len(np.asarray(self.c0.bend_stiffness))
        self.seam_reg = SeamLengthRegularizer(garment)
        self.curv_reg = CurvatureRegularizer(garment)
        self.samples = garment_samples(cloth.x, self.faces, opts.samples, seed=0)
        self.use_body = bool(opts.optimize_body and body_model is not None and body_params is not None)
        self.model, self.p0 = body_model, (body_params.copy() if body_params is not None else None)
        self.x_warm = np.array(cloth.x)   # start and anchor of every re-drape: the current iterate's drape
        self.x_initial = self.x_warm.copy()   # the template's initial drape (try_initial)
        self.x_last = self.x_warm
        self._undo = []          # warm starts before the last commits (revert)
        self.params_last = None  # the parameters x_last is the drape of (the last evaluation)
        self.current = None      # (params, drape) of the optimizer's current iterate (commit, mark_current)
        self._current_undo = []  # `current` before the last commits (revert)
        self.last_fresh = None   # (φ warm, φ fresh) of the last try_fresh
        self.last_guided = None  # (φ warm, φ guided) of the last try_guided
        self.last_initial = None  # (φ warm, φ from the initial drape) of the last try_initial
        self.last_bending = None  # φ of the candidate the last try_bending kept (None: none kept)
        self.last_bending_judged = []   # (k_b N·m, φ judged, the current's φ) per candidate of the last try_bending
        self.last_bending_current = None   # φ at the last try_bending's parameters from its warm start (None: not evaluated)
        self._fresh_seen = {}    # params key -> (φ, drape) of recent fresh drapes (_fresh_value)
        bp = np.zeros((0, 3)) if body_points is None else np.asarray(body_points, np.float64).reshape(-1, 3)
        if len(bp) > opts.samples:   # a fixed, reproducible subset
            bp = bp[np.random.default_rng(0).choice(len(bp), opts.samples, replace=False)]
        self.body_points = bp

    def initial_params(self) -> dict:
        c0, o = self.c0, self.opts
        params = {"handles": (self.cage.zeta0 if self.cage is not None else np.asarray(c0.rest)).reshape(-1).astype(np.float64)}
        if o.bending != "fixed":
            b0 = np.log10(np.maximum(np.asarray(c0.bend_stiffness), 1e-12))
            params["log_bend"] = b0 if o.bending == "panel" else np.array([b0.mean()])
        if o.stretch != "fixed":   # one [warp, weft, shear] set (geometric mean over the groups)
            params["log_stretch"] = np.log10(np.asarray(c0.stretch_compliance).reshape(-1, 3)).mean(axis=0)
        if self.use_body:
            params["shape"] = self.p0.shape.copy()
            params["pose"] = self.p0.pose.reshape(-1).copy()
        return params

    def step_sizes(self) -> dict:
        s = self.opts.step_sizes
        lr = {"handles": s.handles}
        if self.opts.bending != "fixed":
            lr["log_bend"] = s.log10_bending
        if self.opts.stretch != "fixed":
            lr["log_stretch"] = s.log10_stretch
        if self.use_body:
            lr["shape"], lr["pose"] = s.shape, s.pose
        return lr

    def precondition(self) -> dict:
        """{'handles': SobolevMetric} (opts.sobolev_length > 0), the L-BFGS initial metric of the
        pattern parameters, built on the template's rest pattern; {} when off."""
        if not self.opts.sobolev_length:
            return {}
        W = self.cage.W if self.cage is not None else None
        return {"handles": SobolevMetric(self.g.rest, self.faces, W, self.opts.sobolev_length)}

    def unpack(self, params):
        """(rest (V, 2) m, bend (G,) N·m, BodyParams or None) of a parameter dict."""
        h = np.asarray(params["handles"], np.float64).reshape(-1, 2)
        rest = self.cage.rest(h) if self.cage is not None else h
        if self.opts.bending == "fixed":
            bend = np.asarray(self.c0.bend_stiffness)
        else:
            bend = np.broadcast_to(10.0 ** np.asarray(params["log_bend"]), (self.ngroups,)).copy()
        bp = None
        if self.use_body:
            bp = self.p0.copy()
            bp.shape[:] = params["shape"]
            bp.pose[:] = np.asarray(params["pose"]).reshape(self.model.num_joints, 3)
        return rest, bend, bp

    def stretch(self, params):
        """(G, 3) m/N [warp, weft, shear] compliances per group of a parameter dict, or None when
        they are not optimized (the cloth keeps its own)."""
        if self.opts.stretch == "fixed":
            return None
        return np.broadcast_to(10.0 ** np.asarray(params["log_stretch"], np.float64), (self.ngroups, 3)).copy()

    def drape_at(self, rest, bend, body_vertices, stretch=None):
        """Equilibrium at these controls, warm-started from the last one (Newton; a full XPBD +
        Newton drape if that fails). Raises ValueError when no equilibrium is reached."""
        o = self.opts
        self.cloth.set_control(rest=rest, bend_stiffness=bend, body_vertices=body_vertices,
                               stretch_compliance=stretch)  # ValueError: inverted
        self.cloth.reequilibrate(self.x_warm, o.residual_tol, max_steps=o.drape_steps, iterations=o.drape_sweeps,
                                 cancel=self.cancel)

    def __call__(self, params):
        """(φ, {group: dφ/dgroup}, {term: value}); raises ValueError for an invalid iterate."""
        return self._evaluate(params, gradient=True)

    def value(self, params) -> float:
        """φ at `params` — the same drape and value as __call__ — without the adjoint solve and
        the body's VJP: what the candidate comparisons (try_fresh … try_bending) need."""
        return self._evaluate(params, gradient=False)[0]

    def _evaluate(self, params, gradient: bool):
        o, w = self.opts, self.opts.weights
        rest, bend, bp = self.unpack(params)
        mismatch = seam_mismatch_pct(self.g, rest)
        if mismatch > o.max_seam_mismatch_pct:
            raise ValueError(f"seam mismatch {mismatch:.1f}% above the limit")
        bv = self.model.pose(bp) if self.use_body else None
        stretch = self.stretch(params)
        self.drape_at(rest, bend, bv, stretch)
        x = np.array(self.cloth.x)
        surface = self.scan_mesh if o.interior_to == "surface" else None
        li = interior_loss(x, self.faces, self.samples, self.scan_points, scan_surface=surface)
        lb = boundary_loss(x, self.loops, self.scan_loops, o.boundary_scale) if self.loops else None
        ll = boundary_length_loss(x, self.loops, self.scan_lengths, self.length_tol) if self.loops else None
        ls, gs = self.seam_reg.value_and_grad(rest)
        lc, gc = self.curv_reg.value_and_grad(rest)
        terms = {"boundary": lb.value if lb is not None else 0.0,
                 "boundary_length": ll.value if ll is not None else 0.0,
                 "interior": li.value, "seam": ls, "curvature": lc}
        value = (w.boundary * terms["boundary"] + w.boundary_length * terms["boundary_length"]
                 + w.interior * li.value + w.seam * ls + w.curvature * lc)
        ld = None
        if self.use_body:
            if len(self.body_points) and w.body_data > 0:
                ld = body_data_loss(bv, self.model.faces, self.body_points, o.body_trim_distance)
                terms["body_data"] = ld.value
                value += w.body_data * ld.value
            dnu, dpsi = bp.shape - self.p0.shape, (bp.pose - self.p0.pose).reshape(-1)
            terms["body_prior"] = float(dnu @ dnu + dpsi @ dpsi)
            value += w.body_prior * terms["body_prior"]
        if not gradient:
            self.x_last, self.params_last = x, params
            return float(value), None, terms
        dphi_dx = w.interior * li.grad + (w.boundary * lb.grad + w.boundary_length * ll.grad if lb is not None else 0.0)
        ga = equilibrium_gradient(self.cloth, dphi_dx, cancel=self.cancel)   # the adjoint solve
        g_rest = ga["rest"] + w.seam * gs + w.curvature * gc
        grads = {"handles": (self.cage.grad_zeta(g_rest) if self.cage is not None else g_rest).reshape(-1)}
        if o.bending != "fixed":
            gb = np.asarray(ga["bend_stiffness"]) * bend * np.log(10.0)
            grads["log_bend"] = gb if o.bending == "panel" else np.array([gb.sum()])
        if stretch is not None:   # d/dlog10 α = α ln10 dφ/dα, summed over the groups (one shared set)
            grads["log_stretch"] = (np.asarray(ga["stretch_compliance"]).reshape(-1, 3) * stretch * np.log(10.0)).sum(axis=0)
        if self.use_body:
            sl = self.model.param_slices()
            g_body = np.asarray(ga["body_vertices"])
            if ld is not None:
                g_body = g_body + w.body_data * ld.grad
            gvec = self.model.vjp(bp, g_body)
            grads["shape"] = gvec[sl["shape"]] + 2 * w.body_prior * dnu
            grads["pose"] = gvec[sl["pose"]] + 2 * w.body_prior * dpsi
        self.x_last, self.params_last = x, params
        return float(value), grads, terms

    def restore(self, params) -> None:
        """Puts the cloth at `params`' controls and at the warm start — that iterate's drape when
        `params` is the optimizer's current iterate. An optimizer's last evaluation can be a
        trial it did not take, which leaves the cloth at the trial's pattern."""
        rest, bend, bp = self.unpack(params)
        self.cloth.set_control(rest=rest, bend_stiffness=bend, body_vertices=self.model.pose(bp) if self.use_body else None,
                               stretch_compliance=self.stretch(params))
        self.cloth.reset(self.x_warm)

    def fresh_drape_at(self, rest, bend, body_vertices, stretch=None, jitter: int = 0):
        """Equilibrium at these controls from the template's own 3D layout — sewn and draped as
        the initial drape is, not warm-started. jitter j > 0: the layout moved by normal noise of
        FRESH_JITTER (m) drawn with seed j, for another of a soft fabric's fold states (fresh_min).
        Raises ValueError when it does not converge."""
        o = self.opts
        self.cloth.set_control(rest=rest, bend_stiffness=bend, body_vertices=body_vertices, stretch_compliance=stretch)
        x0 = np.asarray(self.g.x0, np.float64)
        if jitter:
            x0 = x0 + np.random.default_rng(int(jitter)).normal(scale=FRESH_JITTER, size=x0.shape)
        self.cloth.reset(x0)
        self.cloth.sew(cancel=self.cancel)
        r = self.cloth.drape(max_steps=max(o.drape_steps, 1), iterations=o.drape_sweeps,
                             residual_tol=o.residual_tol, refine_iterations=120, raise_on_divergence=False,
                             cancel=self.cancel)
        if not r.converged:
            raise ValueError(f"fresh drape did not converge: {r.message}")

    def fresh_drape(self, params, jitter: int = 0) -> None:
        """fresh_drape_at with the controls of `params` (ValueError when it does not converge)."""
        rest, bend, bp = self.unpack(params)
        self.fresh_drape_at(rest, bend, self.model.pose(bp) if self.use_body else None, self.stretch(params), jitter)

    def _value_or_inf(self, params) -> float:
        try:
            v = self.value(params)
        except (ValueError, FloatingPointError):
            return np.inf
        return v if np.isfinite(v) else np.inf

    def _try_candidate(self, params, redrape) -> tuple[float, float, bool]:
        """φ at `params` from the current warm start, then from the equilibrium redrape() leaves
        the cloth in (called with the warm evaluation's drape in the cloth; it raises ValueError
        when it finds none); the lower becomes the warm start. A failed evaluation counts as
        φ = ∞. Returns (φ warm, φ candidate, candidate kept)."""
        x_keep = np.array(self.x_warm)
        v_warm = self._value_or_inf(params)
        try:
            redrape(v_warm)
            self.x_warm = np.array(self.cloth.x)
            v_cand = self._value_or_inf(params)
        except ValueError:
            v_cand = np.inf
        if v_cand < v_warm:
            self.commit()
            return v_warm, v_cand, True
        self.x_warm = x_keep   # the optimizer's next evaluation re-drapes from it
        return v_warm, v_cand, False

    def try_fresh(self, params) -> bool:
        """φ at `params` from the current warm start and from a fresh drape (fresh_drape_at); the
        lower becomes the warm start (True: the fresh one). Warm-started drapes carry the
        template's folds along as the pattern changes; a fresh drape lets the cloth find the folds
        of the current pattern. An evaluation that fails counts as φ = ∞."""
        v_warm, v_fresh, kept = self._try_candidate(params, lambda _: self.fresh_drape(params))
        self.last_fresh = (v_warm, v_fresh)
        if np.isfinite(v_fresh):   # x_last: the fresh drape φ was evaluated on (kept or not)
            self._remember_fresh((_params_key(params), 0), v_fresh, self.x_last)
        return kept

    def try_initial(self, params) -> bool:
        """As try_fresh, with the candidate re-draped at `params` from the template's initial drape
        (the cloth's state when this objective was made; Cloth.reequilibrate): the current
        parameters in the initial fold state, the one the Chamfer ratio is measured against. A
        warm-started re-drape can switch branch — one Newton solve moved the benchmark dress
        (round-off seed 2, boundary_scale 1 cm) 65 mm into a fold state twice as far from the scan —
        and later re-drapes start from there; this candidate is always one re-drape away from the
        initial state."""
        rest, bend, bp = self.unpack(params)
        bv = self.model.pose(bp) if self.use_body else None
        stretch, o = self.stretch(params), self.opts

        def from_initial(_):
            self.cloth.set_control(rest=rest, bend_stiffness=bend, body_vertices=bv, stretch_compliance=stretch)
            self.cloth.reequilibrate(self.x_initial, o.residual_tol, max_steps=o.drape_steps,
                                     iterations=o.drape_sweeps, cancel=self.cancel)
        v_warm, v_init, kept = self._try_candidate(params, from_initial)
        self.last_initial = (v_warm, v_init)
        return kept

    def _guide(self, kappa: float) -> None:
        """Moves the cloth to its scan-guided equilibrium at κ_g = kappa (1/s²; guided_drape.py) with
        this run's capture distance, tolerance and cancel; ValueError when there is none."""
        guided_equilibrium(self.cloth, *self.scan_mesh, kappa, self.opts.guided_capture,
                           residual_tol=self.opts.residual_tol, cancel=self.cancel)

    def try_guided(self, params) -> bool:
        """As try_fresh, with a scan-guided drape (guided_drape.py: pulled toward the scan with
        springs of opts.guided_stiffness, then released) from the current warm start's drape as
        the candidate: a fold state chosen by the scan. With a list of stiffnesses, each in turn,
        from the warm start the one before left (a stiffer pull holds the cloth nearer the scan's
        folds, a softer one lets it keep more of its own). False (nothing changed) without a scan
        mesh or with guided_stiffness 0."""
        if self.scan_mesh is None:
            return False
        kept = False
        for kappa in self.opts.guided_stiffness:
            def guide(v_warm, kappa=kappa):
                if not np.isfinite(v_warm):
                    raise ValueError("no warm drape to guide")
                self._guide(kappa)
            v_warm, v_guided, k = self._try_candidate(params, guide)
            self.last_guided = (v_warm, v_guided)
            kept |= k
        return kept

    def _fresh_value(self, params, jitter: int = 0) -> float:
        """φ at `params` on a fresh drape (fresh_drape_at, with its jitter), re-evaluated from that
        equilibrium; ∞ when there is none. x_last and x_warm are set to that drape. A fresh drape
        depends on the parameters and the jitter alone, so the last few are remembered (with
        try_fresh's): a check's try_bending judges the current bending on the fresh drape try_fresh
        has just made, and a search step starts from the candidate the step before judged."""
        key = (_params_key(params), int(jitter))
        if key in self._fresh_seen:
            v, x = self._fresh_seen[key]
            if x is not None:   # None: that drape did not converge
                self.x_warm, self.x_last = x.copy(), x.copy()   # the remembered drape stays as it was made
            return v
        try:
            self.fresh_drape(params, jitter)
        except ValueError:
            self._remember_fresh(key, np.inf, None)
            return np.inf
        self.x_warm = np.array(self.cloth.x)
        v = self._value_or_inf(params)
        if np.isfinite(v):
            self._remember_fresh(key, v, self.x_last)
        return v

    def fresh_min(self, params) -> float:
        """The lowest φ of opts.bending_fresh_drapes fresh drapes at `params` (_fresh_value: the
        template layout as it is, then jittered with seeds 1, 2, …): a soft fabric's fresh drape
        lands in one of many fold states, which move φ by as much as a decade of bending does, and
        the lowest of a few compares fabrics with less of that luck (BENCHMARKS.md stop 51). x_warm
        and x_last are set to the lowest's drape; ∞ when none has a finite φ (x_warm and x_last then
        as the last fresh drape left them)."""
        best, x_best = np.inf, None
        for j in range(self.opts.bending_fresh_drapes):
            v = self._fresh_value(params, j)
            if v < best:
                best, x_best = v, np.array(self.x_last)
        if x_best is not None:
            self.x_warm, self.x_last = x_best, x_best.copy()
        return best

    def _remember_fresh(self, key, value, x) -> None:
        self._fresh_seen[key] = (float(value), None if x is None else np.array(x))
        while len(self._fresh_seen) > 8 * self.opts.bending_fresh_drapes:
            self._fresh_seen.pop(next(iter(self._fresh_seen)))

    def try_bending(self, params, offsets=None, current=None, prepare=None, compare=None) -> tuple[dict, bool]:
        """A global step in the bending (N·m) the gradient does not take: L-BFGS moves log10 k_b by
        fractions of a decade, and a stiffer or softer fabric lands in other folds, so φ is not
        smooth over decades. For each offset d (decades) of opts.bending_candidates the current
        drape is re-draped at k_b·10^d, then scan-guided (each of opts.guided_stiffness in turn, as
        try_guided). opts.bending_compare 'guided' (the default): a candidate is judged on the
        lowest φ of its drapes, guided ones included, against the current's warm drape; 'unguided':
        the current bending and each candidate alike on the lower of the warm re-drape and a fresh
        drape, neither pulled toward the scan, the guided drapes only choosing the kept candidate's
        folds — a soft enough cloth stays wherever a guided drape leaves it (guided φ flat and low
        over soft fabrics: t-shirt 101 went 1.3 decades soft), but on the thirteen benchmark cases
        this judging did worse (BENCHMARKS.md stop 49); 'asymmetric': softer candidates as in
        'unguided', stiffer ones as in 'guided' (a stiffer cloth springs back to its own folds
        after a pull, a softer one need not); 'fresh': the current bending and each candidate alike
        on their fresh drapes alone (a soft cloth's warm re-drape keeps the current's fitted folds).
        Fresh drapes: the lowest of opts.bending_fresh_drapes (fresh_min). The candidate judged
        lowest relative to the current φ it is judged against becomes the iterate when that ratio is below
        1 − opts.bending_margin: re-drapes of one θ differ by
        about a percent (the fold state), and a material change must explain the scan better than
        that (stop 43); its warm start is the lowest-φ of its drapes. Candidates outside
        BENDING_RANGE are not tried. Returns (the parameters, True when a candidate was kept);
        (params, False) with the bending fixed or no offsets. φ of a kept candidate is evaluated
        at its own equilibrium (last_bending); the cloth is left at the returned parameters and
        warm start. offsets: decades, default opts.bending_candidates. last_bending_judged: per
        candidate evaluated, (its k_b N·m, its φ judged, the current's φ it is judged against).
        The candidates are draped at once, up to opts.candidate_workers (candidate_workers.py: on
        twins of this objective, the same results bit for bit). current: φ at `params` re-draped
        from the current warm start, when the caller has it (a re-drape depends on the parameters
        and the warm start alone, bit for bit); None: evaluated here. prepare(obj, candidate) ->
        candidate: applied to each candidate first, on the objective that judges it, from the
        current warm start (search_bending's refit: its measurements fitted again at its bending);
        a ValueError there drops the candidate. compare: the judging for this call instead of
        opts.bending_compare."""
        offsets = self.opts.bending_candidates if offsets is None else tuple(offsets)
        self.last_bending_judged, self.last_bending_current = [], None
        if not offsets or "log_bend" not in params:
            return params, False
        mode = self.opts.bending_compare if compare is None else compare
        x_keep = np.array(self.x_warm)
        v_cur = self._value_or_inf(params) if current is None else current
        self.last_bending_current = v_cur
        if not np.isfinite(v_cur):
            return params, False
        lo, hi = np.log10(BENDING_RANGE[0]), np.log10(BENDING_RANGE[1])
        cands = [(d, {**params, "log_bend": np.asarray(params["log_bend"], np.float64) + d}) for d in offsets]
        how = {"asymmetric": lambda d: "unguided" if d < 0 else "guided"}.get(mode, lambda d: mode)
        cands = [(d, c, how(d)) for d, c in cands if lo <= c["log_bend"].min() and c["log_bend"].max() <= hi]
        # what each kind of judging compares a candidate with: the current fabric's warm drape, and
        # its fresh drapes when a candidate is judged on them (draped at once, as the candidates:
        # remembered, fresh_min then finds them)
        ref = {"guided": v_cur}
        if any(h != "guided" for *_, h in cands):
            if self.opts.bending_fresh_drapes > 1:
                run_on_twins(self, [lambda obj, j=j: obj._fresh_value(params, j)
                                    for j in range(self.opts.bending_fresh_drapes)],
                             worker_count(self.opts.candidate_workers))
            ref["fresh"] = self.fresh_min(params)
            ref["unguided"] = min(v_cur, ref["fresh"])
        tasks = [lambda obj, c=c, h=h: obj._judge_bending(c, x_keep, ref[h], h, prepare) for _, c, h in cands]
        ratio_best, best, v_best, x_best = 1.0 - self.opts.bending_margin, params, None, x_keep
        for judged in run_on_twins(self, tasks, worker_count(self.opts.candidate_workers)):
            if judged is None:
                continue
            judge, against, drapes, cand = judged
            self.last_bending_judged.append((float(10.0 ** cand["log_bend"].reshape(-1)[0]), float(judge), float(against)))
            if np.isfinite(against) and judge < ratio_best * against:   # against = ∞: no fresh drape of the current
                ratio_best, best = judge / against, cand
                v_best, x_best = min(drapes, key=lambda dr: dr[0])
        self.x_warm = x_best
        self.x_last = x_best
        self.restore(best)
        self.last_bending = v_best if best is not params else None
        return best, best is not params

    def _judge_bending(self, cand, x_keep, ref: float, how: str, prepare=None):
        """One candidate of try_bending: re-draped at its bending from x_keep, then scan-guided (each
        of opts.guided_stiffness in turn), and unless `how` is 'guided' also draped fresh (fresh_min).
        Judged (how, as opts.bending_compare) on the lowest φ of all these drapes ('guided'), of the
        re-drape and the fresh drapes ('unguided'), or of the fresh drapes alone ('fresh'). Returns
        (φ it is judged on, ref — the current's φ it is judged against —, [(φ, drape) of each of its
        drapes], the candidate), or None when its re-drape has no finite φ. prepare: try_bending's
        (the candidate re-draped from where it leaves the warm start)."""
        self.x_warm = x_keep.copy()
        if prepare is not None:
            # what prepare commits is not this objective's history
            undo, current, current_undo = list(self._undo), self.current, list(self._current_undo)
            try:
                cand = prepare(self, cand)
            except (ValueError, FloatingPointError):
                return None
            finally:
                self._undo, self.current, self._current_undo = undo, current, current_undo
        v = self._value_or_inf(cand)        # re-draped at k_b·10^d from the current drape
        if not np.isfinite(v):
            return None
        drapes = [(v, np.array(self.x_last))]
        for kappa in (self.opts.guided_stiffness if self.scan_mesh is not None else ()):
            try:
                self._guide(kappa)
            except ValueError:
                break
            self.x_warm = np.array(self.cloth.x)
            drapes.append((self._value_or_inf(cand), np.array(self.x_last)))
        judge = min(dr[0] for dr in drapes)
        if how != "guided":
            v_fresh = self.fresh_min(cand)
            if np.isfinite(v_fresh):
                drapes.append((v_fresh, np.array(self.x_last)))
            judge = min(v, v_fresh) if how == "unguided" else v_fresh
        return judge, ref, drapes, cand

    def twin(self) -> "CoOptObjective":
        """A copy that drapes on a clone of the cloth (Cloth.clone) and remembers fresh drapes in a
        copy of this one's memory, at the same warm start: the same φ at the same parameters, bit
        for bit, and safe to run beside this objective in another thread (candidate_workers.py).
        The options, scan, samples and body model are shared (read only)."""
        t = copy.copy(self)
        t.cloth = self.cloth.clone()
        t.x_warm, t._undo, t._current_undo = np.array(self.x_warm), list(self._undo), list(self._current_undo)
        t._fresh_seen = dict(self._fresh_seen)
        return t

    def adopt_fresh(self, twin: "CoOptObjective") -> None:
        """Remembers the fresh drapes a twin made (_fresh_value): values and drapes of the same
        parameters, bit for bit, as this objective would have made."""
        for key, (v, x) in twin._fresh_seen.items():
            if key not in self._fresh_seen:
                self._remember_fresh(key, v, x)

    def search_bending(self, params, steps, cancelled=lambda: False, refit=None) -> tuple[dict, dict]:
        """A coarse-to-fine search of log10 k_b: for each d of `steps` (decades, > 0) in turn,
        try_bending with the offsets (d, −d) from the bending the last one kept — so (1, 0.5, 0.25)
        can end anywhere within ±1.75 decades of the start, on a 0.25-decade grid. Each kept step
        beats the current φ by opts.bending_margin. Returns (params, report): report's
        'bending_Nm_start' / 'bending_Nm' (the first group's, N·m), 'steps_decades', 'kept' (per
        step), 'judged' (per step, per candidate [k_b N·m, φ judged, the current's φ]: try_bending's
        last_bending_judged), 'value_start' / 'value' (φ; value_start None when φ is
        not evaluable there). refit(obj, params) -> params: each candidate's outline fitted again at
        its bending before it is judged, and then judged on its fresh drapes ('fresh' judging,
        fresh_min) — φ profiled over the outline: a fabric judged on the outline fitted under another
        one loses to it (co_optimize, opts.measurement_fit_refit)."""
        steps = tuple(float(d) for d in steps)
        start = float(10.0 ** np.asarray(params["log_bend"]).reshape(-1)[0])
        v0 = self._value_or_inf(params)
        value, kept, judged = v0, [], []
        v_here = v0   # φ at params from the warm start: unchanged by a step that keeps nothing
        for d in steps:
            if cancelled() or not np.isfinite(value):
                break
            if refit is None:
                params, k = self.try_bending(params, (d, -d), current=v_here)
            else:
                params, k = self.try_bending(params, (d, -d), current=v_here, prepare=refit, compare="fresh")
            kept.append(bool(k))
            judged.append([list(j) for j in self.last_bending_judged])
            if k:
                value, v_here = self.last_bending, None
        return params, {"steps_decades": list(steps), "kept": kept, "judged": judged, "bending_Nm_start": start,
                        "bending_Nm": float(10.0 ** np.asarray(params["log_bend"]).reshape(-1)[0]),
                        "value_start": float(v0) if np.isfinite(v0) else None,
                        "value": float(value) if np.isfinite(value) else None}

    def commit(self) -> None:
        """The last evaluated point became the optimizer's current iterate: later re-drapes start
        from (and are anchored to) its drape. Rejected trials never become warm starts — one may
        have found another equilibrium (a skirt slid off the hips)."""
        keep = self.opts.reevaluations + 2
        self._undo = (self._undo + [self.x_warm])[-keep:]
        self._current_undo = (self._current_undo + [self.current])[-keep:]
        self.x_warm = self.x_last
        if self.params_last is not None:   # None: a drape set by hand, not evaluated here
            self.current = (_copy_params(self.params_last), np.array(self.x_last))

    def revert(self) -> None:
        """Undoes the last commit() (its iterate was not accepted after all). The warm starts of
        the last reevaluations + 2 commits are kept: every commit of one line-search trial."""
        if self._undo:
            self.x_warm = self._undo.pop()
        if self._current_undo:
            self.current = self._current_undo.pop()

    def mark_current(self, params) -> None:
        """`params` became the current iterate outside the optimizer's steps (the start, a kept
        candidate of try_fresh … try_bending), its drape the warm start x_warm: what a cancelled run
        returns (co_optimize) is the last such iterate or the optimizer's last commit."""
        self.current = (_copy_params(params), np.array(self.x_warm))


def _copy_params(params) -> dict:
    return {g: np.array(v, np.float64, copy=True) for g, v in params.items()}


def _params_key(params) -> tuple:
    """A hashable, exact key of a parameter dict (its groups' float64 bytes)."""
    return tuple((g, np.asarray(v, np.float64).tobytes()) for g, v in sorted(params.items()))


class _EvaluationFailed(ValueError):
    """φ could not be evaluated at a point (no equilibrium, an invalid iterate): a failed trial for
    the optimizer; at a stage's start it ends the run (co_optimize: stopped 'invalid_start')."""


def co_optimize(cloth, garment, scan_points, scan_loops: dict, opts: RecoverOptions, cage=None,
                body_model=None, body_params: BodyParams | None = None, on_iteration=None,
                cancelled=lambda: False, cancel=None, body_points=None, scan_mesh=None,
                measurement_map=None) -> CoOptResult:
    """Minimizes CoOptObjective (same arguments) from the template's parameters (opts.optimizer,
    opts.iterations accepted steps at most); the last iterate is re-draped — and, with a scan
    mesh and opts.guided_stiffness, also guided toward the scan, the lower-φ equilibrium kept —
    and returned. measurement_map (a measurement_fit.MeasurementMap of the template's cage):
    first the template's measurements are fitted (opts.measurement_fit_iterations steps at most,
    the rest held), then the bending is searched at the fitted outline (opts.measurement_fit_bending,
    search_bending) and, when it moved, the measurements fitted again from there; the handles start
    on the fitted outline. The fits' iterations come first in the history, marked stage
    'measurements'. At the end, the bendings judged alike the returned one (bending_range.py,
    opts.bending_range_offsets; on a twin, nothing returned changes).

    Cancelled (`cancel`, or `cancelled()` in a Python loop) at any point: the current iterate — the
    optimizer's last accepted step, a kept candidate, or the start — in the drape φ was evaluated
    on (its anchored equilibrium, not re-draped: a cancel ends the run at once) is returned with
    stopped 'cancelled'; nothing after it runs (no final candidates, no bending range)."""
    obj = CoOptObjective(cloth, garment, scan_points, scan_loops, opts, cage, body_model, body_params, cancel,
                         body_points, scan_mesh)
    params = obj.initial_params()
    obj.mark_current(params)   # the template's initial drape
    history = []
    try:
        result = _co_optimize(obj, params, history, measurement_map, on_iteration, cancelled)
    except Cancelled as exc:
        return _cancelled_result(obj, history, body_params, str(exc))
    if result.stopped == "cancelled":   # the optimizer stopped between evaluations
        return _cancelled_result(obj, history, body_params, "cancelled")
    return result


def _cancelled_result(obj: CoOptObjective, history: list, body_params, reason: str) -> CoOptResult:
    """co_optimize's result when cancelled: obj.current, its controls set on the cloth at its
    drape; iterations: the co-optimization steps in `history` (after the fits' entries)."""
    params, x = obj.current
    rest, bend, bp = obj.unpack(params)
    bv = obj.model.pose(bp) if obj.use_body else None
    stretch = obj.stretch(params)
    obj.cloth.set_control(rest=rest, bend_stiffness=bend, body_vertices=bv, stretch_compliance=stretch)
    obj.cloth.reset(x)
    fits = [h["iteration"] for h in history if h.get("stage") == "measurements"]
    last = history[-1] if history else None
    it = last["iteration"] - (fits[-1] if fits else 0) if last is not None and last.get("stage") != "measurements" else 0
    return CoOptResult(rest, bend, bp if obj.use_body else body_params, bv, np.array(x), list(history), it, 0,
                       "cancelled", stretch_compliance=np.asarray(obj.cloth.control.stretch_compliance).reshape(-1, 3).copy(),
                       stop_reason=reason)


def _co_optimize(obj: CoOptObjective, params: dict, history: list, measurement_map, on_iteration,
                 cancelled) -> CoOptResult:
    """co_optimize's run; `history` is filled in place (what a cancel keeps)."""
    cloth, opts, cage, body_params = obj.cloth, obj.opts, obj.cage, obj.p0
    fit, base, stop_reason, initial_used, bending_used = None, 0, "", [], []
    searched, brange = None, None
    if opts.iterations and opts.measurement_fit_iterations and measurement_map is not None:
        def report_fit(h, offset=0):
            history.append({**h, "iteration": h["iteration"] + offset, "stage": "measurements"})
            if on_iteration:
                on_iteration(history[-1])
        try:
            fit = fit_measurements(obj, measurement_map, params, opts.measurement_fit_iterations,
                                   opts.step_sizes.measurements, on_iteration=report_fit, cancelled=cancelled)
        except (ValueError, FloatingPointError):   # not evaluable at the template: the co-optimization decides
            history.clear()
        if (fit is not None and fit.stopped != "cancelled" and opts.measurement_fit_bending
                and "log_bend" in params):
            # the material at the fitted outline, then the measurements again at it: fitted under the
            # default bending, the sample skirt (a fabric 1.2 decades stiffer) hung in other folds and
            # φ there preferred it 2.4 cm short (stop 48). Not before the fit: at the template's
            # outline a softer fabric hides a wrong length in folds (t-shirts 101 / 102 went 1.3 / 2.3
            # decades soft)
            params["handles"] = measurement_map.parameters(fit.handles, vertices=cage is None).copy()
            refit = None
            if opts.measurement_fit_refit:
                def refit(o, p, start=fit.values):   # the candidate's measurements fitted again at its bending
                    f = fit_measurements(o, measurement_map, p, opts.measurement_fit_iterations,
                                         opts.step_sizes.measurements, cancelled=cancelled, start=start)
                    return {**p, "handles": measurement_map.parameters(f.handles, vertices=cage is None).copy()}
            params, searched = obj.search_bending(params, opts.measurement_fit_bending, cancelled, refit)
            obj.mark_current(params)
            if any(searched["kept"]) and not cancelled():
                try:
                    again = fit_measurements(obj, measurement_map, params, opts.measurement_fit_iterations,
                                             opts.step_sizes.measurements, cancelled=cancelled, start=fit.values,
                                             on_iteration=lambda h, o=len(history): report_fit(h, o))
                    fit = fit.then(again)
                except (ValueError, FloatingPointError):   # keep the first fit, at the searched bending
                    obj.restore(params)
        if fit is not None:
            params["handles"] = measurement_map.parameters(fit.handles, vertices=cage is None).copy()
            base = history[-1]["iteration"] if history else 0   # the fits' last entry: the co-optimization's start
    if fit is not None and fit.stopped == "cancelled":
        best, it, rej, stopped, kept, gkept = params, 0, 0, "cancelled", 0, 0
    elif opts.iterations == 0:
        value, _, terms = obj(params)
        history[:] = [{"iteration": 0, "value": value, "terms": terms, "lr": obj.step_sizes()}]
        if on_iteration:
            on_iteration(history[-1])
        best, it, rej, stopped, kept, gkept = params, 0, 0, "max_iterations", 0, 0
    else:
        # stages: the optimization restarts (L-BFGS memory cleared) at every cut —
        # bending_after / body_after: the bending stiffness / the body held until then (a skirt cut
        # too large can otherwise hide its extra cloth in softer folds; a body can absorb a misfit
        # of the pattern); fresh_every N: every N iterations the lowest-φ of the warm, a fresh, a
        # from-the-initial-drape and a scan-guided drape of the current parameters becomes the warm start
        n_it, fresh_every = opts.iterations, opts.fresh_every
        bend_after = opts.bending_after if ("log_bend" in params or "log_stretch" in params) else 0
        body_after = opts.body_after if obj.use_body else 0
        cuts = {0, n_it} | {c for c in (bend_after, body_after) if 0 < c < n_it}
        if 0 < fresh_every < n_it:
            cuts |= set(range(fresh_every, n_it, fresh_every))
        cuts = sorted(cuts)
        it, rej, stopped = 0, 0, "max_iterations"
        fresh_used, guided_used = [], []   # initial_used, bending_used: set above (every path reports them)
        pre = obj.precondition() if opts.optimizer == "lbfgs" else {}

        def run_stage(evaluate, free, lr, n, report):
            if opts.optimizer == "lbfgs":
                return minimize_lbfgs(evaluate, free, lr, max_iterations=n, patience=opts.patience,
                                      on_iteration=report, cancelled=cancelled, on_accept=obj.commit,
                                      reevaluate=opts.reevaluations, reevaluate_tol=opts.reevaluate_tol,
                                      precondition=pre, on_revert=obj.revert)

            def accepted(h):
                obj.commit()
                report(h)
            return minimize(evaluate, free, lr, max_iterations=n, patience=opts.patience,
                            on_iteration=accepted, cancelled=cancelled)
        for start, end in zip(cuts, cuts[1:]):
            n = end - start
            held = {}
            if start < bend_after:   # the material held: bending and (when optimized) stretch
                held.update({g: params[g] for g in ("log_bend", "log_stretch") if g in params})
            if start < body_after:
                held.update(shape=params["shape"], pose=params["pose"])
            if fresh_every and 0 < start < n_it and start % fresh_every == 0:
                fresh_used.append(obj.try_fresh(params))
                initial_used.append(obj.try_initial(params))
                guided_used.append(obj.try_guided(params))
                if start >= bend_after:
                    params, b = obj.try_bending(params)
                    bending_used.append(b)
                obj.mark_current(params)
            free = {g: v for g, v in params.items() if g not in held}
            lr = {g: v for g, v in obj.step_sizes().items() if g not in held}

            def evaluate(p, held=held):
                try:
                    value, grads, terms = obj({**p, **held})
                except (ValueError, FloatingPointError) as exc:   # still a ValueError for the optimizer
                    raise _EvaluationFailed(str(exc)) from exc
                return value, {g: v for g, v in grads.items() if g not in held}, terms

            def report(h, offset=base + it):
                h = {**h, "iteration": h["iteration"] + offset}
                if history and history[-1]["iteration"] == h["iteration"]:
                    return   # the stage's starting point is the previous stage's (or the fit's) last iterate
                history.append(h)
                if on_iteration:
                    on_iteration(h)
            try:
                res = run_stage(evaluate, free, lr, n, report)
            except _EvaluationFailed as exc:
                # the stage's start (the last accepted iterate) no longer re-drapes from its own
                # equilibrium: keep that iterate and its committed drape rather than lose the run
                stopped, stop_reason = "invalid_start", str(exc)
                break
            params = {**res.params, **held}
            it, rej, stopped = it + res.iterations, rej + res.rejected, res.stopped
            if stopped == "cancelled":
                break
        best = params
        if stopped != "cancelled":   # the returned drape: the fold state nearer the scan (after
            # invalid_start too: the iterate's own drape did not re-drape, one from the initial may)
            initial_used.append(obj.try_initial(best))
            guided_used.append(obj.try_guided(best))
            best, b = obj.try_bending(best)
            bending_used.append(b)
            obj.mark_current(best)
            if not cancelled():   # on a twin: the returned drape and parameters are the same without it
                # nothing kept: the check just judged these parameters from this warm start — its φ and
                # candidates are the range's (the same re-drapes, bit for bit), not judged twice
                known = None if b else (obj.last_bending_current, obj.last_bending_judged)
                brange = bending_range(obj, best, opts.bending_range_offsets, opts.bending_margin, known)
        kept, gkept = int(sum(fresh_used)), int(sum(guided_used))
    rest, bend, bp = obj.unpack(best)
    bv = obj.model.pose(bp) if obj.use_body else None
    stretch = obj.stretch(best)
    try:
        obj.drape_at(rest, bend, bv, stretch)   # the best iterate's equilibrium
    except ValueError:   # keep its committed (anchored) equilibrium
        cloth.set_control(rest=rest, bend_stiffness=bend, body_vertices=bv, stretch_compliance=stretch)
        cloth.reset(obj.x_warm)
    return CoOptResult(rest, bend, bp if obj.use_body else body_params, bv, np.array(cloth.x), history, it, rej,
                       stopped, kept, gkept, fit, np.asarray(cloth.control.stretch_compliance).reshape(-1, 3).copy(),
                       stop_reason, initial_kept=int(sum(initial_used)), bending_kept=int(sum(bending_used)),
                       bending_search=searched, bending_range=brange)
