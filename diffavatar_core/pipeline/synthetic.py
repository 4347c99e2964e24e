"""Synthetic scans with known ground truth, for the recovery's tests, benchmark and demo sample
(issue 7 benchmark): a built-in template with perturbed measurements, a bending stiffness and a
body with random shape → drape → a scan-like labelled mesh (subdivided surface, normal noise,
small holes, floating fragments; cm, Y up by default). Everything in the ground truth is SI
(m, N·m, core frame: Y up, body faces +Z)."""
from __future__ import annotations

import json
import pathlib
from dataclasses import dataclass, field

import numpy as np

from ..body import BodyModel
from ..body.params import BodyParams
from ..pattern.garment import Garment
from ..pattern.templates import make_template
from ..sim.cloth import Cloth
from ..sim.material import ClothMaterial
from .options import RecoverOptions, sweeps_for_edge
from .refine import settle_carried, transfer_positions

# the measurements each template's ground truth perturbs (fields of Top/SkirtMeasurements)
PERTURBED = {"skirt": ("length", "hem_width"),
             "tshirt": ("length", "ease", "sleeve_length"),
             "longsleeve": ("length", "ease", "sleeve_length"),
             "dress": ("length", "ease", "hem_flare")}
_DEFAULTS = {"skirt": {"length": 0.55, "hem_width": 1.30},
             "tshirt": {"length": 0.70, "ease": 0.10, "sleeve_length": 0.22},
             "longsleeve": {"length": 0.70, "ease": 0.10, "sleeve_length": 0.58},
             "dress": {"length": None, "ease": 0.08, "hem_flare": 0.12}}
# label values of config/labels.yaml
GARMENT_LABEL = {"skirt": 3, "dress": 2, "tshirt": 1, "longsleeve": 1}
BODY_LABEL = 0


@dataclass
class SyntheticCase:
    """scan_vertices (N, 3) in `units` with `up` vertical; scan_faces (M, 3); scan_labels (N,)
    (0 = body, the garment's class value otherwise). Ground truth: garment (the perturbed
    template, draped positions in garment_x (V, 3) m), measurements (m), bend_stiffness (N·m),
    compliance_scale (the stretch compliances: the default material's × this), body_params /
    body_vertices (m)."""
    template: str
    scan_vertices: np.ndarray
    scan_faces: np.ndarray
    scan_labels: np.ndarray
    units: str
    up: str
    garment: Garment
    garment_x: np.ndarray
    measurements: dict
    bend_stiffness: float
    body_params: BodyParams
    body_vertices: np.ndarray
    body_faces: np.ndarray
    drape: dict = field(default_factory=dict)
    compliance_scale: float = 1.0

    def garment_scan(self) -> tuple[np.ndarray, np.ndarray]:
        """(vertices, faces) of the scan's garment-labelled part (a garment-only scan, in
        `units` with `up` vertical)."""
        from ..scan.cleaning import compact
        lab = self.scan_labels != BODY_LABEL
        V, F, _ = compact(self.scan_vertices, self.scan_faces, lab[self.scan_faces].all(axis=1))
        return V, F

    def truth_chamfer_cm(self, options: RecoverOptions | None = None, samples: int = 20000) -> float:
        """Chamfer distance (cm, the metric of chamfer_final_cm) from the truth's own drape to the
        scan's garment region as a recovery with `options` sees it (recovery.scan_for_recovery;
        default: RecoverOptions.from_config in the case's units and up axis). What the scan's
        making adds — resampling, normal noise, holes — and no recovery can take away: a
        recovery at this distance reproduces the truth's drape fold for fold. The benchmark's
        Chamfer ratio can go no lower than this over chamfer_initial_cm."""
        from ..metrics import chamfer_meshes
        from .recovery import scan_for_recovery
        opts = options or RecoverOptions.from_config(units=self.units, up=self.up)
        V, F = scan_for_recovery((self.scan_vertices, self.scan_faces, self.scan_labels), opts).garment_mesh()
        return 100.0 * chamfer_meshes(self.garment_x, self.garment.faces, V, F, samples=samples)

    def truth_json(self) -> dict:
        p = self.body_params
        return {"template": self.template, "measurements_m": self.measurements,
                "bend_stiffness_Nm": self.bend_stiffness, "compliance_scale": self.compliance_scale,
                "pattern_area_m2": self.garment.total_area(),
                "body": {"shape": p.shape.tolist(), "pose": p.pose.tolist(), "bone_scales": p.bone_scales.tolist(),
                         "rotation": p.rotation.tolist(), "translation": p.translation.tolist()},
                "drape": self.drape, "units": self.units, "up": self.up}


def perturbed_measurements(template: str, rng, lo: float = 0.05, hi: float = 0.15) -> dict:
    """Each perturbed measurement × (1 ± U[lo, hi]) with a random sign (issue 7: ±5–15%)."""
    out = {}
    for k in PERTURBED[template]:
        base = _DEFAULTS[template][k]
        if base is None:
            continue
        out[k] = float(base * (1 + rng.choice([-1, 1]) * rng.uniform(lo, hi)))
    return out


def random_body(model: BodyModel, rng, shape_sd: float = 0.5, num_shape: int = 4) -> BodyParams:
    """A body within the prior: the first `num_shape` shape coefficients ~ N(0, shape_sd²), rest pose."""
    p = model.zero_params()
    k = min(num_shape, model.num_shape)
    p.shape[:k] = np.clip(rng.normal(scale=shape_sd, size=k), -2, 2)
    return p


# How far (m) the top of a ground-truth garment may sink below its placement and still count as
# worn: a skirt or a shirt settles by a few cm (measured 1.8 cm on a skirt); one that slid off the
# hips to the floor drops by more than half a metre.
MAX_TOP_DROP = 0.15


# XPBD steps at most for a fine ground truth's settle (make_case's truth_edge); it is settled as
# the recovery settles its fine output (refine.settle_carried, the same sweeps, substeps and damping)
FINE_TRUTH_STEPS = 1500


def truth_material(bend_stiffness: float, compliance_scale: float = 1.0) -> ClothMaterial:
    """The ground truth's cloth: bend_stiffness (N·m), the default stretch compliances (m/N) ×
    compliance_scale."""
    d = ClothMaterial()
    return ClothMaterial(bend_stiffness=bend_stiffness, warp_compliance=d.warp_compliance * compliance_scale,
                         weft_compliance=d.weft_compliance * compliance_scale,
                         shear_compliance=d.shear_compliance * compliance_scale)


def _truth_cloth(g: Garment, x, body, bend_stiffness: float, compliance_scale: float,
                 contact_normals: str | None = None) -> Cloth:
    """contact_normals: the truth's contact plane (None: the recovery's default, so the truth is
    simulated as the output is)."""
    return Cloth(g.rest, g.faces, x, seams=g.seams, groups=g.panel[g.faces[:, 0]],
                 materials=[truth_material(bend_stiffness, compliance_scale)] * len(g.panels), body=body,
                 grain=g.face_grain(), contact_normals=contact_normals or RecoverOptions.contact_normals)


def drape_truth(g: Garment, body, bend_stiffness: float, max_steps: int = 600, cancel=None,
                compliance_scale: float = 1.0, contact_normals: str | None = None, sweeps: int = 40):
    """The ground-truth drape of garment g on body (V, F): (Cloth, DrapeResult); the default
    material's stretch compliances × compliance_scale; sweeps: XPBD sweeps per step (40 for the
    4 cm mesh, options.sweeps_for_edge for others, as the recovery's drapes). Raises RuntimeError
    when the garment did not stay on the body (its top sank more than MAX_TOP_DROP below where it
    was placed) or the drape did not converge."""
    cloth = _truth_cloth(g, g.x0, body, bend_stiffness, compliance_scale, contact_normals)
    cloth.sew(cancel=cancel)
    r = cloth.drape(max_steps=max_steps, iterations=sweeps, residual_tol=1e-7, refine_iterations=120, raise_on_divergence=False,
                    cancel=cancel)
    top0, top = float(np.max(g.x0[:, 1])), float(np.max(np.asarray(cloth.x)[:, 1]))
    if top < top0 - MAX_TOP_DROP:   # checked first: it also explains a drape that did not converge
        raise RuntimeError(f"the ground-truth garment slid off the body: its top fell from {top0:.2f} m to "
                           f"{top:.2f} m (more than {MAX_TOP_DROP} m)")
    if not r.converged:
        raise RuntimeError(f"the ground-truth drape did not converge: {r.message}")
    return cloth, r


def settle_fine_truth(g: Garment, x, fine: Garment, body, bend_stiffness: float, compliance_scale: float = 1.0,
                      cancel=None, friction: float | None = None, contact_normals: str | None = None):
    """The ground truth on a finer mesh `fine` of the same garment g (same template and
    measurements, another edge length): every fine vertex starts at g's drape x (V, 3) m of its
    pattern location, pushed out of the body, then XPBD until it stands still (Cloth.settle;
    Newton stalls on ~10k-vertex buckled cloth). Its folds are those a fine cloth forms, not the
    coarse mesh's. friction: Coulomb μ of the settle (None: the recovery's output_friction, so the
    truth is settled as the output is). Returns (Cloth, SettleResult); raises RuntimeError when it
    does not settle."""
    x0 = transfer_positions(g, x, fine)
    cloth = _truth_cloth(fine, x0, body, bend_stiffness, compliance_scale, contact_normals)
    mu = RecoverOptions.output_friction if friction is None else friction
    s = settle_carried(cloth, x0, body[0], body[1], FINE_TRUTH_STEPS, RecoverOptions.output_drape_sweeps,
                       cancel=cancel, friction=mu, substeps=RecoverOptions.output_drape_substeps,
                       damping=RecoverOptions.output_drape_damping)
    if not s.settled:
        raise RuntimeError(f"the fine ground-truth drape did not settle: {s.message}")
    return cloth, s


def _subdivide(V, F):
    """One 1→4 midpoint subdivision (the scan samples the surface at other points than the
    simulation mesh)."""
    E = np.sort(np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    uniq, inv = np.unique(E, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    mids = len(V) + inv.reshape(3, -1).T       # (F, 3): midpoints of edges 01, 12, 20
    V2 = np.vstack([V, 0.5 * (V[uniq[:, 0]] + V[uniq[:, 1]])])
    a, b, c = F.T
    m01, m12, m20 = mids.T
    F2 = np.vstack([np.column_stack([a, m01, m20]), np.column_stack([m01, b, m12]),
                    np.column_stack([m20, m12, c]), np.column_stack([m01, m12, m20])])
    return V2, F2


def _vertex_normals(V, F):
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    N = np.zeros_like(V)
    for k in range(3):
        np.add.at(N, F[:, k], n)
    return N / np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-12)


def weld(V, F, pairs):
    """Merges vertex pairs (sewn seams: one surface in a scan) into one vertex at their mean;
    returns (V', F') with unreferenced vertices dropped."""
    V, F = np.asarray(V, float), np.asarray(F, np.int64)
    parent = np.arange(len(V))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i
    for a, b in np.asarray(pairs, np.int64).reshape(-1, 2):
        ra, rb = find(a), find(b)
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    root = np.array([find(i) for i in range(len(V))])
    uniq, inv = np.unique(root, return_inverse=True)
    Vw = np.zeros((len(uniq), 3))
    np.add.at(Vw, inv, V)
    Vw /= np.bincount(inv)[:, None]
    Fw = inv[F]
    Fw = Fw[(Fw[:, 0] != Fw[:, 1]) & (Fw[:, 1] != Fw[:, 2]) & (Fw[:, 2] != Fw[:, 0])]
    return Vw, Fw


def scan_like(garment_x, garment_faces, body_vertices, body_faces, garment_label: int, rng,
              noise: float = 0.002, holes: int = 3, hole_radius: float = 0.012, fragments: int = 3,
              covered_distance: float = 0.025, seams=None):
    """A labelled scan-like mesh (m, core frame) of a draped garment and the visible body:
    body vertices closer than covered_distance to the garment are removed (hidden), the garment
    subdivided once (a scan samples other points than the simulation mesh), both surfaces displaced by N(0, noise²) along their normals, `holes` small
    holes punched into the garment away from its boundary, `fragments` floating triangles.
    seams: (S, 2) sewn vertex pairs of the garment, welded (a scan sees one surface)."""
    from ..metrics import surface_distances
    Vg, Fg = weld(garment_x, garment_faces, np.zeros((0, 2)) if seams is None else seams)
    Vg, Fg = _subdivide(Vg, Fg)
    Vb, Fb = np.asarray(body_vertices, float), np.asarray(body_faces, np.int64)
    hidden = surface_distances(Vb, np.asarray(garment_x, float), np.asarray(garment_faces, np.int32)) < covered_distance
    Fb = Fb[~hidden[Fb].any(axis=1)]
    used = np.unique(Fb)
    remap = -np.ones(len(Vb), np.int64)
    remap[used] = np.arange(len(used))
    Vb, Fb = Vb[used], remap[Fb]
    Vg = Vg + rng.normal(scale=noise, size=(len(Vg), 1)) * _vertex_normals(Vg, Fg)
    Vb = Vb + rng.normal(scale=noise, size=(len(Vb), 1)) * _vertex_normals(Vb, Fb)
    # holes: faces within hole_radius of interior centres (≥ 5 cm from the garment's boundary)
    E = np.sort(np.vstack([Fg[:, [0, 1]], Fg[:, [1, 2]], Fg[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(E, axis=0, return_counts=True)
    bverts = np.unique(uniq[counts == 1])
    centroids = Vg[Fg].mean(axis=1)
    from scipy.spatial import cKDTree
    far = cKDTree(Vg[bverts]).query(centroids)[0] > 0.05
    drop = np.zeros(len(Fg), bool)
    for c in rng.choice(np.flatnonzero(far), size=min(holes, int(far.sum())), replace=False):
        drop |= np.linalg.norm(centroids - centroids[c], axis=1) < hole_radius
    Fg = Fg[~drop]
    V = np.vstack([Vg, Vb])
    F = np.vstack([Fg, Fb + len(Vg)])
    L = np.concatenate([np.full(len(Vg), garment_label), np.full(len(Vb), BODY_LABEL)])
    # floating fragments: single small triangles 20–40 cm from the garment, garment-labelled
    lo, hi = V.min(axis=0), V.max(axis=0)
    for _ in range(fragments):
        c = np.array([rng.uniform(lo[0], hi[0]), rng.uniform(lo[1], hi[1]), hi[2] + rng.uniform(0.2, 0.4)])
        tri = c + rng.normal(scale=0.01, size=(3, 3))
        F = np.vstack([F, len(V) + np.arange(3)[None]])
        V = np.vstack([V, tri])
        L = np.concatenate([L, np.full(3, garment_label)])
    return V, F.astype(np.int64), L.astype(np.int64)


def to_scan_frame(V_core, units: str = "cm", up: str = "y") -> np.ndarray:
    """Core frame (m, Y up) → a scan frame in `units` with `up` vertical (ScanTransform's inverse)."""
    from ..scan.frame import ScanTransform
    return ScanTransform.from_options(units, up).to_scan(V_core)


def make_case(template: str = "skirt", seed: int = 0, bend_stiffness: float | None = None,
              measurements: dict | None = None, edge: float = 0.04, units: str = "cm", up: str = "y",
              noise: float = 0.002, holes: int = 3, fragments: int = 3, shape_sd: float = 0.5,
              max_steps: int = 600, model: BodyModel | None = None, truth_edge: float | None = None,
              compliance_scale: float = 1.0, friction: float | None = None,
              contact_normals: str | None = None) -> SyntheticCase:
    """One ground-truth case. Unless given: measurements perturbed ±5–15%, bend stiffness
    log-uniform in [1e-6, 1e-4] N·m, body shape random (rest pose), the default stretch
    compliances (× compliance_scale). The truth is draped on a mesh
    of `edge` (m); with truth_edge < edge it is then carried to a mesh of truth_edge and settled
    there (settle_fine_truth): the truth of a ~10k-vertex output (a 4 cm cloth folds as a 4 cm
    mesh can, and a 1 cm one does not hang the same way). contact_normals: the truth's contact
    plane (face | smooth; None: the recovery's default)."""
    if template not in PERTURBED:
        raise ValueError(f"template: synthetic cases exist for {sorted(PERTURBED)}, got {template!r}")
    if truth_edge is not None and not 0.005 <= truth_edge < edge:
        raise ValueError(f"truth_edge: expected a length in [0.005, edge = {edge}) m, got {truth_edge}")
    if not (np.isfinite(compliance_scale) and compliance_scale > 0):
        raise ValueError(f"compliance_scale: expected a positive factor, got {compliance_scale}")
    rng = np.random.default_rng(seed)
    model = model or BodyModel.default()
    meas = perturbed_measurements(template, rng) if measurements is None else dict(measurements)
    k = float(10 ** rng.uniform(-6, -4)) if bend_stiffness is None else float(bend_stiffness)
    params = random_body(model, rng, shape_sd)
    bv, bf = model.pose(params), np.asarray(model.faces)
    g = make_template(template, landmarks=model.landmarks(params), edge_length=edge, **meas)
    cloth, r = drape_truth(g, (bv, bf), k, max_steps, compliance_scale=compliance_scale,
                           contact_normals=contact_normals, sweeps=sweeps_for_edge(40, edge))
    x = np.array(cloth.x)
    drape = {"steps": r.steps, "residual": r.residual, "max_penetration_m": r.max_penetration}
    if truth_edge is not None:
        fine = make_template(template, landmarks=model.landmarks(params), edge_length=truth_edge, **meas)
        cloth, s = settle_fine_truth(g, x, fine, (bv, bf), k, compliance_scale, friction=friction,
                                     contact_normals=contact_normals)
        g, x = fine, np.array(cloth.x)
        drape = {"coarse": drape, "edge_m": truth_edge, "settle": s.to_json()}
    V, F, L = scan_like(x, g.faces, bv, bf, GARMENT_LABEL[template], rng, noise, holes,
                        fragments=fragments, seams=g.seams)
    return SyntheticCase(template, to_scan_frame(V, units, up), F, L, units, up, g, x, meas, k, params, bv, bf,
                         drape=drape, compliance_scale=float(compliance_scale))


def write_case(case: SyntheticCase, out_dir) -> pathlib.Path:
    """scan.ply (binary, float32 x y z + uchar label) and truth.json into out_dir; returns the PLY path."""
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "scan.ply"
    write_labelled_ply(path, case.scan_vertices, case.scan_faces, case.scan_labels)
    (out / "truth.json").write_text(json.dumps(case.truth_json(), indent=2))
    return path


def write_labelled_ply(path, V, F, labels) -> None:
    """Binary little-endian PLY: float x, y, z, uchar label per vertex; int triangle lists."""
    V = np.asarray(V, "<f4")
    F = np.asarray(F, "<i4")
    L = np.asarray(labels)
    if L.min() < 0 or L.max() > 255:
        raise ValueError("labels: must lie in [0, 255] for a uchar PLY property")
    head = (f"ply\nformat binary_little_endian 1.0\ncomment DiffAvatar synthetic scan\n"
            f"element vertex {len(V)}\nproperty float x\nproperty float y\nproperty float z\n"
            f"property uchar label\nelement face {len(F)}\nproperty list uchar int vertex_indices\nend_header\n")
    vert = np.zeros(len(V), dtype=[("p", "<f4", 3), ("l", "u1")])
    vert["p"], vert["l"] = V, L
    face = np.zeros(len(F), dtype=[("n", "u1"), ("i", "<i4", 3)])
    face["n"], face["i"] = 3, F
    with open(path, "wb") as fh:
        fh.write(head.encode())
        fh.write(vert.tobytes())
        fh.write(face.tobytes())
