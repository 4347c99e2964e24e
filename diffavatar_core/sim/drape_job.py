"""The drape job behind `diffavatar drape` and the demo: a garment sewn and draped on a body,
written as draped.obj, body.obj and drape.json (metres in the OBJ files).

Garments: the built-in templates (diffavatar_core.pattern.templates: tshirt, longsleeve, dress,
skirt) on the default body model (diffavatar_core.body, zero shape and pose), and
'mannequin-skirt', the project's two-panel skirt on its generated mannequin (fast; the demo's)."""
from __future__ import annotations

import json
import pathlib
import time

import numpy as np

from .. import _validate
from ..io import save_mesh
from .cloth import NEWTON_SOLVERS, Cloth
from .material import ClothMaterial
from .scenes import mannequin, two_panel_skirt

from ..pattern.templates import TEMPLATES

GARMENTS = tuple(TEMPLATES) + ("mannequin-skirt",)
# XPBD substeps per 1/120 s step of the drape (Cloth.drape): with one step of 100 sweeps the
# 2.5 cm pants' waistband stretched over the hips during the first fall and the pants slid to
# the floor; four steps of 25 sweeps (as many sweeps) hold them at the waist (docs/simulation.md).
SUBSTEPS = 4
# Sweep precision of the drape's XPBD phase: "single" is the vectorised float sweep
# (sim/fast_sweep.hpp, 6× faster on the 10k t-shirt with AVX-512); the Newton refinement is
# float64 either way.
SWEEPS = ("single", "double")
# Newton iterations of the drape's refinement (Cloth.drape's default: 200). The buckled 2.5 cm
# t-shirt converges only linearly for a while: over 14 drapes whose patterns differ by 1e-13 m of
# round-off (`pytest --roundoff-seed`) it took 59–206 iterations (63 unperturbed), then converges
# quadratically; at 200 one variant was reported not converged at residual 0.08.
REFINE_ITERATIONS = 400


def build(garment: str = "tshirt", material: ClothMaterial | None = None, edge: float = 0.025,
          contact_normals: str = "face"):
    """(Cloth, garment dict, body (V, F)) for `garment` (see GARMENTS) at target edge `edge` (m),
    with the contact plane `contact_normals` (Cloth). The garment dict has rest, faces, x0, seams,
    groups, boundaries (name → vertex chain)."""
    if garment not in GARMENTS:
        raise ValueError(f"garment: unknown {garment!r}; available: {', '.join(GARMENTS)}")
    mat = material or ClothMaterial()
    if garment == "mannequin-skirt":
        body = mannequin()
        g = two_panel_skirt(edge=edge)
    else:
        from ..body import BodyModel
        from ..pattern.templates import make_template
        model = BodyModel.default()
        params = model.zero_params()
        body = (model.pose(params), model.faces)
        t = make_template(garment, landmarks=model.landmarks(params), edge_length=edge)
        g = dict(rest=t.rest, faces=t.faces, x0=t.x0, seams=t.seams, groups=t.panel[t.faces[:, 0]],
                 boundaries=dict(t.boundaries), grain=t.face_grain())
    cloth = Cloth(g["rest"], g["faces"], g["x0"], seams=g["seams"], groups=g["groups"],
                  materials=[mat] * (int(g["groups"].max()) + 1), body=body, grain=g.get("grain"),
                  contact_normals=contact_normals)
    return cloth, g, body


def run(out: pathlib.Path, garment: str = "tshirt", max_steps: int = 1500, iterations: int = 100,
        refine: bool = True, edge: float = 0.025, progress=None, cancel=None, substeps: int = SUBSTEPS,
        sweeps: str = "single", newton_solver: str = "supernodal") -> dict:
    """Drapes and writes the files; returns the drape.json content."""
    return execute(out, garment, max_steps, iterations, refine, edge, progress, cancel, substeps, sweeps,
                   newton_solver=newton_solver)[0]


def execute(out: pathlib.Path, garment: str = "tshirt", max_steps: int = 1500, iterations: int = 100,
            refine: bool = True, edge: float = 0.025, progress=None, cancel=None, substeps: int = SUBSTEPS,
            sweeps: str = "single", contact_normals: str = "face", newton_solver: str = "supernodal"):
    """As run, also returning the draped Cloth, the garment dict and the body: (info, cloth, g, body).
    newton_solver: the Newton refinement's LDLᵀ, NEWTON_SOLVERS — supernodal by default: on the 1 cm
    t-shirt (30,408 DOFs) 3.2× the factorization speed of Eigen's simplicial one and the whole drape
    1.59× faster, the same 111 Newton iterations to the same equilibrium (BENCHMARKS.md stop 53)."""
    substeps = _validate.positive_int("substeps", substeps)   # before any work
    if sweeps not in SWEEPS:
        raise ValueError(f"sweeps: expected one of {', '.join(SWEEPS)}, got {sweeps!r}")
    if newton_solver not in NEWTON_SOLVERS:
        raise ValueError(f"newton_solver: expected one of {', '.join(NEWTON_SOLVERS)}, got {newton_solver!r}")
    t0 = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    cloth, g, (bv, bf) = build(garment, edge=edge, contact_normals=contact_normals)
    cloth.solver.supernodal_newton = newton_solver == "supernodal"
    sew_steps = cloth.sew(cancel=cancel)
    r = cloth.drape(max_steps=max_steps, iterations=iterations, refine=refine, refine_iterations=REFINE_ITERATIONS,
                    progress=progress, cancel=cancel, raise_on_divergence=False, substeps=substeps, fast=sweeps == "single")
    x = np.array(cloth.x)
    gap = float(np.linalg.norm(x[g["seams"][:, 0]] - x[g["seams"][:, 1]], axis=1).max())
    save_mesh(out / "draped.obj", x, g["faces"])
    save_mesh(out / "body.obj", bv, bf)
    info = {
        "garment": garment, "vertices": int(len(x)), "triangles": int(len(g["faces"])),
        "body_triangles": int(len(bf)), "sew_steps": sew_steps, "steps": r.steps, "substeps": substeps, "sweeps": sweeps,
        "newton_solver": newton_solver,
        "settled": r.settled,
        "converged": r.converged, "diverged": r.diverged, "residual": r.residual,
        "refine_iterations": r.refine_iterations, "max_penetration_mm": 1e3 * r.max_penetration,
        "max_seam_gap_mm": 1e3 * gap, "wall_s": time.perf_counter() - t0, "message": r.message,
    }
    (out / "drape.json").write_text(json.dumps(info, indent=2))
    return info, cloth, g, (bv, bf)
