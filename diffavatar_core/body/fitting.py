"""Fitting the parametric body to a scan (paper §4.1, "Body Shape and Pose Initialization"):
Gauss–Newton / Levenberg–Marquardt over shape ν, joint angles ψ, bone-length scales and a
global rigid transform, minimising a robust two-way point-to-surface Chamfer energy, with
joint limits (angles projected onto their box after every step) and priors.

Energy (all lengths in m, after the scan is brought into the core's frame):
  E(θ) = 1/M Σ_i ρ_σ(n_i·(x_i(θ) − p_i))            scan → body, point-to-plane: p_i a scan
                                                     sample, x_i its closest body-surface point
                                                     (barycentric in the posed body), n_i the
                                                     body face normal
       + β/B Σ_v ρ_σb(|x_v(θ) − q_v|)                body → scan: q_v the closest scan point
                                                     (surface when the scan has faces)
       + γ/Q Σ_u min(0, n_u·(x_u(θ) − y_u(θ)))²      self-penetration, in the last iterations:
                                                     forearm/hand vertices x_u against the torso
                                                     surface, lower-leg vertices against the
                                                     other leg (y_u the closest point there, n_u
                                                     its normal)
       + α_ν |ν|² + α_ψ |ψ|² + α_s |s − 1|²          priors (ν ~ N(0, I))
ρ_σ is Geman–McClure, minimised by iteratively reweighted least squares
(w = σ⁴ / (σ² + r²)²), so holes and floating fragments (residuals ≫ σ) are ignored; σ is
annealed from coarse to fine, and σ_b = σ/2 so that body vertices over a hole let go early.
The global transform is initialised from the scan's robust
extent and horizontal principal axes (twelve yaw candidates; the three best are refined
rigidly with the stature coefficient, and the best of those starts the full fit).

Garment-only scans (the body is not visible): the garment is a shell around the body, so
  E_g = 1/M Σ_i [a_i w_i (d_i − c)² + κ min(0, d_i − c_min)²],  d_i = ±|p_i − x_i|
the signed garment-to-body distance: Euclidean, + outside, to the surface a garment can cover
(not the head, hands or feet: a foot caught in a trouser leg held the leg too short). Its
gradient −u_i·∂x_i/∂θ, u_i the unit direction from x_i to p_i, is exact; the face-normal
distance of the full-scan term jumps where the closest point passes from one face of an edge
to the other, and LM stalled on those jumps under garments. The term is quadratic about the
clearance c where the garment is closer (symmetric: a one-sided penalty makes a smaller,
shorter body the cheapest fit), Geman–McClure where it is further (loose regions do not pull
the body out), and κ = penetration_weight below the minimum gap c_min (the body about to poke
through). a_i ∈ {0, 1} says which garment points attract the body: a draped garment touches
it only where it hangs from (a loose t-shirt's lower half, a skirt below the hips hang free,
and attracting them inflated the body by up to 13 cm in stature). Tops and dresses are fitted twice: first only their top band (top_band: shoulders,
upper chest) attracts, under a stronger shape prior; then every point whose gap is within
contact_tolerance of c joins (all of a tight top, the chest and back of a loose one) and the
fit goes on under the ordinary prior. On skirts only the top skirt_band (waistband, hips)
attracts, under a stronger prior still: a skirt shows neither the legs nor the stature. Points
that do not attract still keep the body inside (κ). Bone scales are held at 1 except the
torso's under tops and dresses, which show its proportions, and the priors are weighted like
the data (about residual² / samples / prior variance: the garment's shape decides ν where it is
seen, the prior where it is not). The placement
puts the garment's top at the shoulders (tops, dresses) or the waist (skirts, trousers:
garment_type); the best placement and the best one facing the other way (a garment's front and
back look alike) are both fitted for a few iterations and the lower robust energy goes on.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from .. import _core, _validate
from .._validate import check_cancel
from .model import BodyModel
from .params import BodyParams

UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}


def scan_to_core(points, units: str = "m", up: str = "y") -> tuple[np.ndarray, np.ndarray]:
    """Scan points → core frame (m, Y up). Returns (points (N,3) m, 3×3 matrix A with
    core = A @ scan): scan.frame.ScanTransform's scale and rotation (Z-up scans turned by −90°
    about X, (x, y, z) → (x, z, −y); up -y / -z turned 180° about X more)."""
    from ..scan.frame import UP_AXES, ScanTransform
    if units not in UNITS:
        raise ValueError(f"units: expected one of {sorted(UNITS)}, got {units!r}")
    if up not in UP_AXES:
        raise ValueError(f"up: expected one of {', '.join(UP_AXES)}, got {up!r}")
    P = _validate.points("scan", points)
    t = ScanTransform.from_options(units, up)
    A = t.scale * t.rotation
    return P @ A.T, A


@dataclass
class FitOptions:
    """Tuning of fit_body (lengths in m)."""
    iterations: int = 45                 # Gauss–Newton iterations of the full fit
    scan_samples: int = 5000             # scan points per iteration (scan → body)
    body_samples: int = 2500             # body vertices per iteration (body → scan)
    sigma: tuple = (0.08, 0.015)        # robust scale annealed from the first to the second
    body_to_scan_weight: float = 0.3     # β
    body_to_scan_sigma: float = 0.5      # robust scale of the body → scan term, × σ
    shape_prior: float = 2e-8            # α_ν (m² per unit²)
    pose_prior: float = 2e-8             # α_ψ (m² per rad²) at the end of the annealing
    pose_prior_boost: float = 1000.0     # α_ψ multiplier at the start (annealed to 1)
    scale_prior: float = 2e-5            # α_s (m² per unit of scale²)
    bone_scale_range: tuple = (0.85, 1.2)
    shape_range: float = 3.5             # |ν_k| ≤ this
    self_penetration_weight: float = 1.0  # γ
    self_penetration_samples: int = 300  # vertices per part pair and iteration
    self_penetration_iterations: int = 12  # the term is active in the last iterations only
    clearance: float = 0.01              # garment-only: target body-to-garment gap (m)
    min_clearance: float = 0.003         # garment-only: gaps below this are penalised with κ
    penetration_weight: float = 10.0     # garment-only: κ
    # garment-only priors: about (residual² / independent samples) / (prior variance), so that
    # the torso's shape decides ν where it is seen; stronger ones shrink ν towards the mean
    # body (a tall body under a top came out 7 cm short with 2e-6 / 5e-5)
    garment_shape_prior: float = 5e-8
    garment_pose_prior: float = 5e-6
    multi_start_iterations: int = 12     # garment-only: iterations of each of the two starts
    top_band: float = 0.25               # garment-only tops, dresses: the band (m) below the top attracting first
    top_shape_prior: float = 5e-7        # garment-only tops, dresses: α_ν while only that band attracts
    contact_tolerance: float = 0.01      # then points with |gap − clearance| below this (m) attract too
    contact_iterations: int = 20         # iterations of that second pass (after `iterations`)
    skirt_band: float = 0.2              # garment-only skirts: the top band (m) that attracts the body
    skirt_shape_prior: float = 5e-6      # garment-only skirts: α_ν (a skirt shows the waist and hips only)
    seed: int = 0


@dataclass
class FitResult:
    """params: fitted BodyParams in the core frame (m, Y up) of the converted scan;
    to_core: 3×3 matrix taking scan coordinates to that frame; history: energy per iteration;
    rms: RMS scan → body distance of the inlier scan points (m)."""
    params: BodyParams
    to_core: np.ndarray
    history: list = field(default_factory=list)
    rms: float = float("nan")


def _gm_weight(r, sigma):
    return (sigma ** 2 / (sigma ** 2 + r ** 2)) ** 2


def _gm_rho(r, sigma):
    """Geman–McClure ρ(r) = σ² r² / (σ² + r²) (≈ r² for |r| ≪ σ, → σ² for outliers)."""
    return sigma ** 2 * r ** 2 / (sigma ** 2 + r ** 2)


def _jacobian_rows(model: BodyModel, p: BodyParams, idx) -> np.ndarray:
    """∂x_v/∂θ for the vertex indices idx (any shape): idx.shape + (3, P), evaluated once per
    distinct vertex (a fit touches a few thousand of the body's vertices per iteration)."""
    idx = np.asarray(idx)
    uniq, inv = np.unique(idx, return_inverse=True)
    return model.jacobian(p, uniq)[inv.reshape(idx.shape)]


def _wrapped(rotvec) -> np.ndarray:
    """The same rotation as an axis-angle vector of angle ≤ π: near |r| = 2π the map from r to
    the rotation is singular (every axis gives the identity there) and LM steps lose their way."""
    return Rotation.from_rotvec(np.asarray(rotvec, np.float64)).as_rotvec()


def _face_normals(X, F):
    n = np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-18)


class _Fitter:
    def __init__(self, model: BodyModel, scan: np.ndarray, scan_faces, opts: FitOptions, garment: bool,
                 progress=None, occluders=None, cancel=None):
        self.m, self.opts, self.garment = model, opts, garment
        self.cancel = cancel
        self.scan = scan
        self.scan_faces = scan_faces
        self.tree = cKDTree(scan)
        # full scans: points of what covers the body (the garment); a body vertex nearer to them
        # than to the body's own points is hidden, and the body → scan term leaves it free
        self.occluder_tree = cKDTree(occluders) if occluders is not None and len(occluders) else None
        self.rng = np.random.default_rng(opts.seed)
        self.progress = progress
        K, J = model.num_shape, model.num_joints
        sl = model.param_slices()
        free = np.ones(model.num_params, bool)
        fixed_angle = (model.limits_lo >= model.limits_hi).reshape(-1)
        free[sl["pose"]] &= ~fixed_angle
        free[sl["bone_scales"].start] = False          # the root's scale has no effect
        if garment:
            free[sl["bone_scales"]] = False
        self.free = free
        # garment-only: the surface a garment can cover, and per-point attraction weights a_i
        self.cover_faces = garment_faces(model) if garment else np.ascontiguousarray(model.faces)
        self.attract = np.ones(len(scan))
        self.shape_prior = opts.garment_shape_prior if garment else opts.shape_prior
        self.contact_pass = False
        self.sl = sl
        self.K, self.J = K, J
        self.pose_boost = 1.0
        self.pen_pairs = penetration_pairs(model)
        self.pen_on = 0.0
        self.pen_rng = np.random.default_rng(opts.seed + 1)

    # -- residuals and their Jacobians at θ ------------------------------------------------------
    def _terms(self, p: BodyParams, sigma: float, idx_scan, idx_body, with_jac: bool):
        m, o = self.m, self.opts
        X = m.pose(p)
        F = self.cover_faces
        S = self.scan[idx_scan]
        tri, bary, cp = _core.closest_points_on_mesh(X, F, np.ascontiguousarray(S))
        nf = _face_normals(X, F[tri])
        d = np.einsum("ij,ij->i", S - cp, nf)              # signed, + outside the body
        if self.garment:
            # Euclidean signed distance; its direction u replaces the face normal (exact gradient)
            diff = S - cp
            dist = np.linalg.norm(diff, axis=1)
            sgn = np.where(d < 0, -1.0, 1.0)
            ok = dist > 1e-12
            nf = np.where(ok[:, None], sgn[:, None] * diff / np.where(ok, dist, 1.0)[:, None], nf)
            d = sgn * dist
        rows, res, wts, rho = [], [], [], 0.0
        if self.garment:
            # symmetric about the clearance (an asymmetric one shrinks the body: a smaller, shorter
            # body is the cheapest way to stay clear everywhere), Geman–McClure outside it, and
            # κ below the minimum clearance (the garment about to enter the body)
            r1 = d - o.clearance
            a = self.attract[idx_scan]
            w1 = np.where(r1 < 0, 1.0, a * _gm_weight(r1, sigma))
            r2 = np.minimum(d - o.min_clearance, 0.0)
            kin = o.penetration_weight
            rho += float(np.sum(np.where(r1 < 0, r1 * r1, a * _gm_rho(r1, sigma)) + kin * r2 * r2)) / len(S)
            res += [-r1, -r2]                                # u·(x − p) + c, u·(x − p) + c_min
            wts += [w1 / len(S), np.full(len(S), kin / len(S))]
        else:
            r1 = -d
            res.append(r1)
            wts.append(_gm_weight(r1, sigma) / len(S))
            rho += float(np.sum(_gm_rho(r1, sigma))) / len(S)
        jac = (lambda idx: _jacobian_rows(m, p, idx)) if with_jac else None
        if with_jac:
            Fi = F[tri]
            Jb = np.einsum("ik,ikcp->icp", bary, jac(Fi))
            rows.append(np.einsum("ic,icp->ip", nf, Jb))
            if self.garment:
                rows.append(np.where((r2 < 0)[:, None], rows[-1], 0.0))
        if not self.garment:
            Xb = X[idx_body]
            if self.scan_faces is not None:
                _, _, q = _core.closest_points_on_mesh(self.scan, self.scan_faces, np.ascontiguousarray(Xb))
            else:
                q = self.scan[self.tree.query(Xb)[1]]
            diff = Xb - q
            dist = np.linalg.norm(diff, axis=1)
            beta = o.body_to_scan_weight / len(Xb)
            sb = o.body_to_scan_sigma * sigma        # tighter: body vertices over holes let go
            seen = np.ones(len(Xb))
            if self.occluder_tree is not None:       # under the garment: no body point to reach
                seen = (dist <= self.occluder_tree.query(Xb)[0]).astype(np.float64)
            res.append(diff.reshape(-1))
            wts.append(np.repeat(beta * seen * _gm_weight(dist, sb), 3))
            rho += beta * float(np.sum(seen * _gm_rho(dist, sb)))
            if with_jac:
                rows.append(jac(idx_body).reshape(-1, m.num_params))
        gamma = o.self_penetration_weight * self.pen_on
        for verts, faces in (self.pen_pairs if gamma > 0 else []):
            u = verts if len(verts) <= o.self_penetration_samples else \
                self.pen_rng.choice(verts, o.self_penetration_samples, replace=False)
            t2, b2, c2 = _core.closest_points_on_mesh(X, faces, np.ascontiguousarray(X[u]))
            n2 = _face_normals(X, faces[t2])
            dp = np.minimum(np.einsum("ij,ij->i", X[u] - c2, n2), 0.0)
            res.append(dp)
            wts.append(np.full(len(u), gamma / len(u)))
            rho += gamma * float(np.sum(dp * dp)) / len(u)
            if with_jac:
                Fi = faces[t2]
                Jc = np.einsum("ik,ikcp->icp", b2, jac(Fi))
                Jrow = np.einsum("ic,icp->ip", n2, jac(u) - Jc)
                Jrow[dp == 0.0] = 0.0
                rows.append(Jrow)
        inl = np.abs(d) < 3 * sigma
        rms = float(np.sqrt(np.mean(d[inl] ** 2))) if inl.any() else float("nan")
        return np.concatenate(res), np.concatenate(wts), (np.concatenate(rows) if with_jac else None), rms, rho

    def _priors(self, p: BodyParams):
        """(residuals, weights, Jacobian rows) of the priors (pose prior × self.pose_boost)."""
        o, m = self.opts, self.m
        a_nu = self.shape_prior
        a_psi = (o.garment_pose_prior if self.garment else o.pose_prior) * self.pose_boost
        n = m.num_params
        r = np.concatenate([p.shape, p.pose.reshape(-1), p.bone_scales - 1])
        w = np.concatenate([np.full(self.K, a_nu), np.full(3 * self.J, a_psi), np.full(self.J, o.scale_prior)])
        Jp = np.zeros((len(r), n))
        Jp[np.arange(len(r)), np.arange(len(r))] = 1.0
        return r, w, Jp

    def energy(self, p, sigma, idx_scan, idx_body):
        """E(θ) with the robust ρ (module doc) on the given samples."""
        _, _, _, _, rho = self._terms(p, sigma, idx_scan, idx_body, with_jac=False)
        rp, wp, _ = self._priors(p)
        return rho + float(np.sum(wp * rp * rp))

    def project(self, p: BodyParams) -> BodyParams:
        o, m = self.opts, self.m
        p.pose = m.clamp_pose(p.pose)
        p.bone_scales = np.clip(p.bone_scales, *o.bone_scale_range)
        p.shape = np.clip(p.shape, -o.shape_range, o.shape_range)
        p.rotation = _wrapped(p.rotation)
        return p

    def run(self, p: BodyParams, iterations: int, sigmas, free=None, n_scan=None, n_body=None,
            history=None, boosts=(1.0,), pen_last=0):
        o, m = self.opts, self.m
        free = self.free if free is None else free
        n_scan = min(n_scan or o.scan_samples, len(self.scan))
        n_body = min(n_body or o.body_samples, m.num_vertices)
        lam = 1e-4
        rms = float("nan")
        for it in range(iterations):
            check_cancel(self.cancel, "body fit")
            sigma = float(sigmas[min(it, len(sigmas) - 1)])
            self.pose_boost = float(boosts[min(it, len(boosts) - 1)])
            self.pen_on = 1.0 if it >= iterations - pen_last else 0.0
            idx_scan = self.rng.choice(len(self.scan), n_scan, replace=False)
            idx_body = self.rng.choice(m.num_vertices, n_body, replace=False)
            r, w, Jr, rms, rho = self._terms(p, sigma, idx_scan, idx_body, with_jac=True)
            rp, wp, Jp = self._priors(p)
            e0 = rho + float(np.sum(wp * rp * rp))
            r = np.concatenate([r, rp])
            w = np.concatenate([w, wp])
            Jr = np.ascontiguousarray(np.concatenate([Jr, Jp])[:, free])
            H, g = _core.normal_equations(Jr, np.ascontiguousarray(w), np.ascontiguousarray(r))
            x0 = p.to_vector()
            accepted = False
            for _ in range(6):
                step = _core.damped_step(H, g, lam)
                x = x0.copy()
                x[free] += step
                q = self.project(BodyParams.from_vector(x, self.K, self.J))
                e1 = self.energy(q, sigma, idx_scan, idx_body)
                if e1 <= e0:
                    p, accepted = q, True
                    lam = max(lam / 3, 1e-7)
                    break
                lam *= 10
            if history is not None:
                history.append(min(e0, e1) if accepted else e0)
            if self.progress is not None:
                self.progress(it, iterations, rms)
            if not accepted and lam > 1e3:
                break
        return p, rms


def _robust_extent(P):
    lo, hi = np.percentile(P, [0.5, 99.5], axis=0)
    return lo, hi


#: Where the top of a garment of each class sits on the body (garment-only placement).
GARMENT_ANCHORS = {"upper": "shoulders", "dress": "shoulders", "skirt": "waist", "pants": "waist"}


def garment_class_of(garment_type: str) -> str:
    """The garment class ('upper', 'dress', 'skirt', 'pants') of a garment type or class name
    as in config/labels.yaml ('tshirt' → 'upper', 'trousers' → 'pants', 'skirt' → 'skirt')."""
    from ..scan.labels import LabelMap
    lmap = LabelMap.load()
    cls = lmap.garment_class(str(garment_type))
    if cls not in GARMENT_ANCHORS:
        raise ValueError(f"garment_type: {garment_type!r} is not a known garment type or class "
                         f"(classes: {', '.join(GARMENT_ANCHORS)}; types: {', '.join(lmap.garment_types)})")
    return cls


def _anchor_point(model: BodyModel, anchor: str) -> np.ndarray:
    """Rest-pose point (3,) of the mean body where a garment's top sits: the shoulder joints
    (tops, dresses) or the waist (skirts, trousers; the waist landmark of the mean body, or
    10 cm above the hip joints for models without the default skeleton)."""
    J = model.j_template
    if anchor == "shoulders":
        sh = J[[model.joint_index("shoulder_left"), model.joint_index("shoulder_right")]].mean(0)
        return sh + np.array([0.0, 0.02, 0.0])          # the shoulder line, 2 cm above the joints
    try:
        return np.asarray(model.landmarks(model.zero_params()).waist_center, np.float64)
    except ValueError:
        hips = [i for i, n in enumerate(model.joint_names) if n.startswith("hip")]
        c = J[hips].mean(0) if hips else J[0]
        return c + np.array([0.0, 0.10, 0.0])


def fit_body(scan_vertices, scan_faces=None, model: BodyModel | None = None, *, units: str = "m",
             up: str = "y", garment_only: bool | None = None, garment_type: str | None = None,
             options: FitOptions | None = None, progress=None, occluders=None, cancel=None) -> FitResult:
    """Fits the body to a scan (points (N,3), optional triangles (F,3)) given in `units`
    (m/cm/mm) with `up` ('y' or 'z') vertical. Returns the body parameters in the core frame
    (m, Y up) of the converted scan.

    garment_only: the scan is a garment worn by the body (the body is fitted inside it);
    default: True when garment_type is given, else False.
    garment_type: the garment's type or class ('tshirt', 'upper', 'dress', 'skirt',
    'trousers', 'pants', ... as in config/labels.yaml): where its top sits on the body (the
    shoulders for tops and dresses, the waist for skirts and trousers). Without it a
    garment-only scan is placed as a top.
    occluders (M,3), same units and axes: full scans — the points of the garment covering the
    body. A body vertex nearer to them than to the body points is hidden under the garment and
    not pulled toward the body points (without them, the arms under long sleeves swung toward
    the hips and hands: 6–13 cm mean vertex error).
    cancel: a threading.Event or CancelToken, checked every Gauss–Newton iteration (a fit takes
    seconds): raises diffavatar_core.Cancelled."""
    model = model or BodyModel.default()
    o = options or FitOptions()
    if garment_only is None:
        garment_only = garment_type is not None
    if garment_type is not None and not garment_only:
        raise ValueError("garment_type is for garment-only scans (garment_only=True)")
    anchor = GARMENT_ANCHORS[garment_class_of(garment_type)] if garment_type is not None else "shoulders"
    P, A = scan_to_core(scan_vertices, units, up)
    F = None
    if scan_faces is not None and len(scan_faces):
        F = _validate.faces("scan_faces", scan_faces, len(P))
    lo, hi = _robust_extent(P)
    inl = np.all((P >= lo - 0.05) & (P <= hi + 0.05), axis=1)
    centre = P[inl].mean(axis=0)
    # yaw candidates from the horizontal principal axes (the body's width is along X)
    H = P[inl][:, [0, 2]] - centre[[0, 2]]
    evals, evecs = np.linalg.eigh(H.T @ H)
    major = evecs[:, 1]
    yaw0 = np.arctan2(-major[1], major[0])        # rotation about Y taking +X to `major`
    rest = model.v_template
    height_scan = hi[1] - lo[1]

    # height ↔ first shape coefficient, from the model (linear in ν)
    def stature(nu):
        v = model.rest_vertices(nu)
        return v[:, 1].max() - v[:, 1].min()
    e0 = np.zeros(model.num_shape)
    e1 = e0.copy()
    e1[0] = 1.0
    h0, dh = stature(e0), stature(e1) - stature(e0)

    occ = None
    if occluders is not None and len(occluders) and not garment_only:
        occ = _validate.points("occluders", occluders) @ A.T
    fitter = _Fitter(model, P, F, o, garment_only, progress=None, occluders=occ, cancel=cancel)
    if garment_only:
        _garment_setup(fitter, model, P, hi[1], garment_class_of(garment_type) if garment_type else "upper")
    free_rigid = np.zeros(model.num_params, bool)
    sl = model.param_slices()
    free_rigid[sl["rotation"]] = True
    free_rigid[sl["translation"]] = True
    free_rigid[sl["shape"].start] = True

    idx_s = fitter.rng.choice(len(P), min(4000, len(P)), replace=False)
    idx_b = fitter.rng.choice(model.num_vertices, 2000, replace=False)

    anchor_point = _anchor_point(model, anchor) if garment_only else None

    def initial(yaw):
        p = model.zero_params()
        p.rotation[:] = _wrapped([0, yaw, 0])
        R = Rotation.from_rotvec(p.rotation).as_matrix()
        if not garment_only:
            p.shape[0] = np.clip((height_scan - h0) / dh, -o.shape_range, o.shape_range)
            body_c = np.array([0.0, 0.0, rest[:, 2].mean()])
            p.translation[:] = [centre[0], lo[1], centre[2]] - R @ body_c
        else:
            # the garment's top at the body's shoulders (tops, dresses) or waist (skirts,
            # trousers), centred horizontally
            a = anchor_point
            p.translation[:] = [centre[0], hi[1] - a[1], centre[2]] - R @ np.array([0, 0, a[2]])
        return p

    # twelve yaws 30° apart scored as placed, the three best refined rigidly (with stature)
    starts = [initial(yaw0 + k * np.pi / 6) for k in range(12)]
    scores = [fitter.energy(q, 0.1, idx_s, idx_b) for q in starts]
    order = list(np.argsort(scores)[:3])
    if garment_only:
        # a garment's front and back look alike (trousers above all): the best yaw's opposite
        # is always a candidate, and both go into the full fit (below)
        order.append(int(np.argsort(scores)[0] + 6) % 12)
    refined = []
    for k in dict.fromkeys(order):
        q, _ = fitter.run(starts[k], 10, np.geomspace(0.15, 0.03, 10), free=free_rigid, n_scan=1500, n_body=800)
        refined.append((fitter.energy(q, 0.03, idx_s, idx_b), k, q))
    refined.sort(key=lambda c: c[0])
    history: list = []
    # coarse to fine: the robust scale shrinks and the pose prior relaxes (a stiff skeleton
    # first, so that shape and global placement settle before distal joints are released)
    n_anneal = max(o.iterations - 8, 1)
    sig = np.geomspace(o.sigma[0], o.sigma[1], n_anneal)
    boosts = np.geomspace(o.pose_prior_boost, 1.0, n_anneal)
    n0 = 0
    p = refined[0][2]
    if garment_only:
        # multi-start: the best placement and the best one facing the other way are fitted for
        # the first iterations (shape and pose free) and scored by the robust energy there;
        # the lower one goes on (the knees' and hips' limits tell front from back)
        k0 = refined[0][1]
        other = [c for c in refined if abs((c[1] - k0 + 6) % 12 - 6) >= 3]
        if other and o.multi_start_iterations > 0:
            n0 = min(o.multi_start_iterations, o.iterations - 1)
            s0 = float(sig[min(n0, len(sig)) - 1])
            runs = []
            for c in (refined[0], other[0]):
                q, _ = fitter.run(c[2], n0, sig[:n0], boosts=boosts[:n0])
                runs.append((fitter.energy(q, s0, idx_s, idx_b), q))
            p = min(runs, key=lambda r: r[0])[1]
    n_main = o.iterations - n0
    n_contact = o.contact_iterations if fitter.contact_pass else 0
    if progress is not None:
        fitter.progress = lambda it, n, r: progress(it, n_main + n_contact, r)
    p, rms = fitter.run(p, n_main, sig[n0:] if n0 < len(sig) else sig[-1:], history=history,
                        boosts=boosts[n0:] if n0 < len(boosts) else boosts[-1:],
                        pen_last=0 if n_contact else o.self_penetration_iterations)
    if n_contact:
        # contact pass (module doc): where the garment touches the fitted body it attracts too
        touch = contact_points(model, p, P, o.clearance, o.contact_tolerance)
        fitter.attract = np.maximum(fitter.attract, touch.astype(np.float64))
        fitter.shape_prior = o.garment_shape_prior
        if progress is not None:
            fitter.progress = lambda it, n, r: progress(n_main + it, n_main + n_contact, r)
        p, rms = fitter.run(p, n_contact, sig[-1:], history=history, boosts=boosts[-1:],
                            pen_last=min(o.self_penetration_iterations, n_contact))
    return FitResult(params=p, to_core=A, history=history, rms=rms)


#: Bones whose lengths a garment of each class shows (freed in garment-only fits): the torso's
#: under tops and dresses. Trousers are not listed: freeing the legs' bones let them trade
#: length for shape and ended up inside the trouser legs.
GARMENT_BONES = {"upper": ("spine_1", "spine_2", "spine_3", "spine_4", "chest", "clavicle_left", "clavicle_right"),
                 "dress": ("spine_1", "spine_2", "spine_3", "spine_4", "chest", "clavicle_left", "clavicle_right"),
                 "skirt": (), "pants": ()}


def _garment_setup(fitter: _Fitter, model: BodyModel, P: np.ndarray, top: float, cls: str) -> None:
    """Garment-only specifics of class cls (module doc): the bones it shows are freed (models
    with the default skeleton); tops and dresses attract with their top band first, under a
    stronger shape prior, and get the contact pass; skirts attract with their top band only."""
    o = fitter.opts
    names = model.joint_names
    for n in GARMENT_BONES[cls]:
        if n in names:
            fitter.free[fitter.sl["bone_scales"].start + names.index(n)] = True
    if cls in ("upper", "dress"):
        fitter.attract = (P[:, 1] > top - o.top_band).astype(np.float64)
        fitter.shape_prior = o.top_shape_prior
        fitter.contact_pass = o.contact_iterations > 0
    elif cls == "skirt":
        fitter.attract = (P[:, 1] > top - o.skirt_band).astype(np.float64)
        fitter.shape_prior = o.skirt_shape_prior


def contact_points(model: BodyModel, params: BodyParams, points, clearance: float, tolerance: float) -> np.ndarray:
    """(N,) bool: the points (m) whose distance to the surface a garment can cover on the posed
    body is within tolerance of clearance (where a garment touches the body)."""
    X = model.pose(params)
    P = np.ascontiguousarray(_validate.points("points", points))
    _, _, cp = _core.closest_points_on_mesh(X, garment_faces(model), P)
    return np.abs(np.linalg.norm(P - cp, axis=1) - clearance) < tolerance


def inside_fraction(model: BodyModel, params: BodyParams, points) -> float:
    """Fraction of points (N,3, m) inside the posed body (signed by the closest face normal)."""
    X = model.pose(params)
    P = _validate.points("points", points)
    tri, _, cp = _core.closest_points_on_mesh(X, model.faces, P)
    n = _face_normals(X, model.faces[tri])
    return float(np.mean(np.einsum("ij,ij->i", P - cp, n) < 0))


_TORSO = ("pelvis", "spine_1", "spine_2", "spine_3", "spine_4", "chest", "clavicle_left", "clavicle_right")


def penetration_pairs(model: BodyModel) -> list:
    """(vertex indices, faces) pairs checked for self-penetration: forearm+hand vertices
    against the torso surface, lower-leg vertices against the other leg's surface. Empty for
    models without the default skeleton's joint names (e.g. user SMPL files)."""
    names = model.joint_names
    need = set(_TORSO) | {f"{j}_{s}" for j in ("elbow", "wrist", "hip", "knee", "ankle") for s in ("left", "right")}
    if not need <= set(names):
        return []
    dom = np.argmax(model.weights, axis=1)

    def verts(*joints):
        return np.flatnonzero(np.isin(dom, [names.index(j) for j in joints])).astype(np.int64)

    def faces(*joints):
        inside = np.zeros(model.num_vertices, bool)
        inside[verts(*joints)] = True
        return np.ascontiguousarray(model.faces[inside[model.faces].all(axis=1)])
    torso = faces(*_TORSO)
    return [(verts("elbow_left", "wrist_left"), torso), (verts("elbow_right", "wrist_right"), torso),
            (verts("knee_left", "ankle_left"), faces("hip_right", "knee_right", "ankle_right")),
            (verts("knee_right", "ankle_right"), faces("hip_left", "knee_left", "ankle_left"))]


def garment_faces(model: BodyModel) -> np.ndarray:
    """Faces of the body a garment can cover: all but the head's, hands' and feet's (faces with a
    vertex skinned mostly to the head, a wrist or an ankle). All faces for models without the
    default skeleton's joint names."""
    names = model.joint_names
    bare = ("head", "wrist_left", "wrist_right", "ankle_left", "ankle_right")
    if not set(bare) <= set(names):
        return np.ascontiguousarray(model.faces)
    out = np.isin(np.argmax(model.weights, axis=1), [names.index(n) for n in bare])
    return np.ascontiguousarray(model.faces[~out[model.faces].any(axis=1)])


def self_penetration_depth(model: BodyModel, params: BodyParams) -> float:
    """Deepest self-penetration (m) of the posed body over penetration_pairs (0 when none)."""
    X = model.pose(params)
    worst = 0.0
    for verts, faces in penetration_pairs(model):
        tri, _, cp = _core.closest_points_on_mesh(X, faces, np.ascontiguousarray(X[verts]))
        d = np.einsum("ij,ij->i", X[verts] - cp, _face_normals(X, faces[tri]))
        worst = max(worst, float(-d.min()) if d.min() < 0 else 0.0)
    return worst
