"""A garment ready to simulate: Model (topology, masses, seams, body topology), Control (rest
pattern, material, body vertices) and State (x, v) kept apart, over the C++ XpbdSolver."""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .. import _core, _validate
from .material import ClothMaterial


class SimulationDiverged(RuntimeError):
    """A drape produced non-finite or absurd velocities; the state holds the last finite step."""

    def __init__(self, result: "DrapeResult"):
        super().__init__(result.message)
        self.result = result


@dataclass
class DrapeResult:
    converged: bool
    settled: bool
    diverged: bool
    steps: int
    refine_iterations: int
    max_speed: float        # m/s at the end of the XPBD phase
    residual: float         # max |net force| / mean vertex weight
    max_penetration: float  # m below the body surface
    wall_s: float
    message: str

    def to_json(self) -> dict:
        d = dict(self.__dict__)
        d["max_penetration_mm"] = 1e3 * d.pop("max_penetration")
        return d


@dataclass
class SettleResult:
    settled: bool
    steps: int
    max_displacement: float  # m: the largest vertex displacement over the last window
    window_s: float          # s: the window's simulated time
    max_penetration: float   # m below the body surface
    seam_gap_max: float      # m: the widest sewn vertex pair
    residual: float          # max |net force| / mean vertex weight (large after XPBD: informative only)
    wall_s: float
    message: str

    def to_json(self) -> dict:
        moved = 1e3 * self.max_displacement if np.isfinite(self.max_displacement) else None   # None: no full window
        return {"settled": self.settled, "steps": self.steps, "max_displacement_mm": moved,
                "window_s": self.window_s, "max_penetration_mm": 1e3 * self.max_penetration,
                "seam_gap_max_mm": 1e3 * self.seam_gap_max, "residual": self.residual, "wall_s": self.wall_s,
                "message": self.message}


# m: how deep in the body Cloth.reseat_contacts looks for vertices to push out. A Newton solve
# carries a vertex without contact in by centimetres (a skirt's waist vertex: 28 mm); cloth deeper
# than this was inside before (test_xpbd_physics: a sheet hung at a ball's centre), and a contact
# would drag it across the body.
RESEAT_MAX_DEPTH = 0.05

# Cloth.reequilibrate: Newton's budget from the warm start before the fallback drape. A Newton
# that needs more than 80 from a nearby equilibrium is crawling to another fold state, which the
# XPBD fallback from the same start avoids better: at 200 the recovery benchmark's long sleeve
# ended at Chamfer ratio 0.73 (0.57 at 80) and skirt 102 at 0.28 (0.26), the other four cases
# measured unchanged (BENCHMARKS.md, stop 36). Valley contacts (two planes per crease vertex)
# need ~50% more iterations: at 80 a skirt's first re-drape missed (80 + 12 needed, round-off
# seed 1), its fallback drape failed, and the recovery stopped before its first step.
REEQUILIBRATE_ITERATIONS = 80
REEQUILIBRATE_ITERATIONS_VALLEY = 200

# Cloth.self_anchor: how many times a round re-solves with the contact planes its end state
# detects (a Newton solve holds those of its start), anchors kept.
CONTACT_REDETECTIONS = 3

# The contact plane of a cloth vertex on the body (sim/contact_kernel.hpp, docs/simulation.md): its
# closest triangle's own plane, the tangent plane with the interpolated vertex normal, or face planes
# with both faces' over a concave body edge in the quasi-static solves (valley; sim/body_collider.hpp).
CONTACT_NORMALS = ("face", "smooth", "valley")
# 1/s: Cloth.settle's largest drag. A drag vanishes at rest, but a strong one can stop the cloth in a
# state the undamped cloth leaves: settled at 60/s, the 4 cm t-shirt of test_settle.py then moved
# 10.5 mm under the simulator's own 4/s on an AVX2 machine (stop 56; a tolerance shrunk as 1/drag
# did not help: a fold was held, not creeping), where 20/s — the recovery's output drape — stayed
# within 0.43 mm on the ~10k t-shirts (BENCHMARKS.md stop 47) and within 2 × 0.5 mm here.
SETTLE_DRAG_MAX = 20.0
# Newton's LDLᵀ (XpbdSolver.supernodal_newton): Eigen's SimplicialLDLT, or the supernodal one of
# linalg/supernodal_ldlt.hpp (the same solutions up to round-off; bench/newton.py)
NEWTON_SOLVERS = ("simplicial", "supernodal")
# How Newton's projected Hessian (far from equilibrium) makes a hinge's 12×12 block PSD
# (XpbdSolver.hinge_clamp): its Gauss–Newton part k w ∇θ∇θᵀ, or the exact block clamped to its
# non-negative eigenvalues on the translation-free 9×9 subspace (before stop 59; bench/newton.py)
NEWTON_HINGE_BLOCKS = ("gauss_newton", "clamp")


def _sim_params(dt, iterations, gravity, damping, contact_radius, max_speed, fast=False, friction=0.0):
    p = _core.SimParams()
    p.fast = bool(fast)
    p.friction = _validate.friction(friction)
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt: expected a time step > 0 s, got {dt}")
    p.dt = float(dt)
    p.iterations = _validate.positive_int("iterations", iterations)
    g = np.asarray(gravity, dtype=np.float64).reshape(-1)
    if g.shape != (3,) or not np.all(np.isfinite(g)):
        raise ValueError(f"gravity: expected a finite (3,) vector in m/s², got {gravity}")
    p.gravity = g
    if not (np.isfinite(damping) and damping >= 0):
        raise ValueError(f"damping: expected a rate >= 0 (1/s), got {damping}")
    p.damping = float(damping)
    p.contact_radius = float(contact_radius)
    p.max_speed = float(max_speed)
    return p


class Cloth:
    """Build from numpy arrays (all metres):

    rest (V,2): the sewing pattern (each triangle counter-clockwise); faces (F,3); x0 (V,3)
    initial 3D positions; seams (S,2) vertex pairs sewn together; pinned: vertex indices held
    fixed; groups (F,) material group per triangle (e.g. per panel) with one ClothMaterial per
    group (density from the first); body: (vertices (Vb,3), faces (Fb,3)) collider or None;
    thickness h (m), contact stiffness (N/m), seam compliance (m/N); grain (F,) the fabric's
    warp direction per triangle, rad counter-clockwise from the pattern x axis (None: 0, warp =
    pattern x, weft = pattern y; a Garment's is Garment.face_grain()); masses_follow_rest: the
    lumped masses (density × a third of the adjacent rest areas, kg) follow every new rest shape
    given to set_control instead of staying those of `rest` (what an optimizer of the pattern
    wants: a larger pattern is heavier); contact_normals: the contact plane (CONTACT_NORMALS) —
    face, smooth, or valley (face planes, and in Newton both faces' over a concave body edge).
    """

    def __init__(self, rest, faces, x0, seams=None, pinned=None, groups=None,
                 materials: ClothMaterial | list[ClothMaterial] | None = None, body=None,
                 thickness: float = 0.004, contact_stiffness: float = 2.0e3,
                 seam_compliance: float = 1.0e-5, grain=None, masses_follow_rest: bool = False,
                 contact_normals: str = "face"):
        if contact_normals not in CONTACT_NORMALS:
            raise ValueError(f"contact_normals: expected one of {', '.join(CONTACT_NORMALS)}, got {contact_normals!r}")
        rest = _validate.points("rest", rest, dims=2)
        F = _validate.faces("faces", faces, len(rest))
        x0 = _validate.points("x0", x0)
        if len(x0) != len(rest):
            raise ValueError(f"x0: expected {len(rest)} rows (one per rest vertex), got {len(x0)}")
        seams = np.zeros((0, 2), np.int32) if seams is None else np.asarray(seams)
        if seams.ndim != 2 or seams.shape[1] != 2:
            raise ValueError(f"seams: expected shape (S, 2), got {seams.shape}")
        if len(seams) and (seams.min() < 0 or seams.max() >= len(rest)):
            raise ValueError(f"seams: vertex index out of range [0, {len(rest)})")
        seams = np.ascontiguousarray(seams, dtype=np.int32)
        pinned = [] if pinned is None else [int(i) for i in np.asarray(pinned).reshape(-1)]
        groups = np.zeros(len(F), np.int32) if groups is None else np.asarray(groups, dtype=np.int32)
        if groups.shape != (len(F),) or (len(groups) and groups.min() < 0):
            raise ValueError(f"groups: expected ({len(F)},) non-negative ints, got shape {groups.shape}")
        if grain is None:
            grain = np.zeros(len(F))
        grain = np.asarray(grain, dtype=np.float64)
        if grain.shape != (len(F),) or not np.all(np.isfinite(grain)):
            raise ValueError(f"grain: expected ({len(F)},) finite angles (rad), got shape {grain.shape}")
        ng = int(groups.max()) + 1 if len(groups) else 1
        if materials is None:
            materials = ClothMaterial()
        if isinstance(materials, ClothMaterial):
            materials = [materials] * ng
        if len(materials) != ng:
            raise ValueError(f"materials: expected {ng} (one per group), got {len(materials)}")
        if body is None:
            bV, bF = np.zeros((0, 3)), np.zeros((0, 3), np.int32)
        else:
            bV, bF = _validate.mesh("body vertices", body[0], "body faces", body[1])
        self.materials = list(materials)
        model = _core.build_cloth_model(len(rest), F, rest, groups, seams, pinned, bF,
                                        materials[0].density, float(thickness),
                                        float(contact_stiffness), float(seam_compliance), grain,
                                        bool(masses_follow_rest), contact_normals == "smooth",
                                        contact_normals == "valley")
        control = _core.ClothControl(rest, np.array([m.compliance for m in materials]),
                                     np.array([m.bend_stiffness for m in materials]), bV)
        self.solver = _core.XpbdSolver(model, control)
        self.state = self.solver.make_state(x0)
        self.body_faces = bF

    # --- Model / Control / State ------------------------------------------------------------
    @property
    def model(self):
        return self.solver.model

    @property
    def control(self):
        """A copy of the control; change it through set_control (validated)."""
        return self.solver.control

    @property
    def sweep_plan(self) -> dict:
        """How a sweep orders its projections (cpp/sim/sweep_plan.hpp): "lanes" 1 = colour by
        colour; ≥ 2 = that many lanes in parallel, then the "interface_constraints" serially."""
        return dict(self.solver.sweep_plan)

    def set_sweep_plan(self, lanes: int = 2, min_constraints: int = 16384) -> None:
        """Lane-parallel sweeps (`lanes` ≥ 2) for models with at least `min_constraints`
        triangles + hinges + seams, colour by colour otherwise (the default). Changes the order of
        the Gauss–Seidel projections, hence an unconverged trajectory's round-off and iterates,
        never the equilibrium; the result never depends on the thread count."""
        p = _core.SweepPlanParams()
        p.lanes = _validate.positive_int("lanes", lanes)
        if int(min_constraints) < 0:
            raise ValueError(f"min_constraints: expected >= 0, got {min_constraints}")
        p.min_constraints = int(min_constraints)
        self.solver.set_sweep_plan(p)
        self._sweep_plan_args = (p.lanes, p.min_constraints)   # what clone() rebuilds

    def set_control(self, rest=None, stretch_compliance=None, bend_stiffness=None, body_vertices=None):
        """Changes the optimized parameters (Control). The lumped masses are the Model's, from
        the constructor's rest areas: a new `rest` changes the elastic rest shape only — unless
        the Cloth was built with masses_follow_rest=True, when the masses are recomputed from
        the new rest areas too (the equilibrium adjoint differentiates them; the trajectory
        adjoint refuses such a cloth)."""
        c = self.solver.control
        if rest is not None:
            c.rest = _validate.points("rest", rest, dims=2)
        if stretch_compliance is not None:
            c.stretch_compliance = np.asarray(stretch_compliance, dtype=np.float64).reshape(-1, 3)
        if bend_stiffness is not None:
            c.bend_stiffness = np.asarray(bend_stiffness, dtype=np.float64).reshape(-1)
        if body_vertices is not None:
            c.body_vertices = _validate.points("body_vertices", body_vertices, allow_empty=True)
        self.solver.set_control(c)

    def clone(self) -> "Cloth":
        """An independent Cloth: this one's Model, Control and sweep plan in a solver of its own (the
        C++ objects copied, nothing shared), at this state's positions (m) and velocities (m/s),
        with the last drape's simulation parameters. The two may run at once in two threads (their
        C++ calls release the GIL). The body's BVH is copied as it is (XpbdSolver.clone), not
        rebuilt: a tree built for another pose and refit breaks exact ties between body triangles
        (a vertex nearest a body vertex) otherwise than a new one, and the contact planes then
        differ — a clone after the body moved drapes as its original only with the same tree. Not
        copied: the contact set and anchors a solver holds between calls — the next drape, refine
        or reequilibrate of the clone detects and sets its own, as they do on this cloth
        (keep_anchor / keep_contacts reuse them)."""
        c = object.__new__(Cloth)
        c.materials, c.body_faces = list(self.materials), self.body_faces
        c.solver = self.solver.clone()
        if hasattr(self, "_sweep_plan_args"):
            c.set_sweep_plan(*self._sweep_plan_args)
        if hasattr(self, "params"):
            c.params = self.params   # replaced by every drape, never changed in place
        c.state = c.solver.make_state(np.array(self.x))
        c.state.v = np.array(self.state.v)
        return c

    @property
    def x(self) -> np.ndarray:
        """Positions (V,3) m: a view into the C++ state (no copy)."""
        return self.state.x

    def reset(self, x) -> None:
        self.state = self.solver.make_state(_validate.points("x", x))

    # --- Simulation ---------------------------------------------------------------------------
    def step(self, n: int = 1, dt: float = 1 / 120, iterations: int = 100, gravity=(0, -9.81, 0),
             damping: float = 4.0, contact_radius: float = 0.01, max_speed: float = 50.0, fast: bool = False,
             friction: float = 0.0) -> float:
        """n XPBD steps; returns the max vertex speed (m/s) after the last one. fast: the sweeps in
        single precision, vectorised (sim/fast_sweep.hpp; 6× faster with AVX-512, float round-off,
        the state's multipliers stay zero): for drapes, not for anything differentiated.
        friction: Coulomb coefficient μ of the cloth on the body (dimensionless; 0 = frictionless;
        sim/friction_kernel.hpp), forward only — the adjoints differentiate frictionless steps."""
        p = _sim_params(dt, iterations, gravity, damping, contact_radius, max_speed, fast, friction)
        return self.solver.step(self.state, p, _validate.positive_int("n", n))

    def sew(self, max_steps: int = 60, gap_tol: float = 1e-3, iterations: int = 100, min_gap: float = 0.05,
            cancel=None) -> int:
        """Quasi-static sewing before a drape: XPBD steps without gravity whose velocities are
        discarded after each step, until every seam pair is closer than gap_tol (m) or max_steps.
        Closing wide seam gaps in ordinary steps turns the closure into speed (a 30 cm gap
        closed in one 1/120 s step is 36 m/s) and can throw a garment off the body; sewn first,
        a skirt's waist is closed before gravity pulls it over the hips. A garment whose widest
        seam gap is below min_gap (m) is left alone: such gaps close harmlessly in the drape's
        first steps (and a quasi-static start measurably slowed the trousers' settling).
        Returns steps taken."""
        seams = np.asarray(self.model.seams).reshape(-1, 2)
        n = _validate.positive_int("max_steps", max_steps)
        if not len(seams):
            return 0
        def gap():
            x = self.state.x
            return np.linalg.norm(x[seams[:, 0]] - x[seams[:, 1]], axis=1).max()
        if gap() < max(gap_tol, min_gap):   # already sewn, or nearly
            return 0
        p = _sim_params(1 / 120, iterations, (0.0, 0.0, 0.0), 0.0, 0.01, 50.0)
        for k in range(n):
            if cancel is not None and cancel.cancelled:
                raise _core.Cancelled("cancelled while sewing")
            self.solver.step(self.state, p, 1)
            self.state.v = np.zeros_like(self.state.x)
            if gap() < gap_tol:
                return k + 1
        return n

    def drape(self, max_steps: int = 2000, min_steps: int = 20, speed_tol: float = 2e-3,
              refine: bool = True, residual_tol: float = 1e-5, refine_iterations: int = 200, anchor_stiffness: float = 1.0,
              dt: float = 1 / 120, iterations: int = 100, gravity=(0, -9.81, 0), damping: float = 4.0,
              contact_radius: float = 0.01, max_speed: float = 50.0, progress=None, cancel=None,
              raise_on_divergence: bool = True, substeps: int = 1, fast: bool = False,
              friction: float = 0.0) -> DrapeResult:
        """Quasi-static drape: XPBD until every vertex is slower than speed_tol (m/s) or
        max_steps steps of dt (s; each made of `substeps` XPBD steps of dt/substeps with
        iterations/substeps sweeps: as many sweeps, a stiffer cloth on fine meshes), then
        (refine=True) Newton refinement of the same energy to a relative force residual
        ≤ residual_tol — converged only if, in addition, no vertex is deeper in the body than 10%
        of the collision thickness; anchor_stiffness κ (1/s²) ties each vertex to its settled
        position with a spring of stiffness κ·m (a static-friction proxy that also removes the
        zero-energy sliding modes of a frictionless contact). fast: the XPBD phase's sweeps in
        single precision, vectorised (as in step; the Newton refinement stays in double). friction:
        Coulomb μ of the XPBD phase (as in step; the refinement's friction is the anchor springs).
        Releases the GIL; progress(ProgressEvent); cancel: CancelToken."""
        p = _sim_params(dt, iterations, gravity, damping, contact_radius, max_speed, fast, friction)
        self.params = p
        d = _core.DrapeParams()
        d.max_steps = _validate.positive_int("max_steps", max_steps)
        d.min_steps = int(min_steps)
        d.substeps = _validate.positive_int("substeps", substeps)
        d.speed_tol = float(speed_tol)
        d.refine = bool(refine)
        d.residual_tol = float(residual_tol)
        d.refine_iterations = int(refine_iterations)
        d.anchor_stiffness = float(anchor_stiffness)
        r = self.solver.drape(self.state, p, d, progress, cancel)
        t0 = time.perf_counter()
        converged, residual, its, pen, msg = r.converged, r.residual, r.refine_iterations, r.max_penetration, r.message
        if refine and converged and pen > 0.0:
            k, residual, pen = self.reseat_contacts(residual_tol, refine_iterations, anchor_stiffness,
                                                    progress=progress, cancel=cancel)
            its += k
            converged = residual <= residual_tol
            if not converged:
                msg = f"Newton refinement after re-detecting contacts stopped at residual {residual:.3g}"
        # an equilibrium with the cloth inside the body is no drape: converged also needs the
        # deepest vertex within 10% of the collision thickness
        pen_tol = 0.1 * self.model.thickness
        if refine and converged and pen > pen_tol:
            converged = False
            msg = (f"the equilibrium leaves a vertex {1e3 * pen:.2f} mm inside the body (more than 10% of the "
                   f"{1e3 * self.model.thickness:.1f} mm collision thickness)")
        res = DrapeResult(converged, r.settled, r.diverged, r.steps, its, r.max_speed,
                          residual, pen, r.wall_s + (time.perf_counter() - t0), msg)
        if res.diverged and raise_on_divergence:
            raise SimulationDiverged(res)
        return res

    def settle(self, max_steps: int = 1500, window_steps: int = 60, displacement_tol: float = 5e-4,
               iterations: int = 100, substeps: int = 4, fast: bool = True, dt: float = 1 / 120,
               cancel=None, friction: float = 0.0, check_steps: int = 10, damping: float = 4.0) -> SettleResult:
        """XPBD drape until the cloth stands still: until no vertex moved more than
        displacement_tol (m) over the last window_steps steps of dt (s), or max_steps. The window
        slides: every check_steps steps (a divisor of window_steps) the positions are kept and
        compared with those a window earlier, so the drape stops within check_steps steps of the
        first such window rather than at the next multiple of window_steps. For a
        garment too large for Newton (its stalls on buckled cloth at ~10k vertices cost seconds
        per iteration), this is the paper's own equilibrium — the end of a quasi-static XPBD
        simulation — rather than a force residual: XPBD's sweeps leave stiff constraints
        unconverged (the relative force residual stays large; see SettleResult), and a vertex
        speed criterion never fires, because single substeps jitter where a window does not.
        Settled also needs no vertex deeper in the body than 10% of the collision thickness.
        Starts from the current state (velocities kept); releases the GIL in the sweeps. friction:
        Coulomb μ of the cloth on the body (as in step). damping (1/s): v ← v·exp(−damping·dt) per
        step, a drag that vanishes at rest, so the still state is an undamped one too (the check
        above is on positions, not speeds); a stronger drag stops the carried cloth's swinging and
        the jitter of its unconverged sweeps sooner (recovery: output_drape_damping); at most
        SETTLE_DRAG_MAX (20/s): a stronger one can hold the cloth where the undamped one moves on."""
        n = _validate.positive_int("max_steps", max_steps)
        w = _validate.positive_int("window_steps", window_steps)
        c = _validate.positive_int("check_steps", check_steps)
        if w % c:
            raise ValueError(f"check_steps: expected a divisor of window_steps ({w}), got {c}")
        if not (np.isfinite(displacement_tol) and displacement_tol > 0):
            raise ValueError(f"displacement_tol: expected a distance > 0 m, got {displacement_tol}")
        if not damping <= SETTLE_DRAG_MAX:   # NaN too; < 0 is refused by the steps
            raise ValueError(f"damping: expected at most {SETTLE_DRAG_MAX:g} 1/s for a settle, got {damping}: a "
                             f"stronger drag can hold the cloth in a state the undamped cloth leaves (a fold it "
                             f"would release), which the still window cannot tell")
        t0 = time.perf_counter()
        steps, moved, settled, message = 0, float("inf"), False, ""
        kept = [(0, np.array(self.state.x))]   # (step, positions) at the checks of the last window
        while steps < n:
            k = min(c, n - steps)
            r = self.drape(max_steps=k, min_steps=k, refine=False, iterations=iterations, substeps=substeps,
                           fast=fast, dt=dt, raise_on_divergence=False, cancel=cancel, friction=friction,
                           damping=damping)
            steps += r.steps
            if r.diverged:
                message = r.message
                break
            x = np.array(self.state.x)
            kept = [(s, xs) for s, xs in kept if s >= steps - w]
            if kept[0][0] == steps - w:   # a full window behind
                moved = float(np.linalg.norm(x - kept[0][1], axis=1).max())
                if moved < displacement_tol:
                    settled = True
                    break
            kept.append((steps, x))
        x = np.asarray(self.state.x)
        pen = float(self.solver.max_penetration(x))
        seams = np.asarray(self.model.seams).reshape(-1, 2)
        gap = float(np.linalg.norm(x[seams[:, 0]] - x[seams[:, 1]], axis=1).max()) if len(seams) else 0.0
        residual = float(self.solver.residual(x, np.asarray(self.params.gravity)))
        if settled and pen > 0.1 * self.model.thickness:
            settled = False
            message = (f"the settled cloth has a vertex {1e3 * pen:.2f} mm inside the body (more than 10% of the "
                       f"{1e3 * self.model.thickness:.1f} mm collision thickness)")
        if not message:
            message = "settled" if settled else (
                f"step budget exhausted ({steps} steps; the last window moved a vertex {1e3 * moved:.2f} mm)"
                if np.isfinite(moved) else f"step budget exhausted ({steps} steps, shorter than the {w}-step window)")
        return SettleResult(settled, steps, moved, w * dt, pen, gap, residual, time.perf_counter() - t0, message)

    def refine(self, keep_anchor: bool = True, keep_contacts: bool = False, residual_tol: float = 1e-5, refine_iterations: int = 200,
               anchor_stiffness: float = 1.0, progress=None, cancel=None, anchor=None,
               contact_radius: float | None = None) -> tuple[int, float]:
        """Newton refinement of the current state to equilibrium with the last drape's simulation
        parameters; keep_anchor reuses the anchors of the last refinement and keep_contacts its
        contact set (what the equilibrium adjoint differentiates); anchor (V,3) m: new anchor
        positions instead (springs of stiffness anchor_stiffness·m, 1/s², pulling toward a target
        shape); contact_radius (m): the contact search reach beyond the collision thickness for
        this refinement's detection (None: the last drape's). Returns (iterations, residual)."""
        if anchor is not None:
            self.solver.set_anchor(_validate.points("anchor", anchor))
            keep_anchor = True
        d = _core.DrapeParams()
        d.residual_tol = float(residual_tol)
        d.refine_iterations = int(refine_iterations)
        d.anchor_stiffness = float(anchor_stiffness)
        p = self._last_params()
        if contact_radius is not None:
            if not (np.isfinite(contact_radius) and contact_radius >= 0):
                raise ValueError(f"contact_radius: expected a distance >= 0 m, got {contact_radius}")
            p = _sim_params(p.dt, p.iterations, p.gravity, p.damping, contact_radius, p.max_speed, p.fast, p.friction)
        return self.solver.refine(self.state, p, d, keep_anchor, keep_contacts, progress, cancel)

    def _last_params(self):
        """The last drape's simulation parameters (the defaults before any drape)."""
        return getattr(self, "params", None) or _sim_params(1 / 120, 100, (0, -9.81, 0), 4.0, 0.01, 50.0)

    def own_contacts_residual(self) -> float:
        """The relative force residual at the current state with the contact set detected there
        (which it then keeps): a Newton solve holds the set of its start, so its end state can
        be an equilibrium of those contacts and not of its own."""
        p = self._last_params()
        self.solver.detect_contacts(self.x, p)
        return float(self.solver.residual(self.x, np.asarray(p.gravity, dtype=np.float64)))

    def reseat_contacts(self, residual_tol: float, refine_iterations: int = 200, anchor_stiffness: float = 1.0,
                        rounds: int = 3, progress=None, cancel=None) -> tuple[int, float, float]:
        """Newton holds the contact set of its starting state fixed, so a vertex that was not in
        contact can end inside the body: while one is (max penetration > 0), re-detect the
        contacts at the current state and refine again, anchors kept (an active-set iteration,
        `rounds` at most). The search reaches the deepest vertex up to RESEAT_MAX_DEPTH: one that
        Newton carried deeper than the contact search reach (collision thickness + contact_radius;
        a vertex outside that reach at the start of the solve had no contact) is found and pushed
        out too. Returns (Newton iterations, last residual, max penetration m)."""
        its, res = 0, float("nan")
        pen = float(self.solver.max_penetration(self.x))
        base = getattr(self, "params", None)
        reach = float(base.contact_radius) if base is not None else 0.01
        for _ in range(rounds):
            if not pen > 0.0:
                break
            k, res = self.refine(keep_anchor=True, keep_contacts=False, residual_tol=residual_tol,
                                 refine_iterations=refine_iterations, anchor_stiffness=anchor_stiffness,
                                 progress=progress, cancel=cancel,
                                 contact_radius=max(reach, min(pen, RESEAT_MAX_DEPTH) - float(self.model.thickness)
                                                    + 1e-3))
            its, pen = its + k, float(self.solver.max_penetration(self.x))
        return its, res, pen

    def self_anchor(self, residual_tol: float, rounds: int = 10, tol: float = 1e-4, refine_iterations: int = 400,
                    cancel=None, friction: float = 0.0) -> float:
        """Re-solves the equilibrium with the static-friction anchors (κ = 1/s²) moved to the
        current state, until the state stays put (no vertex moves more than tol, m; `rounds` at
        most): an equilibrium of its own anchors, which a fresh Cloth of the same model and
        control started there does not leave (a drape anchored elsewhere — an optimizer's warm
        start — moves by up to its distance from it). A round that misses residual_tol or ends
        in the body (deeper than 10% of the thickness) is undone and ends the rounds. Usually
        geometric (the skirt template on the default body: 0.93 → 0.036 → 0 mm). A Newton solve
        holds the contact planes of its start; a round re-solves (anchors kept, up to
        CONTACT_REDETECTIONS times) while its end state detects others, so that a converged state is
        an equilibrium with its own contacts too. Face planes that keep switching are vertices
        over concave body edges; with contact_normals="valley" the solves hold both faces' planes
        there and the long-sleeve template's rounds on the default body, which alternate 7.3–7.5
        mm apart for ever with "face", converge (1.47, 0.008 mm; docs/simulation.md, "Valleys").
        refine_iterations: the Newton budget of each solve, as the drape job's (400): a recovered
        skirt's second round needed 167 (189 with valley contacts), and at 120 its failure left
        the recovery's output with the optimizer's anchored drape (benchmark skirt 102).

        friction μ > 0 (Coulomb, dimensionless): a vertex keeps its anchor while the anchor's pull
        is a static friction force the body can exert — tangential part ≤ μ × the normal force
        (contact penalty plus the pull's normal part; contact_cone_violation) — and only the
        others are re-anchored; the rounds end when none is left. The result is then a static
        equilibrium under Coulomb friction μ: every anchor force is zero (within tol of its
        vertex) or inside its contact's friction cone. Returns the largest distance (m) of the last
        round from a vertex to an anchor that is not inside its cone, or the largest move of its
        re-solves when its contact planes kept switching, whichever is larger (≤ tol: converged; 0
        when every anchor is; inf if no round completed)."""
        mu = _validate.friction(friction)
        offset = float("inf")
        anchor = np.array(self.x)
        for _ in range(max(int(rounds), 0)):
            x0 = np.array(self.x)
            _, res = self.refine(anchor=anchor, residual_tol=residual_tol, refine_iterations=refine_iterations,
                                 cancel=cancel)
            # the round held the contact planes of its start; where its end state has others (a
            # closest triangle switched), re-solved with them, anchors kept — otherwise a reload,
            # which detects them afresh, would move (0.75 mm under 1e-13 m of round-off). Planes
            # that still switch leave the round unconverged by the largest of these moves.
            switching = 0.0
            for j in range(CONTACT_REDETECTIONS + 1):
                if not res <= residual_tol:
                    break
                if self.own_contacts_residual() <= residual_tol:
                    switching = 0.0
                    break
                if j == CONTACT_REDETECTIONS:
                    break
                xs = np.array(self.x)
                _, res = self.refine(keep_anchor=True, keep_contacts=True, residual_tol=residual_tol,
                                     refine_iterations=refine_iterations, cancel=cancel)
                switching = max(switching, float(np.linalg.norm(np.asarray(self.x) - xs, axis=1).max()))
            if not (res <= residual_tol and not self.solver.max_penetration(self.x) > 0.1 * self.model.thickness):
                self.reset(x0)
                break
            x = np.asarray(self.x)
            d = np.linalg.norm(anchor - x, axis=1)
            # every anchor friction cannot hold (all of them without friction) moves to the state,
            # however little its vertex moved: anchors left behind within tol would add up their
            # offsets round after round and hold the rounds just above tol
            loose = self.contact_cone_violation(anchor, mu) if mu > 0 else np.ones(len(x), bool)
            offset = max(float(d[loose].max()) if loose.any() else 0.0, switching)
            anchor[loose] = x[loose]
            if offset <= tol:
                break
        return offset

    def contact_cone_violation(self, anchor, friction: float, anchor_stiffness: float = 1.0) -> np.ndarray:
        """(V,) bool at the current state: True where the anchor spring's force
        f = κ m (a − x) (anchor (V, 3) m, κ = anchor_stiffness 1/s²) is not a Coulomb friction
        force of the body — the body's total force on the vertex, the contact penalty
        k_c max(0, −C) n (the contact plane at the closest body point, contact_kernel.hpp) plus f, must push
        outward (N = its normal part ≥ 0) with a tangential part ≤ friction·N. A vertex off the
        body (no penalty) fails whenever f ≠ 0."""
        mu = _validate.friction(friction)
        x = np.asarray(self.x)
        a = _validate.points("anchor", anchor)
        m = np.asarray(self.model.mass)
        f = anchor_stiffness * m[:, None] * (a - x)
        bv = np.ascontiguousarray(self.control.body_vertices, np.float64)
        if not len(bv):
            return np.linalg.norm(f, axis=1) > 0
        bf = np.ascontiguousarray(self.body_faces, np.int32)
        _, q, n = _core.contact_planes(bv, bf, np.ascontiguousarray(x, np.float64), bool(self.model.smooth_contact))
        C = ((x - q) * n).sum(1) - self.model.thickness
        fn = (f * n).sum(1)
        N = self.model.contact_stiffness * np.maximum(-C, 0.0) + fn
        ft = np.linalg.norm(f - fn[:, None] * n, axis=1)
        return ~((N >= 0) & (ft <= mu * N))

    def reequilibrate(self, x_warm, residual_tol: float = 1e-7, refine_iterations: int | None = None,
                      max_steps: int = 600, iterations: int = 100, cancel=None, fast: bool = False,
                      substeps: int = 1) -> None:
        """Equilibrium of the current control from a nearby one x_warm (V,3) m — what an
        optimizer needs after a small change of θ: Newton from x_warm first (anchored to it),
        a full XPBD + Newton drape from x_warm only if Newton misses residual_tol (fast and
        substeps: that drape's, as in drape). Raises ValueError when no equilibrium is reached.
        refine_iterations: Newton's budget before the fallback drape (None: REEQUILIBRATE_ITERATIONS,
        with valley contacts REEQUILIBRATE_ITERATIONS_VALLEY)."""
        if refine_iterations is None:
            refine_iterations = REEQUILIBRATE_ITERATIONS_VALLEY if self.model.valley_contact else REEQUILIBRATE_ITERATIONS
        self.state.x = x_warm
        self.state.v = np.zeros_like(self.state.x)
        _, res = self.refine(keep_anchor=False, residual_tol=residual_tol, refine_iterations=refine_iterations,
                             cancel=cancel)
        if not res <= residual_tol:
            self.state.x = x_warm
            r = self.drape(max_steps=max(max_steps, 1), iterations=iterations, min_steps=1, residual_tol=residual_tol,
                           refine_iterations=120, raise_on_divergence=False, cancel=cancel, fast=fast,
                           substeps=substeps)
            if not r.converged:
                raise ValueError(f"drape did not converge: {r.message}")

    def energy(self, x=None, gravity=(0, -9.81, 0)) -> float:
        """Total potential energy (J) at x (default: current) with the current contact set."""
        x = self.x if x is None else _validate.points("x", x)
        return self.solver.energy(x, np.asarray(gravity, dtype=np.float64))
