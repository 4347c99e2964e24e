"""Whether the folds' curvature tells the bending apart where the Chamfer distance cannot (issue
7's ±0.15-decade bending target). A drape's fold *positions* follow the triangulation it hangs on
(a recovery's template mesh is not the truth's), so φ cannot rank bendings within about a decade
on soft fabrics (BENCHMARKS.md stops 39, 50, 51); the *amount* of folding may not depend on it.

For each benchmark case (bench/_case_grid.py): the truth's outline on the template's 4 cm mesh
with the true body (bench/recover_floor.py's truth_outline_case: every parameter exact but the mesh),
draped fresh at the true bending × 10^d, and the truth itself. Each surface's fold curvature
S (1/m) at radius r: quadrics h(u, v) fitted by least squares to 60,000 area-sampled surface
points within r of each of 3,000 other sampled centres (local frame by PCA), S = the mean over
centres of ‖∇²h‖_F = sqrt(4a² + 2b² + 4c²) (the second fundamental form's norm, ≈ sqrt(κ₁² + κ₂²)).
The scan is measured as it is; a drape either as it is (`raw`) or as the scan was made from it
(`scanlike`: synthetic.scan_like without holes or fragments — seams welded, subdivided once,
N(0, σ²) normal noise, σ = the case's 2 mm —, the mean over --noise-seeds seeds) so that the scan's noise
does not read as folds. Per case: S of the scan, of the truth, of each offset's drape, and the
offsets d at which S(d) − S(scan) changes sign (linear interpolation between neighbours: the
bendings this statistic would pick). Not a test; prints JSON.

Run: `.venv/bin/python bench/fold_curvature.py [--templates tshirt] [--cases 3] [--radii 0.03,0.05]`."""
import time

import numpy as np
from scipy.spatial import cKDTree

from _case_grid import run_grid
from recover_floor import truth_outline_case
from diffavatar_core.pipeline.synthetic import scan_like
from diffavatar_core.sim.cloth import Cloth
from diffavatar_core.sim.material import ClothMaterial

OFFSETS = (-1.0, -0.5, -0.15, 0.0, 0.15, 0.5, 1.0)   # decades
NOISE = 0.002   # m: make_case's scan noise


def surface_samples(V, F, n: int, seed: int) -> np.ndarray:
    """(n, 3) points uniform by area on the triangle mesh (V m, F)."""
    V, F = np.asarray(V, float), np.asarray(F, np.int64)
    area = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
    rng = np.random.default_rng(seed)
    f = rng.choice(len(F), n, p=area / area.sum())
    u, v = rng.random(n), rng.random(n)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    return V[F[f, 0]] * (1 - u - v)[:, None] + V[F[f, 1]] * u[:, None] + V[F[f, 2]] * v[:, None]


def fold_curvature(V, F, radii) -> dict:
    """{r: S} (1/m) for each radius r (m): the module docstring's statistic."""
    P, C = surface_samples(V, F, 60000, 1), surface_samples(V, F, 3000, 2)
    tree = cKDTree(P)
    out = {}
    for r in radii:
        norms = []
        for c, idx in zip(C, tree.query_ball_point(C, r)):
            if len(idx) < 12:
                continue
            Q = P[idx] - c
            Q = Q - Q.mean(axis=0)
            _, E = np.linalg.eigh(Q.T @ Q)   # ascending: E[:, 0] the normal
            h, v, u = (Q @ E).T
            A = np.stack([u * u, u * v, v * v, u, v, np.ones_like(u)], axis=1)
            a, b, cc = np.linalg.lstsq(A, h, rcond=None)[0][:3]
            norms.append(np.sqrt(4 * a * a + 2 * b * b + 4 * cc * cc))
        out[f"{r:g}"] = float(np.mean(norms))
    return out


def scanlike_curvature(x, garment, body, radii, seeds: int) -> dict:
    """fold_curvature of the drape x (V, 3) m of `garment` on `body` (vertices, faces) as the scan
    was made from its truth (synthetic.scan_like, without holes or fragments: seams welded,
    subdivided once, N(0, NOISE²) along the normals); the mean over `seeds` noise seeds."""
    per = []
    for s in range(seeds):
        V, F, L = scan_like(x, garment.faces, *body, 1, np.random.default_rng(100 + s), noise=NOISE, holes=0,
                            fragments=0, seams=garment.seams)
        n = int((L == 1).sum())   # the garment's vertices come first, then the body's
        per.append(fold_curvature(V[:n], F[(F < n).all(axis=1)], radii))
    return {r: float(np.mean([p[r] for p in per])) for r in per[0]}


def crossings(values: dict, target: float) -> list:
    """The offsets d (decades) where the piecewise-linear S(d) through `values` {d: S or None}
    equals `target`."""
    pts = sorted((d, s) for d, s in values.items() if s is not None)
    out = []
    for (d0, s0), (d1, s1) in zip(pts, pts[1:]):
        f0, f1 = s0 - target, s1 - target
        if f0 == 0.0:
            out.append(d0)
        elif f0 * f1 < 0.0:
            out.append(d0 + (d1 - d0) * f0 / (f0 - f1))
    if pts and pts[-1][1] == target:
        out.append(pts[-1][0])
    return [round(d, 3) for d in out]


def case_row(template: str, seed: int, bend: float, args) -> dict:
    t0 = time.perf_counter()
    case, g, rest_truth, (Vs, Fs) = truth_outline_case(template, seed, bend)
    radii, body = args.radii, (case.body_vertices, case.body_faces)
    row = {"template": template, "seed": seed, "bend_stiffness_Nm": bend, "scan": fold_curvature(Vs, Fs, radii),
           "truth": {"raw": fold_curvature(case.garment_x, case.garment.faces, radii),
                     "scanlike": scanlike_curvature(case.garment_x, case.garment, body, radii, args.noise_seeds)},
           "outline": {"raw": {}, "scanlike": {}}}
    for d in OFFSETS:
        c = Cloth(g.rest, g.faces, g.x0, seams=g.seams, groups=g.panel[g.faces[:, 0]],
                  materials=[ClothMaterial(bend_stiffness=bend * 10 ** d)] * len(g.panels),
                  body=body, grain=g.face_grain())
        c.set_control(rest=rest_truth)
        c.sew()
        r = c.drape(max_steps=200, iterations=40, residual_tol=1e-7, refine_iterations=120, raise_on_divergence=False)
        ok = bool(r.converged)
        row["outline"]["raw"][f"{d:g}"] = fold_curvature(np.asarray(c.x), g.faces, radii) if ok else None
        row["outline"]["scanlike"][f"{d:g}"] = (scanlike_curvature(np.asarray(c.x), g, body, radii, args.noise_seeds)
                                                if ok else None)
    row["crossings_decades"] = {
        kind: {rad: crossings({float(d): (s[rad] if s else None) for d, s in row["outline"][kind].items()},
                              row["scan"][rad]) for rad in row["scan"]}
        for kind in ("raw", "scanlike")}
    row["wall_s"] = time.perf_counter() - t0
    return row


def _arguments(ap):
    ap.add_argument("--radii", type=lambda t: [float(v) for v in t.split(",") if v], default=[0.03, 0.05],
                    help="fit radii, m (default 0.03,0.05)")
    ap.add_argument("--noise-seeds", type=int, default=3, help="noise draws per scan-like drape (default 3)")


def main():
    run_grid("fold_curvature", case_row, lambda a: {"offsets_decades": OFFSETS, "radii_m": a.radii,
                                                     "noise_m": NOISE, "noise_seeds": a.noise_seeds},
             add_arguments=_arguments)


if __name__ == "__main__":
    main()
