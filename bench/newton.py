"""Benchmark: the Newton refinement's Hessian assembly (sim/newton_system.hpp) against the triplet
assembly it replaced (cloth_energy.cpp energy_hessian: Eigen triplets + setFromTriplets on every
iteration), side by side in this run, and what a Newton iteration of the recovery costs. Prints JSON.

Run: `.venv/bin/python bench/newton.py [--edges 0.04 0.02] [--repeats 20]`.

For each edge length (m) the t-shirt template is draped on the default body (XPBD + Newton), its
rest shape then scaled by 1.01 (a pattern step of the co-optimization) and:
  * assembly_ms: ∇²E at the draped state with its contacts and anchors, PSD-projected (what a
    Newton step far from equilibrium assembles) and exact, by the reference (`energy_hessian`)
    and by the cached in-place assembly (`newton_hessian`) — the same matrix bit for bit
    (checked here and in test/sim/test_newton_system.py); best of `--repeats`, interleaved so both
    see the same load. Both include the same copy of the matrix to Python.
  * factorize_ms: the LDLᵀ of that matrix by Eigen's SimplicialLDLT (the reference; the
    recovery's default) and by linalg/supernodal_ldlt.hpp (the drape command's), the same matrix,
    each analysed once, best of `--repeats` interleaved; with both solutions' residuals.
  * newton: the warm re-equilibration after the rest-shape step (Cloth.refine, anchors at the
    drape, κ = 1/s²): iterations, wall ms per iteration (gradient, assembly, LDLᵀ, line search);
    newton_supernodal: the same from a clone with `supernodal_newton` on, and how far apart the
    two equilibria are; newton_hinge_clamp: from a clone with `hinge_clamp` on — the projected
    Hessian's hinge blocks clamped to their non-negative eigenvalues, the Newton of stops 31–58
    (the reference; the default uses their Gauss–Newton parts, stop 59) — its iterations, wall
    and how far its equilibrium is from the default's; with the projected assembly's time both ways.
Times in ms on this machine; quote the ratios (2-core machines are noisy).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time

os.environ.setdefault("OMP_WAIT_POLICY", "passive")

import numpy as np  # noqa: E402

import diffavatar_core as dc  # noqa: E402
from diffavatar_core.sim.drape_job import build  # noqa: E402

G = np.array([0.0, -9.81, 0.0])


def ms(fn):
    t0 = time.perf_counter()
    fn()
    return 1e3 * (time.perf_counter() - t0)


def case(edge, repeats):
    cloth, _, _ = build("tshirt", edge=edge)
    r = cloth.drape(max_steps=400, residual_tol=1e-7, refine_iterations=120, raise_on_divergence=False)
    s = cloth.solver
    x = np.array(cloth.x)
    out = {"edge_m": edge, "vertices": int(cloth.model.num_vertices), "triangles": int(len(cloth.model.faces)),
           "hinges": int(len(cloth.model.hinges)), "drape_converged": bool(r.converged),
           "contacts": int(s.num_contacts)}
    for project in (True, False):
        A, B = s.energy_hessian(x, G, project), s.newton_hessian(x, G, project)
        same = bool(np.array_equal(A.indptr, B.indptr) and np.array_equal(A.indices, B.indices)
                    and np.array_equal(A.data, B.data))
        ref, ours = [], []
        for _ in range(repeats):   # interleaved: both see the same load
            ref.append(ms(lambda: s.energy_hessian(x, G, project)))
            ours.append(ms(lambda: s.newton_hessian(x, G, project)))
        key = "projected" if project else "exact"
        out[f"assembly_{key}"] = {"nonzeros": int(A.nnz), "identical": same, "reference_ms": min(ref),
                                  "ours_ms": min(ours), "speedup_vs_reference": min(ref) / min(ours)}
        # the step's LDLᵀ: Eigen's SimplicialLDLT (the reference; the recovery's default) against
        # the supernodal one (`supernodal_newton`, the drape command's default); the same ordering,
        # each analysed once. The right-hand side: the gradient's first n entries (any vector does)
        b = -np.asarray(s.energy_gradient(x, G)).reshape(-1)[:A.shape[0]]
        fact = {}
        for name in ("SimplicialLdlt", "SupernodalLdlt"):
            f = getattr(dc._core, name)()
            t0 = time.perf_counter()
            f.analyze_pattern(B)
            fact[name] = {"f": f, "analyze_ms": 1e3 * (time.perf_counter() - t0), "times": []}
        for _ in range(repeats):
            for name in fact:
                fact[name]["times"].append(ms(lambda: fact[name]["f"].factorize(B)))
        sol = {name: v["f"].solve(b) for name, v in fact.items()}
        ref_x, our_x = sol["SimplicialLdlt"], sol["SupernodalLdlt"]
        r, o = fact["SimplicialLdlt"], fact["SupernodalLdlt"]
        out[f"factorize_{key}"] = {
            "reference_ms": min(r["times"]), "ours_ms": min(o["times"]),
            "speedup_vs_reference": min(r["times"]) / min(o["times"]),
            "analyze_reference_ms": r["analyze_ms"], "analyze_ours_ms": o["analyze_ms"],
            "solution_relative_difference": float(np.linalg.norm(our_x - ref_x) / np.linalg.norm(ref_x)),
            "relative_residual_ours": float(np.linalg.norm(B @ our_x - b) / np.linalg.norm(b)),
            "relative_residual_reference": float(np.linalg.norm(B @ ref_x - b) / np.linalg.norm(b))}
    # the projected assembly with the hinge blocks clamped (the reference) against Gauss–Newton
    # (the same solver, its contacts and anchors, the switch flipped; interleaved)
    gn_ms, clamp_ms = [], []
    for _ in range(repeats):
        s.hinge_clamp = True
        clamp_ms.append(ms(lambda: s.newton_hessian(x, G, True)))
        s.hinge_clamp = False
        gn_ms.append(ms(lambda: s.newton_hessian(x, G, True)))
    out["assembly_projected_hinge_blocks"] = {"clamp_ms": min(clamp_ms), "gauss_newton_ms": min(gn_ms),
                                              "speedup_vs_clamp": min(clamp_ms) / min(gn_ms)}
    rest = np.asarray(cloth.control.rest)
    cloth.set_control(rest=rest * 1.01)
    twins = {"simplicial": cloth.clone(), "supernodal": cloth.clone(), "hinge_clamp": cloth.clone()}
    twins["supernodal"].solver.supernodal_newton = True   # the same state, contacts, BVH
    twins["hinge_clamp"].solver.hinge_clamp = True
    ends = {}
    for name, c in twins.items():   # one after the other, the reference first
        t0 = time.perf_counter()
        it, res = c.refine(keep_anchor=False, residual_tol=1e-7, refine_iterations=120, anchor_stiffness=1.0)
        wall = time.perf_counter() - t0
        ends[name] = np.array(c.x)
        out["newton" if name == "simplicial" else f"newton_{name}"] = {
            "iterations": int(it), "residual": float(res), "wall_ms": 1e3 * wall, "ms_per_iteration": 1e3 * wall / max(it, 1)}
    out["newton_supernodal"]["speedup_per_iteration_vs_simplicial"] = (
        out["newton"]["ms_per_iteration"] / out["newton_supernodal"]["ms_per_iteration"])
    out["newton_supernodal"]["max_position_difference_m"] = float(np.abs(ends["simplicial"] - ends["supernodal"]).max())
    ref = out["newton_hinge_clamp"]
    ref["default_speedup_vs_clamp"] = ref["wall_ms"] / out["newton"]["wall_ms"]
    ref["max_position_difference_m"] = float(np.abs(ends["simplicial"] - ends["hinge_clamp"]).max())
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--edges", type=float, nargs="+", default=[0.04, 0.02], help="template edge lengths (m)")
    ap.add_argument("--repeats", type=int, default=20)
    a = ap.parse_args(argv)
    out = {"benchmark": "newton_assembly_and_factorization", "date": time.strftime("%Y-%m-%d"),
           "machine": f"{platform.machine()}, {os.cpu_count()} logical cores", "threads": dc.num_threads(),
           "load_average_start": [round(v, 2) for v in os.getloadavg()],
           "cases": [case(e, a.repeats) for e in a.edges]}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
