"""Options of the recovery pipeline: the `recover:` section of config/diffavatar.yaml (merged
with a user --config file) plus per-run choices (garment type, template file, units, up axis).
Lengths in m, bending stiffness in N·m, angles in rad."""
from __future__ import annotations

import math
import numbers
import os
from dataclasses import dataclass, field, fields, replace

from ..config import load_config
from ..scan.frame import UP_AXES
from ..sim.cloth import CONTACT_NORMALS, NEWTON_HINGE_BLOCKS, NEWTON_SOLVERS, SETTLE_DRAG_MAX

PARAMETRIZATIONS = ("cage", "vertices")
OPTIMIZERS = ("lbfgs", "adam")
BENDING = ("garment", "panel", "fixed")
STRETCH = ("fixed", "garment")
INTERIOR_TO = ("surface", "points")
BENDING_COMPARE = ("guided", "unguided", "asymmetric", "fresh")   # CoOptObjective.try_bending
REFERENCE_EDGE = 0.04   # m: the mesh drape_iterations is set for (the default edge_length)
# Bounds of the options, from how each value is used (each checked when the options are made, so a
# bad value is refused by its own name before the scan is even read, not minutes later by a stage):
INT_MAX = 2**31 - 1        # counts reach the C++ core as a C int (a larger one: pybind's TypeError)
MAX_SAMPLES = 10**7        # samples / metrics.chamfer_samples / scan.interior_samples: each sample is
                           #   tens of bytes in arrays made (and measured) per evaluation; 10⁸ would be GBs
MIN_INTERIOR_SAMPLES = 10  # scan.interior_samples: the recovery refuses a garment region with fewer (NO_GARMENT)
BEND_STIFFNESS_MAX = 1e-2  # N·m: 10x the stiffest fabric the bending candidates reach (coopt.BENDING_RANGE,
                           #   1e-3, heavier than denim); at 1 N·m the sample skirt's drape failed, the cloth in the body
RESIDUAL_TOL_MIN = 1e-8    # about the relative force residual a drape's Newton reaches in round-off: the sample skirt's
                           #   stalls at 6.6e-9, and residual_tol 3e-9 (or 1e-300) failed as SIMULATION_FAILED after the
                           #   body fit; 1e-8 converges (and is what the tests use); 1 would be the weight unbalanced
SOBOLEV_LENGTH_MAX = 10.0  # m: 5x a garment's largest panel, past which the H¹ metric is the same (panel-wide moves
                           #   only); at 1e6 m the metric is singular in round-off (pattern/sobolev.py)
BOUNDARY_SCALE_MIN = 1e-4  # m: 0.1 mm, far below a scan's noise; at 1e-300 m s² underflows and L_boundary is NaN


def sweeps_for_edge(sweeps: int, edge: float) -> int:
    """XPBD sweeps per step for a drape on a mesh of edge `edge` (m) given `sweeps` for the
    REFERENCE_EDGE mesh: (REFERENCE_EDGE / edge)² times as many on finer meshes, as many on coarser
    ones. Gauss–Seidel removes a constraint error's smooth part by 1 − O(h²) per sweep (h: the edge
    over the cloth's size), so a finer cloth needs ∝ 1/h² sweeps to hang as stiff in one step: the
    benchmark's skirt 103 on a 2 cm mesh after 200 steps of 40 still fell at 1.2 m/s and its
    recovery failed in the initial drape; with 160 it stood at 0.03 m/s and Newton converged in 61
    iterations (BENCHMARKS.md stop 54)."""
    return max(int(sweeps), int(round(sweeps * (REFERENCE_EDGE / edge) ** 2)))


@dataclass(frozen=True)
class Weights:
    boundary: float = 1.0
    boundary_length: float = 1.0
    interior: float = 30.0
    seam: float = 1000.0
    curvature: float = 0.1
    body_data: float = 1.0
    body_prior: float = 1e-2


@dataclass(frozen=True)
class StepSizes:   # each >= 0; with iterations > 0 every group the co-optimization moves needs > 0
    handles: float = 0.004
    log10_bending: float = 0.1
    log10_stretch: float = 0.1
    shape: float = 0.02
    pose: float = 0.002
    measurements: float = 0.01


GROUPS = {"weights": Weights, "step_sizes": StepSizes}   # the nested groups of RecoverOptions


def _group(name: str, base, override, where: str = "recover options", path: str = ""):
    """The group `name` (Weights / StepSizes) with `override` merged over `base` (a group instance
    or a mapping of its fields): a mapping overrides the named fields and keeps the others, an
    instance replaces the group. Unknown fields and anything but a mapping are refused by name."""
    kind, path = GROUPS[name], path or name
    if isinstance(override, kind):
        return override
    if not isinstance(override, dict):
        raise ValueError(f"{where}: {path} must be a mapping of {', '.join(f.name for f in fields(kind))}, "
                         f"got {type(override).__name__}")
    known = [f.name for f in fields(kind)]
    unknown = [str(k) for k in override if k not in known]
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {', '.join(f'{path}.{k}' for k in sorted(unknown))} "
                         f"(known: {', '.join(known)})")
    values = base.__dict__ if isinstance(base, kind) else dict(base or {})
    return kind(**{**values, **override})


@dataclass(frozen=True)
class RecoverOptions:
    """See config/diffavatar.yaml `recover:` for every field's meaning and unit."""
    iterations: int = 30
    edge_length: float = 0.04
    output_edge_length: float = 0.0
    output_settle_tol: float = 5e-4
    output_drape_steps: int = 1500
    output_drape_sweeps: int = 200
    output_drape_substeps: int = 8
    output_drape_damping: float = 20.0
    output_friction: float = 0.0
    contact_normals: str = "face"
    parametrization: str = "cage"
    optimizer: str = "lbfgs"
    bending: str = "garment"
    stretch: str = "fixed"
    bending_after: int = 0
    body_after: int = 0
    optimize_body: bool = True
    weights: Weights = field(default_factory=Weights)
    step_sizes: StepSizes = field(default_factory=StepSizes)
    bend_stiffness: float = 5e-6   # N·m, in (0, BEND_STIFFNESS_MAX]
    samples: int = 2000   # garment samples of L_interior: in [1, MAX_SAMPLES] (0: garment_samples refused it late)
    interior_to: str = "points"
    drape_steps: int = 200
    drape_rounds: int = 3
    drape_iterations: int = 40   # sweeps per XPBD step at 4 cm: >= 1 (0: the drape refused it late), scaled ≤ INT_MAX
    residual_tol: float = 1e-7   # relative force residual: in [RESIDUAL_TOL_MIN, 1)
    max_seam_mismatch_pct: float = 5.0
    body_trim_distance: float = 0.05
    length_measure: str = "raw"
    length_smoothing: float = 0.005
    boundary_scale: float = 0.0   # m: 0 (L2) or >= BOUNDARY_SCALE_MIN
    fresh_every: int = 5
    measurement_fit_iterations: int = 10
    measurement_fit_bending: tuple = (1.0, 0.5, 0.25)   # decades: the bending searched after the fit, which then runs again (CoOptObjective.search_bending); () none
    measurement_fit_refit: bool = False   # each bending search candidate's measurements fitted again at its bending, judged on fresh drapes (search_bending refit)
    template_sizing: bool = True
    masses_follow_rest: bool = True
    guided_stiffness: tuple = (1.0e4, 1.0e6)   # 1/s², each in turn (CoOptObjective.try_guided); a number k is (k,), 0 is ()
    guided_capture: float = 0.03
    bending_candidates: tuple = (1.0, -1.0)   # decades: log10 offsets of the bending tried at every check (CoOptObjective.try_bending)
    bending_margin: float = 0.02     # a bending candidate is kept when φ is lower by more than this fraction
    bending_range_offsets: tuple = (0.15, 0.5, 1.0)   # decades: ± offsets the recovered bending's range is judged at (bending_range.py); () none
    bending_compare: str = "guided"   # the drapes a bending candidate is judged on (CoOptObjective.try_bending): BENDING_COMPARE
    bending_fresh_drapes: int = 1   # fresh drapes per bending an unguided judging takes the lowest φ of (CoOptObjective.fresh_min)
    candidate_workers: int = 0   # bending candidates draped at once, in threads (candidate_workers.py); 0: one per CPU of the process
    newton_solver: str = "simplicial"   # the Newton refinement's LDLᵀ: NEWTON_SOLVERS (Cloth.solver.supernodal_newton)
    newton_hinge_blocks: str = "gauss_newton"   # a hinge's projected Hessian block: NEWTON_HINGE_BLOCKS (Cloth.solver.hinge_clamp)
    length_tolerance_pct: float = 2.0
    length_tolerance_min: float = 0.01
    patience: int = 5
    sobolev_length: float = 0.3   # m: in [0, SOBOLEV_LENGTH_MAX] (0: Euclidean)
    reevaluations: int = 1
    reevaluate_tol: float = 0.01
    # per run
    garment_type: str | None = None   # a string (template name or labels.yaml synonym) or None
    template: str | None = None          # a template file (OBJ with UVs / GarmentCode JSON)
    units: str = "m"
    up: str = "y"
    label: str | int | None = None   # the garment's label name or value
    job_id: str = ""
    config: dict = field(default_factory=dict, compare=False, repr=False)  # the full loaded config

    def __post_init__(self):
        def bad(name, why):
            raise ValueError(f"recover options: {name} {why}, got {getattr(self, name)!r}")
        for name in ("iterations", "samples", "drape_steps", "drape_rounds", "drape_iterations", "patience", "bending_after",
                     "body_after", "output_drape_steps", "output_drape_sweeps", "output_drape_substeps", "fresh_every", "reevaluations",
                     "measurement_fit_iterations"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                bad(name, "must be a non-negative integer")
            if v > INT_MAX:
                bad(name, f"must be at most {INT_MAX}")
        for name in ("samples", "drape_iterations"):   # 0: garment_samples / the drape's sweeps refuse it late
            if getattr(self, name) < 1:
                bad(name, "must be a positive integer")
        if self.samples > MAX_SAMPLES:
            bad("samples", f"must be at most {MAX_SAMPLES}")
        for name in ("edge_length", "bend_stiffness", "residual_tol", "max_seam_mismatch_pct",
                     "body_trim_distance", "output_settle_tol", "guided_capture"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                bad(name, "must be a positive number")
        if not self.bend_stiffness <= BEND_STIFFNESS_MAX:
            bad("bend_stiffness", f"must be at most {BEND_STIFFNESS_MAX:g} N·m (cloth: 1e-7 … 1e-3)")
        if not RESIDUAL_TOL_MIN <= self.residual_tol < 1:
            bad("residual_tol", f"must lie in [{RESIDUAL_TOL_MIN:g}, 1) (a force residual relative to the weight; "
                                "a drape's Newton stalls near 1e-8 in round-off)")

        def choice(name, allowed, why=None):   # a string among `allowed` (a list or number is refused too)
            v = getattr(self, name)
            if not isinstance(v, str) or v not in allowed:
                bad(name, why or f"must be one of {tuple(allowed)}")
        choice("length_measure", ("raw", "resampled"), "must be raw or resampled")
        kg = self.guided_stiffness   # stored as the tuple of stiffnesses to try: a number k is (k,), 0 is ()
        seq = tuple(kg) if isinstance(kg, (list, tuple)) else (kg,)
        stored_off = isinstance(kg, tuple) and not kg   # 0 as stored: with_() re-validates it
        if (not seq and not stored_off) or any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0
                          or (v == 0 and len(seq) > 1) for v in seq):
            bad("guided_stiffness", "must be a number >= 0 (0: off) or a non-empty list of positive numbers")
        object.__setattr__(self, "guided_stiffness", tuple(float(v) for v in seq if v > 0))
        def decades(name, ok, why):   # stored as a tuple of decades; a number d is (d,)
            v = getattr(self, name)
            seq = tuple(v) if isinstance(v, (list, tuple)) else (v,)
            if any(isinstance(d, bool) or not isinstance(d, (int, float)) or not math.isfinite(d) or not ok(d)
                   for d in seq):
                bad(name, why)
            object.__setattr__(self, name, tuple(float(d) for d in seq))
        decades("bending_candidates", lambda d: d != 0 and abs(d) <= 3,
                "must be a list of non-zero offsets in decades, each within ±3")
        decades("bending_range_offsets", lambda d: 0 < d <= 3,
                "must be a list of offsets in decades, each in (0, 3] (each tried as ±d)")
        decades("measurement_fit_bending", lambda d: 0 < d <= 3,
                "must be a list of search steps in decades, each in (0, 3]")
        w = self.candidate_workers
        if isinstance(w, bool) or not isinstance(w, int) or w < 0:
            bad("candidate_workers", "must be an integer >= 0 (0: one per CPU)")
        k = self.bending_fresh_drapes
        if isinstance(k, bool) or not isinstance(k, int) or not 1 <= k <= 16:
            bad("bending_fresh_drapes", "must be an integer in [1, 16]")
        m = self.bending_margin
        if isinstance(m, bool) or not isinstance(m, (int, float)) or not 0 <= m < 1:
            bad("bending_margin", "must be a fraction in [0, 1)")
        for name in ("length_tolerance_pct", "length_tolerance_min", "sobolev_length", "reevaluate_tol",
                     "length_smoothing", "output_friction", "boundary_scale", "output_drape_damping"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                bad(name, "must be a number >= 0")
        if self.output_drape_damping > SETTLE_DRAG_MAX:   # Cloth.settle's bound
            bad("output_drape_damping", f"must lie in [0, {SETTLE_DRAG_MAX:g}] 1/s (a stronger drag can hold the "
                                        f"output drape in a state the undamped cloth leaves)")
        if self.sobolev_length > SOBOLEV_LENGTH_MAX:
            bad("sobolev_length", f"must lie in [0, {SOBOLEV_LENGTH_MAX:g}] m (0: the Euclidean metric)")
        if 0 < self.boundary_scale < BOUNDARY_SCALE_MIN:
            bad("boundary_scale", f"must be 0 (off) or at least {BOUNDARY_SCALE_MIN:g} m")
        for name in ("optimize_body", "masses_follow_rest", "template_sizing", "measurement_fit_refit"):
            if not isinstance(getattr(self, name), bool):
                bad(name, "must be true or false")
        for name in ("output_drape_steps", "output_drape_sweeps", "output_drape_substeps", "drape_rounds"):
            if getattr(self, name) < 1:
                bad(name, "must be at least 1")
        if not 0.005 <= self.edge_length <= 0.2:
            bad("edge_length", "must lie in [0.005, 0.2] m")
        if self.drape_sweeps > INT_MAX:   # drape_iterations × (0.04 m / edge_length)²
            bad("drape_iterations", f"times (0.04 m / edge_length)² must be at most {INT_MAX}")
        o = self.output_edge_length
        if isinstance(o, bool) or not isinstance(o, (int, float)) or not (o == 0 or 0.005 <= o <= 0.2):
            bad("output_edge_length", "must be 0 (off) or lie in [0.005, 0.2] m")
        choice("contact_normals", CONTACT_NORMALS)
        choice("newton_solver", NEWTON_SOLVERS)
        choice("newton_hinge_blocks", NEWTON_HINGE_BLOCKS)
        choice("parametrization", PARAMETRIZATIONS)
        choice("optimizer", OPTIMIZERS)
        choice("bending", BENDING)
        choice("stretch", STRETCH)
        choice("bending_compare", BENDING_COMPARE)
        choice("interior_to", INTERIOR_TO)
        choice("units", ("m", "cm", "mm"), "must be m, cm or mm")
        choice("up", UP_AXES, f"must be one of {', '.join(UP_AXES)}")
        if self.garment_type is not None and not isinstance(self.garment_type, str):
            bad("garment_type", "must be a garment type name (a string: a template name or a synonym in "
                                "config/labels.yaml)")
        lb = self.label
        if lb is not None and (isinstance(lb, bool) or not isinstance(lb, (str, numbers.Integral))):
            bad("label", "must be a label name or an integer label value")
        if not isinstance(self.job_id, str):
            bad("job_id", "must be a string")
        if not isinstance(self.config, dict):
            bad("config", "must be a loaded configuration (a mapping)")
        for name, kind in GROUPS.items():
            if not isinstance(getattr(self, name), kind):
                bad(name, f"must be a {kind.__name__} (or, to from_config / with_, a mapping of its fields)")
        t = self.template
        if t is not None:
            if not isinstance(t, (str, os.PathLike)) or not str(t):
                bad("template", "must be a built-in template name or a template file path")
            from ..pattern.templates import TEMPLATES
            if str(t) not in TEMPLATES:
                if os.path.isdir(t):
                    bad("template", "is a directory, not a template file (OBJ with UVs or GarmentCode JSON)")
                if not os.path.isfile(t):
                    bad("template", f"is neither a built-in template ({', '.join(sorted(TEMPLATES))}) nor an "
                                    "existing file")
        for name in GROUPS:
            group = getattr(self, name)
            for f in fields(group):
                v = getattr(group, f.name)
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                    raise ValueError(f"recover options: {name}.{f.name} must be a non-negative number, got {v!r}")
        if self.measurement_fit_iterations and not self.step_sizes.measurements > 0:
            raise ValueError("recover options: step_sizes.measurements must be positive when "
                             f"measurement_fit_iterations is {self.measurement_fit_iterations}")
        if self.iterations:   # every group the co-optimization moves needs a positive unit step (lbfgs / optim)
            s, why = self.step_sizes, {"handles": "the pattern is optimized"}
            if self.bending != "fixed" and self.bending_after < self.iterations:
                why["log10_bending"] = f"bending is {self.bending}"
            if self.stretch != "fixed" and self.bending_after < self.iterations:
                why["log10_stretch"] = f"stretch is {self.stretch}"
            if self.optimize_body and self.body_after < self.iterations:
                why["shape"] = why["pose"] = "optimize_body is true"
            for name, reason in why.items():
                if not getattr(s, name) > 0:
                    raise ValueError(f"recover options: step_sizes.{name} must be positive when {reason} "
                                     f"(iterations {self.iterations}), got {getattr(s, name)!r}")
        self._check_config_groups()

    def _check_config_groups(self):
        """The loaded config's `metrics:` and `scan:` groups, which the recovery reads (recovery.py,
        ScanOptions): refused here by their own names, not by a stage minutes in."""
        cfg = self.config
        if not cfg:
            return
        for group in ("metrics", "scan"):
            if not isinstance(cfg.get(group, {}), dict):
                raise ValueError(f"config: {group} must be a mapping, got {type(cfg[group]).__name__}")
        metrics = cfg.get("metrics", {})
        n = metrics.get("chamfer_samples", 20000)
        if isinstance(n, bool) or not isinstance(n, numbers.Integral) or not 1 <= n <= MAX_SAMPLES:
            raise ValueError(f"config: metrics.chamfer_samples must be a positive integer (at most {MAX_SAMPLES}), "
                             f"got {n!r}")
        seed = metrics.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or not 0 <= seed < 2**64:
            raise ValueError(f"config: metrics.seed must be an integer in [0, 2**64), got {seed!r}")
        from ..scan.preprocess import ScanOptions
        scan = ScanOptions.from_config(cfg)   # each field refused by name ("scan options: ...")
        if not MIN_INTERIOR_SAMPLES <= scan.interior_samples <= MAX_SAMPLES:
            raise ValueError(f"config: scan.interior_samples must lie in [{MIN_INTERIOR_SAMPLES}, {MAX_SAMPLES}] for "
                             f"a recovery, got {scan.interior_samples!r}")

    @property
    def drape_sweeps(self) -> int:
        """XPBD sweeps per step of the recovery's drapes (initial, fresh, fallback): drape_iterations
        scaled to edge_length (sweeps_for_edge; drape_iterations itself at the default 4 cm)."""
        return sweeps_for_edge(self.drape_iterations, self.edge_length)

    @classmethod
    def from_config(cls, cfg: dict | None = None, **overrides) -> "RecoverOptions":
        """From a loaded configuration (default: the project's) with per-run overrides (None
        values are ignored, so CLI flags left unset keep the configured value)."""
        cfg = cfg if cfg is not None else load_config()
        section = dict(cfg.get("recover", {}))
        known = {f.name for f in fields(cls)}
        unknown = set(section) - known
        if unknown:
            raise ValueError(f"config: unknown key(s) recover.{', recover.'.join(sorted(unknown))}")
        for name in GROUPS:   # the configured group, its fields named in the config over the defaults
            section[name] = _group(name, GROUPS[name](), section.get(name) or {}, "config", f"recover.{name}")
        unknown = set(overrides) - known | ({"config"} & set(overrides))   # the loaded config is `cfg`
        if unknown:
            raise ValueError(f"recover options: unknown option(s) {', '.join(sorted(unknown))}")
        for k, v in overrides.items():
            if v is None:
                continue
            # a nested group's override (a mapping of some of its fields) is merged over the configured group
            section[k] = _group(k, section[k], v) if k in GROUPS else v
        return cls(config=cfg, **section)

    @classmethod
    def coerce(cls, options) -> "RecoverOptions":
        """RecoverOptions as given, or from a dict of overrides of the configured defaults (also
        the node's job options: job_id, iterations, garment_type, units, up_axis; an empty string
        for garment_type, units, up, template or label is "not given"). iterations 0 is taken as
        given — drape the template only — as everywhere else (config, CLI); the node maps a
        scan's 0 to its default_iterations parameter before it gets here."""
        if isinstance(options, cls):
            return options
        if options is None:
            return cls.from_config()
        if not isinstance(options, dict):
            raise ValueError(f"options: expected RecoverOptions or a dict, got {type(options).__name__}")
        d = dict(options)
        if "up_axis" in d:
            d["up"] = d.pop("up_axis")
        for k in ("garment_type", "units", "up", "template", "label"):
            if k in d and d[k] in ("", None):
                d.pop(k)
        return cls.from_config(**d)

    def with_(self, **changes) -> "RecoverOptions":
        """A copy with `changes`; weights / step_sizes may be given as a mapping of some of their
        fields, merged over this object's. Unknown names are refused by name (ValueError)."""
        unknown = set(changes) - {f.name for f in fields(self)}
        if unknown:
            raise ValueError(f"recover options: unknown option(s) {', '.join(sorted(unknown))}")
        for k in GROUPS:
            if k in changes:
                changes[k] = _group(k, getattr(self, k), changes[k])
        return replace(self, **changes)
