"""recover(scan) — the DiffAvatar main job (paper §4.2): a segmented scan in, a simulation-ready
garment (sewing pattern, material) and body out.

Stages (each reported through `progress` and checked for cancellation):
  preprocess  scan → ScanData (core frame m / Y up, garment region, named openings, interior
              samples; diffavatar_core.scan)
  body        body fit: to the scan's body-labelled points (a full scan) or under the garment
              (garment-only scans, or too little body visible)
  drape       template chosen by garment type (or a template file), placed around the fitted
              body's landmarks, sewn and draped to equilibrium
  optimize    co-optimization of cage handles, bending stiffness, body shape and pose
              (pipeline/coopt.py, equilibrium adjoint)
  metrics     Chamfer before/after (cm), mesh quality, seam mismatch
"""
from __future__ import annotations

import threading
import time
from functools import partial

import numpy as np
from scipy.spatial.transform import Rotation

from .. import _core
from .._validate import is_cancelled
from ..body import BodyModel
from ..body.fitting import fit_body
from ..metrics import chamfer_meshes, mesh_quality, surface_distances
from ..pattern.cage import build_cage
from ..pattern.export import pattern_assets
from ..pattern.garment import Garment
from ..pattern.templates import FIT_MEASUREMENTS, TEMPLATES, make_template, template_measurements
from ..scan import ScanData, load_scan
from ..scan.errors import ScanError
from ..scan.frame import FLIPPED_UP, lying_hint, upside_down_hint
from ..sim.cloth import Cloth
from ..sim.material import ClothMaterial
from .coopt import co_optimize, seam_mismatch_pct
from .facing import FACING_TURN, facing_yaw, turned_params, yaw_rotation
from .measurement_fit import MeasurementMap
from .options import RecoverOptions
from .refine import settle_carried, transfer_pattern, transfer_positions
from .result import BodyAssets, MaterialAssets, RecoveryResult
from .template_sizing import SIZING_ROUNDS, size_from_openings

STAGES = ("preprocess", "body", "drape", "optimize", "refine", "metrics")
# garment class → built-in template when the type names a class or a synonym (config/labels.yaml)
CLASS_TEMPLATE = {"upper": "tshirt", "dress": "dress", "skirt": "skirt", "pants": "pants"}
LONG_SLEEVE_REACH = 0.95    # sleeve_reach above this: long sleeves (between the t-shirt's ~0.65 and the longsleeve's ~1.3)
CANCEL_POLL_S = 0.05        # s: how often a threading.Event given as `cancel` is looked at
SELF_ANCHOR_TOL = 1e-4      # m: the output drape re-anchored at itself until it moves less (Cloth.self_anchor)
MIN_BODY_FRACTION = 0.2    # of the scan's vertices, for a body fit to the body-labelled points
SUPPORT_GAP = 0.01          # m: a drape with no vertex this near the body does not rest on it (2.5 × the 4 mm contact thickness)
POOR_BODY_FIT = 0.01        # m: a full scan's body fit with a larger rms is tried upside down (_refuse_upside_down)
POOR_FIT_CM = 3.0           # cm: a final Chamfer above it is said to misfit (a recovery that fits: 0.1–1 cm; a t-shirt
# recovered from a skirt's scan: 6–9 cm)


class RecoveryError(ValueError):
    """The recovery cannot proceed with this input (a clear message says why). `code` names the
    problem as the ROS interface spells it (AvatarAssets.ERROR_<code>), as ScanError's do:
    SIMULATION_FAILED (the default: no drape of the template on the fitted body), NO_GARMENT (the
    garment region cannot be fitted), UNKNOWN_TEMPLATE."""

    def __init__(self, message: str, code: str = "SIMULATION_FAILED"):
        super().__init__(message)
        self.code = code


class RecoveryCancelled(_core.Cancelled):
    """A recovery cancelled once its optimization had begun: `result` (a RecoveryResult) is what
    it had produced — the optimization's current iterate (metrics.stopped 'cancelled') or, when
    cancelled later, the optimized result without what was still to come (metrics.cancelled_during
    names the stage; its warnings say what is missing). Cancelled before: diffavatar_core.Cancelled."""

    def __init__(self, message: str, result):
        super().__init__(message)
        self.result = result


class _Control:
    """Progress and cancellation from either the node's RunControl or the API's callbacks. The
    C++ calls watch `token`: the RunControl's, the caller's own CancelToken, or — for a
    threading.Event — a token that a watcher thread sets within CANCEL_POLL_S of the event
    (otherwise a long drape would only notice at its end). close() ends the watcher."""

    def __init__(self, run_control=None, progress=None, cancel=None):
        self.rc, self.progress, self.user_cancel = run_control, progress, cancel
        self._done = threading.Event()
        if run_control is not None:
            self.token = run_control.cancel
        elif isinstance(cancel, _core.CancelToken):
            self.token = cancel
        else:
            self.token = _core.CancelToken()
            if hasattr(cancel, "wait"):
                threading.Thread(target=self._watch, name="recover-cancel-watch", daemon=True).start()

    def _watch(self) -> None:
        while not self._done.is_set():
            if self.user_cancel.wait(CANCEL_POLL_S):
                self.token.cancel()
                return

    def close(self) -> None:
        self._done.set()

    @property
    def cancelled(self) -> bool:
        if is_cancelled(self.user_cancel):
            self.token.cancel()
        return self.token.cancelled

    def check(self, stage: str) -> None:
        if self.cancelled:
            raise _core.Cancelled(f"cancelled during {stage}")

    def report(self, stage, iteration=0, max_iterations=0, loss=float("nan"), terms=None, check=True) -> None:
        if self.rc is not None:
            self.rc.report(stage, iteration, max_iterations, loss, terms or {})
        if self.progress is not None:
            self.progress(stage, iteration, max_iterations, loss, terms or {})
        if check:
            self.check(stage)


def sleeve_reach(boundaries: dict, lm) -> float | None:
    """Mean position of the scan's sleeve openings along the arm: each opening's centroid
    projected on its nearer shoulder → wrist segment, as a fraction of it (0 at the shoulder
    tip, 1 at the wrist); None without sleeve openings. Benchmark scans: t-shirts 0.65–0.68,
    long sleeves 1.23–1.37 (the cuff hangs past the wrist joint)."""
    arms = ((lm.shoulder_left, lm.wrist_left), (lm.shoulder_right, lm.wrist_right))
    fs = []
    for name, P in boundaries.items():
        if not name.startswith("sleeve") or not len(P):
            continue
        c = np.asarray(P, float).mean(axis=0)
        s, w = min(arms, key=lambda a: float(np.linalg.norm(c - a[0])))
        fs.append(float(np.dot(c - s, w - s) / np.dot(w - s, w - s)))
    return float(np.mean(fs)) if fs else None


def select_template(scan: ScanData, opts: RecoverOptions, landmarks=None) -> str:
    """The built-in template for the scan's garment: its type when that names a template,
    otherwise the class's default (upper → tshirt, dress, skirt, pants) — an upper garment
    whose sleeve openings reach past LONG_SLEEVE_REACH of the arm (sleeve_reach, with the
    fitted body's landmarks) → longsleeve."""
    if scan.garment_type and scan.garment_type in TEMPLATES:
        return scan.garment_type
    name = CLASS_TEMPLATE.get(scan.garment_class)
    if name not in TEMPLATES:
        raise RecoveryError(f"no built-in template for a '{scan.garment_class}' garment (built-ins: "
                            f"{', '.join(sorted(TEMPLATES))}); give one with --template FILE", "UNKNOWN_TEMPLATE")
    if name == "tshirt" and landmarks is not None:
        reach = sleeve_reach(scan.boundaries, landmarks)
        if reach is not None and reach > LONG_SLEEVE_REACH:
            return "longsleeve"
    return name


def _load_template_file(path, edge_length: float, body_vertices: np.ndarray) -> Garment:
    """An OBJ-with-UV or GarmentCode JSON template, its 3D layout moved horizontally onto the
    body's vertical axis (the layout's own height is kept: files are assumed in a Y-up frame
    with the floor at 0, like the core's)."""
    from ..pattern.garmentcode import load_garmentcode
    from ..pattern.obj_import import load_obj_pattern
    p = str(path)
    g = load_garmentcode(p, edge_length=edge_length) if p.lower().endswith(".json") else load_obj_pattern(p)
    lo, hi = body_vertices.min(axis=0), body_vertices.max(axis=0)
    centre = 0.5 * (lo + hi)
    gc = 0.5 * (g.x0.min(axis=0) + g.x0.max(axis=0))
    g.x0 = g.x0 + np.array([centre[0] - gc[0], 0.0, centre[2] - gc[2]])
    return g


def _garment_cloth(g: Garment, rest, x, material, body, bend_stiffness=None, masses_follow_rest=True,
                   contact_normals: str = "face", newton_solver: str = "simplicial",
                   newton_hinge_blocks: str = "gauss_newton") -> Cloth:
    """A Cloth of garment g's mesh, seams, panels and grain at rest shape `rest` (V, 2) m and
    state x (V, 3) m, one material for every panel, on body (V, F); bend_stiffness (G,) N·m
    replaces the material's. Its masses follow the rest shape (masses_follow_rest): every
    pattern the optimizer tries weighs what its area does, and the equilibrium adjoint
    differentiates that; with False they stay those of `rest`. contact_normals: the contact
    plane (sim.cloth.CONTACT_NORMALS); newton_solver: Newton's LDLᵀ (sim.cloth.NEWTON_SOLVERS);
    newton_hinge_blocks: how Newton's projected Hessian makes a hinge's block PSD
    (sim.cloth.NEWTON_HINGE_BLOCKS); its clones keep both."""
    cloth = Cloth(rest, g.faces, x, seams=g.seams, groups=g.panel[g.faces[:, 0]],
                  materials=[material] * len(g.panels), body=body, grain=g.face_grain(),
                  masses_follow_rest=masses_follow_rest, contact_normals=contact_normals)
    cloth.solver.supernodal_newton = newton_solver == "supernodal"
    cloth.solver.hinge_clamp = newton_hinge_blocks == "clamp"
    if bend_stiffness is not None:
        cloth.set_control(bend_stiffness=np.asarray(bend_stiffness, float))
    return cloth


def _fine_output(g, cage, co, fine: Garment, material, body_vertices, body_faces, opts, cancel):
    """(fine garment, its rest (V, 2) m, its drape (V, 3) m, the drape's SettleResult) for the
    co-optimization's result: the pattern carried through the cage, warm-started from the coarse
    drape (pushed out of the body), then an XPBD drape (single-precision sweeps, substeps) until
    it stands still (Cloth.settle: no vertex moves more than output_settle_tol in 0.5 s). Not
    Newton: at ~10k vertices its iterations cost ~1 s and crawl on the buckled cloth (200 of them
    do not converge from this start or from the settled state; docs/simulation.md, "Settled
    drapes"), and nothing is differentiated here. output_drape_sweeps (200) per step over
    output_drape_substeps (8), not `diffavatar drape`'s 100 over 4: Gauss–Seidel sweeps converge
    slower the finer the mesh, and an unconverged cloth is a softer one. On a ~9k-vertex t-shirt
    100 sweeps over 4 substeps left 0.4% mean edge strain where the Newton equilibrium of the
    coarse mesh has 0.07%; the cloth sagged ~1 cm and its Chamfer to the scan rose by a third
    (BENCHMARKS.md, stop 27); 200 over 8 leave 0.13%, 400 over 4 0.12% at twice the cost per
    step (stop 46). A velocity drag of output_drape_damping (20/s, not the simulator's 4) stills
    the carried cloth in 0.75× the steps (the ~10k benchmark job); it vanishes at rest (stop 47). Raises
    ValueError when the cloth does not settle."""
    rest = transfer_pattern(g, cage, co.rest[cage.handles], fine)   # MVC interpolate: ζ = x̄[handles]
    x0 = transfer_positions(g, co.x, fine)
    cloth = _garment_cloth(fine, rest, x0, material, (body_vertices, body_faces), co.bend_stiffness,
                           contact_normals=opts.contact_normals, newton_solver=opts.newton_solver,
                           newton_hinge_blocks=opts.newton_hinge_blocks)
    s = settle_carried(cloth, x0, body_vertices, body_faces, opts.output_drape_steps, opts.output_drape_sweeps,
                       opts.output_settle_tol, cancel, opts.output_friction, opts.output_drape_substeps,
                       opts.output_drape_damping)
    if not s.settled:
        raise ValueError(s.message)
    return fine, rest, np.array(cloth.x), s


def _refuse_upside_down(body_points, fit, model, occluders, up: str, ctl) -> None:
    """Raises RecoveryError (BAD_OPTION) when the body-labelled points (N, 3) m fit the body model
    less than half as well (rms) as they do turned 180° about X — the scan is upside down: a
    Y-down file (the camera frame of OpenCV and most photogrammetry) read as Y-up fitted the
    bundled sample to 1.8 cm rms against 0.18 cm and its drape then fell off the body. Called only
    for a poor fit (rms > POOR_BODY_FIT): the second fit costs another body fit."""
    flipped = fit_body(body_points * np.array([1.0, -1.0, -1.0]), None, model, occluders=occluders * [1.0, -1.0, -1.0],
                       cancel=ctl)
    ctl.check("body")
    if flipped.rms < 0.5 * fit.rms:
        other = FLIPPED_UP[up]
        raise RecoveryError(f"the scan looks upside down: its body fits the body model to {100 * fit.rms:.2f} cm rms "
                            f"as read (up={up}) and to {100 * flipped.rms:.2f} cm turned over — give up={other} "
                            f"(on the command line --up={other})", "BAD_OPTION")


def _initial_drape(cloth, opts, cancel):
    """The template's drape on the fitted body: drape_steps XPBD steps (1/120 s, opts.drape_sweeps
    sweeps each: more on meshes finer than 4 cm, options.sweeps_for_edge), then Newton to
    residual_tol. A drape Newton does not finish — a cloth still far from rest after drape_steps
    (a dress's long skirt on some bodies) — goes on with drape_steps more XPBD steps from where
    Newton stopped, drape_rounds rounds at most. Returns (the last DrapeResult, XPBD steps taken)."""
    steps = 0
    for _ in range(opts.drape_rounds):
        r = cloth.drape(max_steps=max(opts.drape_steps, 1), iterations=opts.drape_sweeps,
                        residual_tol=opts.residual_tol, refine_iterations=120, raise_on_divergence=False,
                        cancel=cancel)
        steps += r.steps
        if r.converged or r.diverged:
            break
    return r, steps


def check_rests_on_body(x, body_vertices, body_faces, template_name: str, cancel=None) -> float:
    """The nearest distance (m) from a drape x (V, 3) m to the body surface; raises RecoveryError
    when it exceeds SUPPORT_GAP. A garment at equilibrium with nothing pinned hangs on the body:
    its weight goes through contacts, so some vertex lies within the contact thickness. One
    farther off fell past the body (a template laid out away from the fitted body) and a
    Newton equilibrium of it balances gravity with the drape's anchor springs, not the body."""
    gap = float(surface_distances(np.asarray(x, float), body_vertices, body_faces, cancel=cancel).min())
    if gap > SUPPORT_GAP:
        raise RecoveryError(f"the initial drape of template '{template_name}' does not rest on the fitted body: "
                            f"its nearest vertex is {100 * gap:.1f} cm from the body's surface (it fell off it); "
                            f"the body fit or the template does not match the scan")
    return gap


def _assets_drape(g, co, material, body_vertices, body_faces, opts, cancel):
    """The co-optimization's drape re-solved on a Cloth of the recovered pattern and re-anchored
    at itself until it stays put (Cloth.self_anchor). The optimizer's equilibria hold anchor
    springs (the refinement's static-friction proxy, the scan guidance); this is the equilibrium
    of the written assets alone, which reloaded do not move.
    With output_friction μ > 0, an anchor whose pull is a static friction force (inside its
    contact's Coulomb cone) is kept: the drape is a static equilibrium under friction μ.

    With the face plane, rounds whose contact planes alternate do not stop: vertices over concave
    body edges, where one face's plane per vertex switches at the bisector (the long sleeve's 3–11
    mm, some skirts' 0.4–0.7 mm; docs/simulation.md, "Valleys"). Such a drape is re-anchored once
    more with valley contacts (both faces' planes there; the same planes everywhere else), from
    the same start, and kept when it moves less: the assets then record contact_normals "valley",
    with which a reload (load_result(...).cloth()) holds that equilibrium. The optimization itself
    keeps the face plane (its fits are better: BENCHMARKS.md, stops 35–36).

    Returns (drape, move, contact plane, the face plane's move or None): drape None when no round
    re-solved; move (m) the largest distance from a vertex to an anchor that is not such a force
    (≤ SELF_ANCHOR_TOL: converged); the contact plane the drape is an equilibrium of; the face
    plane's move (m) when the valley re-anchoring replaced it."""
    def anchored(planes):
        cloth = _garment_cloth(g, co.rest, co.x, material, (body_vertices, body_faces), co.bend_stiffness,
                               contact_normals=planes, newton_solver=opts.newton_solver,
                               newton_hinge_blocks=opts.newton_hinge_blocks)
        move = cloth.self_anchor(opts.residual_tol, tol=SELF_ANCHOR_TOL, cancel=cancel, friction=opts.output_friction)
        return (np.array(cloth.x) if np.isfinite(move) else None), move, planes

    out = anchored(opts.contact_normals)
    if opts.contact_normals == "face" and not out[1] <= SELF_ANCHOR_TOL:
        valley = anchored("valley")
        if valley[0] is not None and (out[0] is None or valley[1] < out[1]):
            return valley + (out[1],)
    return out + (None,)


def _body_assets(model: BodyModel, p) -> BodyAssets:
    # BodyParams hold Euler angles (R = Rz Ry Rx); the assets carry axis-angle per joint
    pose_aa = Rotation.from_euler("ZYX", np.asarray(p.pose)[:, ::-1]).as_rotvec()
    return BodyAssets(model_id=model.name, shape=p.shape.copy(), joint_names=list(model.joint_names),
                      pose=pose_aa, bone_scales=p.bone_scales.copy(),
                      global_transform=np.concatenate([p.rotation, p.translation]))


def recover(scan, options=None, run_control=None, *, progress=None, cancel=None,
            body_model: BodyModel | None = None) -> RecoveryResult:
    """Recovers pattern, material and body from a segmented scan.

    scan: a path (PLY with per-vertex `label`, OBJ, ...), (vertices, faces[, labels]) arrays, the
    node's message dict, or a preprocessed ScanData. options: RecoverOptions or a dict of
    overrides of the configured defaults (iterations, garment_type, template, units, up, ...).
    progress(stage, iteration, max_iterations, loss, terms) is called per stage and per
    iteration; cancel: a threading.Event or CancelToken (raises diffavatar_core.Cancelled; once the
    optimization has begun, RecoveryCancelled, a Cancelled carrying what was produced as `.result`).
    run_control: the node's RunControl (report/cancel), an alternative to progress/cancel.
    Raises ScanError / RecoveryError (ValueError) with a message naming the problem."""
    t0 = time.perf_counter()
    opts = RecoverOptions.coerce(options)
    ctl = _Control(run_control, progress, cancel)
    try:
        return _recover(scan, opts, ctl, body_model, t0)
    finally:
        ctl.close()


def scan_for_recovery(scan, opts: RecoverOptions) -> ScanData:
    """The scan as the recovery sees it (stage `preprocess`): a ScanData as given, anything else
    through load_scan with the options' units, up axis, label, garment type and scan cleaning.
    Its garment_mesh() (m, core frame) is what chamfer_*_cm are measured against."""
    if isinstance(scan, ScanData):
        return scan
    from ..scan.preprocess import ScanOptions
    return load_scan(scan, units=opts.units, up=opts.up, label=opts.label, garment_type=opts.garment_type,
                     options=ScanOptions.from_config(opts.config) if opts.config else None)


def _recover(scan, opts: RecoverOptions, ctl: "_Control", body_model, t0: float) -> RecoveryResult:
    ctl.report("preprocess")
    data = scan_for_recovery(scan, opts)
    Vg_scan, Fg_scan = data.garment_mesh()
    if len(data.interior_points) < 10:
        raise RecoveryError(f"the garment region has only {len(data.interior_points)} interior samples; "
                            f"too small to fit a garment", "NO_GARMENT")

    # body -----------------------------------------------------------------------------------
    ctl.report("body")
    model = body_model or BodyModel.default()
    body_mask = data.label_vertex_mask("body")   # all False for a garment-only scan
    full = body_mask.mean() >= MIN_BODY_FRACTION
    pts = data.vertices[body_mask] if full else Vg_scan
    fit = fit_body(pts, None, model, garment_only=not full,
                   garment_type=None if full else (data.garment_type or data.garment_class),
                   occluders=Vg_scan if full else None,   # the body under the garment is unseen
                   cancel=ctl)
    ctl.check("body")
    if full and fit.rms > POOR_BODY_FIT:
        _refuse_upside_down(pts, fit, model, Vg_scan, data.transform.up, ctl)
    body_params = fit.params
    yaw, turn, given = facing_yaw(body_params), None, data   # given: the scan as converted, before any turn
    if abs(yaw) > FACING_TURN and data.checked is not None:
        # the subject faces elsewhere than +Z: turn the scan (openings named again) and the body
        # to the core frame's facing; the outputs are turned back at the end
        turn = yaw_rotation(-yaw)
        data = data.turned(turn)
        Vg_scan, Fg_scan = data.garment_mesh()
        body_mask = data.label_vertex_mask("body")
        body_params = turned_params(body_params, turn)
    if not data.boundaries:   # L_boundary (paper §4.2.5) would have nothing to match
        found = next((w for w in data.warnings if w.startswith("openings not found")), "no openings found")
        lying = lying_hint(given.vertices, given.transform)
        raise RecoveryError(f"the garment region shows none of a '{data.garment_class}' garment's openings "
                            f"({found}): the boundary term has nothing to fit — "
                            + (f"{lying}" if lying else "is the garment label or type right, and the garment "
                                                        "region a whole garment?"), "NO_GARMENT")
    body_vertices = model.pose(body_params)

    # template + initial drape ------------------------------------------------------------------
    ctl.report("drape")
    template = opts.template or getattr(scan, "template_name", "") or None   # the node's message may name one
    lm = model.landmarks(body_params)
    remake = None   # the same template at another edge length (for the fine output mesh)
    if template and str(template) in TEMPLATES:
        template_name = str(template)
        remake = partial(make_template, template_name, landmarks=lm)
    elif template:
        template_name = str(template)
        if template_name.lower().endswith(".json"):    # GarmentCode: re-triangulated at any edge
            remake = partial(_load_template_file, template, body_vertices=body_vertices)
        else:
            g = _load_template_file(template, opts.edge_length, body_vertices)
    else:
        template_name = select_template(data, opts, lm)
        remake = partial(make_template, template_name, landmarks=lm)
    if remake is not None:
        g = remake(edge_length=opts.edge_length)
    material = ClothMaterial(bend_stiffness=opts.bend_stiffness)
    early_warnings = []
    hint = upside_down_hint(data.boundaries, data.transform)   # a garment-only scan has no body fit to tell
    if hint:
        early_warnings.append(hint)

    def initial_drape(garment, planes):
        c = _garment_cloth(garment, garment.rest, garment.x0, material, (body_vertices, model.faces),
                           masses_follow_rest=opts.masses_follow_rest, contact_normals=planes,
                           newton_solver=opts.newton_solver,
                           newton_hinge_blocks=opts.newton_hinge_blocks)
        c.sew(cancel=ctl.token)
        return (c,) + _initial_drape(c, opts, ctl.token)

    cloth, r, drape_steps = initial_drape(g, opts.contact_normals)
    also = ""   # what the valley retry gave, for the error below
    if not r.converged and not r.diverged and opts.contact_normals == "face":
        # face planes that alternate over concave body edges can keep Newton from converging (a
        # benchmark skirt: residual 13.4 after 3 rounds); both faces' planes there end the cycle
        face_message = f"{r.message}; residual {r.residual:.2e}"
        cloth_v, r_v, steps_v = initial_drape(g, "valley")
        if r_v.converged:
            cloth, r, drape_steps = cloth_v, r_v, steps_v
            opts = opts.with_(contact_normals="valley")
            early_warnings.append(f"the initial drape of template '{template_name}' did not converge with face "
                                  f"contact planes ({face_message}); the recovery continues with contact_normals "
                                  f"'valley' (both faces' planes over concave body edges), which the result records")
        else:
            also = f"; with valley contacts too: {r_v.message}; residual {r_v.residual:.2e}"
    if not r.converged:
        raise RecoveryError(f"the initial drape of template '{template_name}' on the fitted body did not "
                            f"converge in {drape_steps} XPBD steps (at most {opts.drape_rounds} rounds of drape_steps "
                            f"{opts.drape_steps}, each then Newton: {r.message}; residual {r.residual:.2e}{also})")
    x_initial = np.array(cloth.x)
    check_rests_on_body(x_initial, body_vertices, model.faces, template_name, ctl.token)
    cm = 100.0
    nsamp = int(opts.config.get("metrics", {}).get("chamfer_samples", 20000)) if opts.config else 20000
    chamfer_initial = cm * chamfer_meshes(x_initial, g.faces, Vg_scan, Fg_scan, samples=nsamp, cancel=ctl.token)
    g_template = g   # the template as selected: chamfer_initial and template_area_m2 are its

    # template sizing: length and sleeve length from the scan's openings, draped fresh -------------
    sizes, sizing = {}, None
    if opts.template_sizing and opts.iterations and opts.measurement_fit_iterations and template_name in FIT_MEASUREMENTS:
        m_default = template_measurements(template_name, lm)
        sizing = {"template_m": {k: float(getattr(m_default, k)) for k in FIT_MEASUREMENTS[template_name]},
                  "rounds": [], "kept": False}
        best, g_now, x_now, now = chamfer_initial, g, x_initial, {}
        for _ in range(SIZING_ROUNDS):   # each from the last round's drape (template_sizing.py)
            estimate = size_from_openings(template_name, lm, x_now, g_now.boundaries, data.boundaries, measurements=now)
            if not estimate:
                break
            now = {**now, **estimate}
            g_now = make_template(template_name, landmarks=lm, edge_length=opts.edge_length, **now)
            c, r_now, _ = initial_drape(g_now, opts.contact_normals)
            ctl.check("drape")
            entry = {"measurements_m": dict(now), "converged": bool(r_now.converged)}
            sizing["rounds"].append(entry)
            if not r_now.converged:
                break
            x_now = np.array(c.x)
            try:
                check_rests_on_body(x_now, body_vertices, model.faces, template_name, ctl.token)
            except RecoveryError as exc:   # fell off the body: no start, and no base for another round
                entry["off_body"] = str(exc)
                break
            entry["chamfer_cm"] = cm * chamfer_meshes(x_now, g_now.faces, Vg_scan, Fg_scan, samples=nsamp,
                                                      cancel=ctl.token)
            # the start nearest the scan (Chamfer): the measurement fit corrects the outline from either
            # start unless its warm-started drapes are stuck in a fold state far from the scan, which
            # is what the Chamfer distance shows; the folds themselves no gradient step changes, so
            # the start whose folds are nearer is kept (benchmark t-shirt 101: a start chosen by φ's
            # data terms, its hem 6 cm nearer but other folds, ended at ratio 0.57 against 0.50)
            if entry["chamfer_cm"] < best:
                best, g, cloth, x_initial, sizes = entry["chamfer_cm"], g_now, c, x_now, dict(now)
        if sizes:
            remake = partial(make_template, template_name, landmarks=lm, **sizes)
            sizing.update(kept=True, measurements_m=sizes, chamfer_cm=best)

    # co-optimization ------------------------------------------------------------------------
    cage = build_cage(g) if opts.parametrization == "cage" else None
    mmap = None   # the measurement fit: built-in templates (their outline is parametric)
    if opts.measurement_fit_iterations and template_name in FIT_MEASUREMENTS and remake is not None:
        mmap = MeasurementMap(template_name, lm, g, cage if cage is not None else build_cage(g), measurements=sizes)
    # at most: the measurement fit, again after a bending search that moved, then the co-optimization
    n_fit = opts.measurement_fit_iterations * (2 if opts.measurement_fit_bending else 1) + (1 if opts.measurement_fit_bending else 0)
    n_total = opts.iterations + (n_fit if mmap is not None and opts.iterations else 0)
    ctl.report("optimize", 0, n_total)

    def on_iteration(h):
        ctl.report("optimize", h["iteration"], n_total, h["value"], h["terms"])

    co = co_optimize(cloth, g, data.interior_points, data.boundaries, opts, cage=cage, body_model=model,
                     body_params=body_params, on_iteration=on_iteration, cancelled=lambda: ctl.cancelled,
                     cancel=ctl.token, body_points=data.vertices[body_mask] if full else None,
                     scan_mesh=data.garment_mesh(), measurement_map=mmap)
    # a cancel from here on keeps what was produced (RecoveryCancelled): the stages still to come
    # are skipped, the metrics (seconds) computed regardless
    cancelled_in = "optimize" if co.stopped == "cancelled" else None

    body_final = co.body_vertices if co.body_vertices is not None else body_vertices
    if co.stretch_compliance is not None:   # the recovered compliances (opts.stretch; else the material's)
        warp, weft, shear = np.exp(np.log(co.stretch_compliance).mean(axis=0))
        material = ClothMaterial(density=material.density, warp_compliance=float(warp), weft_compliance=float(weft),
                                 shear_compliance=float(shear), bend_stiffness=material.bend_stiffness)
    warnings = list(data.warnings) + early_warnings
    if co.stopped == "invalid_start":
        warnings.append(f"the optimization stopped after {co.iterations} of {opts.iterations} iterations: its "
                        f"last iterate no longer re-draped ({co.stop_reason}); that iterate is returned")
    if cancelled_in:
        step = co.history[-1]["iteration"] if co.history else 0   # as the progress reports counted them
        warnings.append(f"cancelled during the optimization at step {step} of {n_total}: the result is its current "
                        f"iterate in the drape its loss was evaluated on (anchored to the previous iterate's drape, "
                        f"not re-solved without anchors), on the optimized mesh (edge {opts.edge_length} m); no "
                        f"bending range was judged")

    # output resolution (coarse-to-fine through the cage) ------------------------------------------
    g_out, rest_out, x_out, handles_out = g, co.rest, co.x, (cage.handles if cage is not None else None)
    output_drape = {"criterion": "equilibrium", "residual_tol": opts.residual_tol}
    fine_edge = opts.output_edge_length
    if fine_edge and fine_edge < opts.edge_length and not cancelled_in:
        if cage is None or remake is None:
            warnings.append(f"output_edge_length {fine_edge} m needs the cage parametrization and a built-in or "
                            f"GarmentCode template; the optimized mesh (edge {opts.edge_length} m) is returned")
        else:
            try:
                ctl.report("refine")
                g_out, rest_out, x_out, settle = _fine_output(g, cage, co, remake(edge_length=fine_edge),
                                                              material, body_final, model.faces, opts, ctl.token)
                handles_out = None
                output_drape = {"criterion": "settled", **settle.to_json()}
            except ValueError as exc:   # nothing produced so far is lost: keep the coarse result
                warnings.append(f"the fine output mesh (edge {fine_edge} m) did not settle ({exc}); "
                                f"the optimized mesh (edge {opts.edge_length} m) is returned")
            except _core.Cancelled:
                cancelled_in = "refine"
                warnings.append(f"cancelled while carrying the result to the fine output mesh (edge {fine_edge} m): "
                                f"the optimized mesh (edge {opts.edge_length} m) is returned, in the optimizer's "
                                f"(anchored) drape")
    output_planes = opts.contact_normals   # the contact plane the output drape is an equilibrium of
    if g_out is g and not cancelled_in:   # the optimized mesh is the output
        try:
            x_assets, move, planes, face_move = _assets_drape(g, co, material, body_final, model.faces, opts,
                                                              ctl.token)
        except _core.Cancelled:
            cancelled_in = "output drape"
            warnings.append("cancelled while re-solving the recovered drape without the optimizer's anchor springs: "
                            "the optimizer's (anchored) drape is returned")
        else:
            if x_assets is None:
                warnings.append("the recovered drape did not re-solve without the optimizer's anchor springs; the "
                                "optimizer's (anchored) drape is returned")
            else:
                x_out, output_planes = x_assets, planes
                output_drape["self_anchor_move_m"] = move   # the last re-anchoring round's largest move
                output_drape["contact_normals"] = planes
                if face_move is not None:   # re-anchored with valley contacts where face planes alternated
                    output_drape["face_plane_move_m"] = face_move
                if move > SELF_ANCHOR_TOL:
                    warnings.append(f"the recovered drape still moved {1e3 * move:.2f} mm in its last re-anchoring "
                                    f"(Cloth.self_anchor, friction {opts.output_friction}, contact plane {planes}): reloaded, the assets may "
                                    f"settle by about that much")

    # result ------------------------------------------------------------------------------------
    if cancelled_in:
        output_drape["criterion"] = "anchored"   # the optimizer's drape, as the warnings say
    ctl.report("metrics", check=False)   # a cancel from now on keeps the result (RecoveryCancelled)
    g_final = Garment(rest_out, g_out.faces, x_out, g_out.seams, g_out.panel, g_out.panels, g_out.boundaries,
                      name=g_out.name)
    q = mesh_quality(x_out, g_out.faces)
    metrics = {
        "chamfer_initial_cm": chamfer_initial,
        "chamfer_final_cm": cm * chamfer_meshes(x_out, g_out.faces, Vg_scan, Fg_scan, samples=nsamp),
        "mesh_quality_min": q.min, "mesh_quality_avg": q.mean,
        "seam_length_mismatch_max_pct": seam_mismatch_pct(g_out, rest_out),
        "pattern_area_m2": g_final.total_area(), "template_area_m2": g_template.total_area(),
        "template_sizing": sizing,
        "stopped": co.stopped, "rejected_iterations": co.rejected, "fresh_drapes_kept": co.fresh_kept,
        "guided_drapes_kept": co.guided_kept, "initial_drapes_kept": co.initial_kept,
        "bending_candidates_kept": co.bending_kept,
        "measurement_fit": co.measurement_fit.to_json() if co.measurement_fit is not None else None,
        "measurement_fit_bending": co.bending_search,
        "bending_range": co.bending_range,
        "optimized_vertices": int(len(g.rest)), "output_vertices": int(len(rest_out)),
        "output_drape": output_drape,
        "cancelled_during": cancelled_in,   # None: the recovery ran to its end
    }
    if g_out is not g:   # the fine output: also the Chamfer of the optimized (coarse) drape it came from
        metrics["chamfer_optimized_cm"] = cm * chamfer_meshes(co.x, g.faces, Vg_scan, Fg_scan, samples=nsamp)
    optimized = metrics.get("chamfer_optimized_cm", metrics["chamfer_final_cm"])   # on the optimization's mesh
    if optimized > 1.01 * chamfer_initial:   # φ ranked a worse fit lower (beyond re-anchoring's 1%): say so
        warnings.append(f"the recovered garment is farther from the scan (Chamfer {optimized:.3f} cm) than the "
                        f"template's initial drape ({chamfer_initial:.3f} cm): the objective preferred a worse fit "
                        f"(with boundary_scale > 0 a garment hung elsewhere costs little)")
    if metrics["chamfer_final_cm"] > POOR_FIT_CM:   # a result that does not describe the scan: say so, and why it may be
        missing = next((w for w in data.warnings if w.startswith("openings not found")), "")
        warnings.append(f"the recovered garment is {metrics['chamfer_final_cm']:.1f} cm from the scan on average "
                        f"(Chamfer; above {POOR_FIT_CM:g} cm, where fitting recoveries stay within about 1 cm): it does "
                        f"not describe this scan — is the garment type '{data.garment_type or data.garment_class}' "
                        f"(template '{template_name}') right? Openings matched: {', '.join(sorted(data.boundaries))}"
                        + (f"; {missing}" if missing else ""))
    body_out, scan_vertices = co.body_params, data.vertices
    metrics["facing_yaw_rad"] = yaw   # the fitted body's facing, from +Z (about +Y)
    if turn is not None:   # back to the scan's own facing: the assets overlay the scan as given
        x_out, body_final, scan_vertices = x_out @ turn, body_final @ turn, data.vertices @ turn
        body_out = turned_params(co.body_params, turn.T)
        g_final = Garment(rest_out, g_out.faces, x_out, g_out.seams, g_out.panel, g_out.panels, g_out.boundaries,
                          name=g_out.name)
        warnings.append(f"the subject faces {np.degrees(yaw):.0f}° from +Z about the vertical: the recovery ran "
                        f"turned to face +Z and its outputs are turned back (metrics.facing_yaw_rad)")
    origin = given.transform.origin   # a scan far from its file's origin ran centred (scan/frame.py)
    metrics["scan_origin_m"] = origin.tolist()
    if origin.any():   # back where the scan is: the assets overlay it as given
        x_out, body_final, scan_vertices = x_out + origin, body_final + origin, scan_vertices + origin
        body_out = body_out.copy()
        body_out.translation = np.asarray(body_out.translation, np.float64) + origin
        g_final = Garment(rest_out, g_out.faces, x_out, g_out.seams, g_out.panel, g_out.panels, g_out.boundaries,
                          name=g_out.name)
    bend = np.asarray(co.bend_stiffness, float)
    mat = MaterialAssets(bending_stiffness=float(np.exp(np.mean(np.log(bend)))),
                         panel_bending_stiffness=bend.copy() if opts.bending == "panel" else np.zeros(0),
                         compliance_warp=material.warp_compliance, compliance_weft=material.weft_compliance,
                         compliance_shear=material.shear_compliance, density=material.density,
                         thickness=float(cloth.model.thickness), contact_normals=output_planes,
                         bending_stiffness_range=((co.bending_range["low_Nm"], co.bending_range["high_Nm"])
                                                  if co.bending_range else (None, None)))
    result = RecoveryResult(
        garment_type=data.garment_type or data.garment_class, template_name=template_name,
        pattern=pattern_assets(g_final, handles_out), material=mat,
        body=_body_assets(model, body_out), garment_vertices=x_out, garment_faces=g_out.faces.astype(np.int64),
        garment_uv=rest_out.copy(), body_vertices=body_final, body_faces=np.asarray(model.faces, np.int64),
        metrics=metrics, iterations=co.iterations, wall_s=time.perf_counter() - t0,
        loss_history=[{"iteration": h["iteration"], "value": h["value"], "terms": h["terms"],
                       "stage": h.get("stage", "co_optimization")} for h in co.history])
    result.garment = g_final
    result.template = g_out   # the template mesh the pattern was deformed from (same vertices; its rest unchanged)
    result.body_params = body_out
    result.warnings = warnings
    result.scan_mesh = (scan_vertices, data.faces)
    if cancelled_in or ctl.cancelled:
        raise RecoveryCancelled(f"cancelled during {cancelled_in or 'metrics'}", result)
    return result


__all__ = ["recover", "scan_for_recovery", "RecoveryError", "RecoveryCancelled", "select_template", "sleeve_reach", "STAGES", "ScanError"]
