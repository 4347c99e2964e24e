"""Benchmark (issue 3): XPBD throughput of the C++ core on a garment of >= 10k vertices draped on
the default body, side by side in the same run with Newton's XPBD solver (PyPI `newton`, on
Warp's CPU device) on the same mesh at the same iteration count. Prints JSON.

Run: `.venv/bin/python bench/simulate.py [--quick] [--threads N]` (`make bench` installs Newton
from bench/requirements.txt first; without it the JSON says `reference: null` and why).

What is timed, for both solvers, from the same start (the template's initial placement around
the body, contacts active) with dt = 1/120 s and `--iterations` projection sweeps per step:
  * ms_per_step: one full step (prediction, contact detection against the body, the sweeps,
    velocity update); best of `--repeats`, the two solvers interleaved so that both see the
    same machine load;
  * ms_per_iteration = ms_per_step / iterations (per-step overhead spread over the sweeps);
  * ours with the drape's sweep (single precision, vectorised: sim/fast_sweep.hpp; the headline
    ms_per_* and speedup_vs_reference) and with the float64 sweep the trajectory adjoint replays
    (double_*), both on the lane plan, and the float64 colour plan (colour_plan_*);
  * ours also `sweep_ms`: one constraint-projection sweep alone (XpbdSolver.sweep: every
    triangle, hinge, seam and active contact once), the issue's unit of work.
Newton has no triangle (FEM) constraint in its XPBD solver: the reference uses one distance
spring per mesh edge (rest length from the sewing pattern), zero-length springs for the seams,
its dihedral bending on the same interior edges (rest angle 0) and the body as a static
triangle-mesh shape (particle radius = our collision thickness). Its particle-particle
(self-)contacts are switched off because our solver has none. Warp compiles its kernels on the
first launch (cached in ~/.cache/warp); that warm-up is excluded from the timing and reported.
Then the garment is draped with the production drape (XPBD until settled + Newton refinement)
within a step budget, for converged / max_penetration_mm.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
import traceback

# Under oversubscription (a shared 2-core machine) OpenMP's default spin-waiting at every colour
# barrier costs far more than the work; the passive policy must be set before the runtime starts.
os.environ.setdefault("OMP_WAIT_POLICY", "passive")

import numpy as np  # noqa: E402

import diffavatar_core as dc  # noqa: E402
from diffavatar_core.sim.cloth import _sim_params  # noqa: E402
from diffavatar_core.sim.drape_job import SUBSTEPS, build  # noqa: E402

DT = 1.0 / 120.0


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="small garment (edge 0.025 m, ~1.7k vertices), fewer steps")
    ap.add_argument("--threads", type=int, default=None, help="OpenMP threads of the core (default: all)")
    ap.add_argument("--garment", default="tshirt")
    ap.add_argument("--edge", type=float, default=None, help="target edge length in m (default 0.01, quick 0.025)")
    ap.add_argument("--iterations", type=int, default=100, help="projection sweeps per step, both solvers")
    ap.add_argument("--steps", type=int, default=None, help="timed steps per repeat (default 2)")
    ap.add_argument("--repeats", type=int, default=None, help="timing repeats, best kept (default 3)")
    ap.add_argument("--drape-steps", type=int, default=None, help="step budget of the drape (default 1500 as diffavatar drape; 0 skips the drape)")
    ap.add_argument("--drape-iterations", type=int, default=100, help="sweeps per step in the drape (default 100 as diffavatar drape)")
    ap.add_argument("--no-reference", action="store_true", help="skip Newton")
    a = ap.parse_args(argv)
    a.edge = a.edge or (0.025 if a.quick else 0.01)
    a.steps = a.steps or 2
    a.repeats = a.repeats or 3
    a.drape_steps = 1500 if a.drape_steps is None else a.drape_steps
    return a


def timed(fn):
    """(wall s, process CPU s) of fn()."""
    c0, t0 = time.process_time(), time.perf_counter()
    fn()
    return time.perf_counter() - t0, time.process_time() - c0


class Ours:
    def __init__(self, cloth, garment, iterations):
        self.cloth, self.g = cloth, garment
        self.p = _sim_params(DT, iterations, (0, -9.81, 0), 4.0, 0.01, 50.0)
        self.reset()

    def reset(self):
        self.state = self.cloth.solver.make_state(self.g["x0"])

    def steps(self, n, fast=False):
        self.p.fast = fast
        self.cloth.solver.step(self.state, self.p, n)

    def sweeps(self, n):
        self.cloth.solver.sweep(self.state, DT, n)

    def plan(self, lanes):
        self.cloth.set_sweep_plan(lanes=lanes)

    @property
    def x(self):
        return np.array(self.state.x)


class NewtonReference:
    """The same garment in Newton's SolverXPBD on Warp's CPU device (float32)."""

    def __init__(self, cloth, garment, body, iterations, spring_ke, seam_ke, bend_ke):
        import warp as wp
        wp.config.quiet = True  # before Warp initialises: it prints to stdout, which carries our JSON
        import newton
        self.wp, self.newton = wp, newton
        x0, F, rest, S = garment["x0"], garment["faces"], garment["rest"], garment["seams"]
        self.x0 = x0
        b = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=(0.0, -9.81, 0.0))
        b.add_cloth_mesh(pos=wp.vec3(0.0, 0.0, 0.0), rot=wp.quat_identity(), scale=1.0, vel=wp.vec3(0.0, 0.0, 0.0),
                         vertices=np.asarray(x0, np.float32), indices=F.ravel().tolist(), density=0.15,
                         edge_ke=bend_ke, edge_kd=0.0, add_springs=True, spring_ke=spring_ke, spring_kd=0.0,
                         particle_radius=float(cloth.model.thickness))
        n_edge_springs = len(b.spring_rest_length)
        for i, j in S:
            b.add_spring(int(i), int(j), seam_ke, 0.0, 0.0)
        b.add_shape_mesh(-1, mesh=newton.Mesh(np.asarray(body[0], np.float32), np.asarray(body[1], np.int32).ravel()))
        m = b.finalize(device="cpu")
        # Same rest state as ours: spring rest lengths from the 2D pattern, seams of length 0,
        # flat hinges, and our lumped masses (pinned vertices none here).
        si = m.spring_indices.numpy().reshape(-1, 2)
        L = np.linalg.norm(rest[si[:, 0]] - rest[si[:, 1]], axis=1)
        L[n_edge_springs:] = 0.0
        m.spring_rest_length.assign(L.astype(np.float32))
        m.edge_rest_angle.zero_()
        im = np.asarray(cloth.model.inv_mass)
        m.particle_inv_mass.assign(im.astype(np.float32))
        m.particle_mass.assign(np.where(im > 0, 1.0 / np.maximum(im, 1e-300), 0.0).astype(np.float32))
        m.particle_max_radius, m.particle_grid = 0.0, None  # no particle self-contact (ours has none)
        self.model = m
        self.counts = dict(springs=int(m.spring_count), seam_springs=int(len(S)), bending_edges=int(m.edge_count),
                           particles=int(m.particle_count), shapes=int(m.shape_count))
        self.solver = newton.solvers.SolverXPBD(m, iterations=iterations)
        self.pipe = newton.CollisionPipeline(m, soft_contact_gap=0.01)  # = our contact_radius
        self.contacts = self.pipe.contacts()
        self.control = m.control()
        self.reset()

    def reset(self):
        self.s0, self.s1 = self.model.state(), self.model.state()

    def steps(self, n):
        for _ in range(n):
            self.s0.clear_forces()
            self.pipe.collide(self.s0, self.contacts)
            self.solver.step(self.s0, self.s1, self.control, self.contacts, DT)
            self.s0, self.s1 = self.s1, self.s0
        self.wp.synchronize()

    @property
    def x(self):
        return self.s0.particle_q.numpy().astype(np.float64)

    @property
    def num_contacts(self):
        return int(self.contacts.soft_contact_count.numpy()[0])


def summary(x, x0, solver):
    finite = bool(np.all(np.isfinite(x)))
    moved = float(np.abs(x - x0).max()) if finite else np.inf
    return dict(diverged=bool(moved > 1.0), finite=finite, max_displacement_m=float(np.abs(x - x0).max()) if finite else None,
                max_penetration_mm=1e3 * solver.max_penetration(x) if finite else None)


def main(argv=None):
    a = parse_args(argv)
    # Warp prints its start-up banner and module loads on stdout (also from native code): send
    # fd 1 to stderr for the whole run and write the JSON to the original stdout at the end.
    sys.stdout.flush()
    json_out = os.fdopen(os.dup(1), "w")
    os.dup2(2, 1)
    if a.threads:
        dc.set_num_threads(a.threads)
    threads = dc.num_threads()
    out = {"benchmark": "xpbd_drape_throughput", "date": time.strftime("%Y-%m-%d"),
           "machine": f"{platform.machine()}, {os.cpu_count()} logical cores",
           "load_average_start": [round(v, 2) for v in os.getloadavg()],
           "omp_wait_policy": os.environ.get("OMP_WAIT_POLICY"), "quick": a.quick}
    t0 = time.perf_counter()
    cloth, g, body = build(a.garment, edge=a.edge)
    ours = Ours(cloth, g, a.iterations)
    m = cloth.model
    out.update(garment=a.garment, edge_m=a.edge, vertices=int(m.num_vertices), triangles=int(len(m.faces)),
               hinges=int(len(m.hinges)), seams=int(len(m.seams)), body_vertices=int(len(body[0])),
               body_triangles=int(len(body[1])), threads=threads, iterations=a.iterations, dt_s=DT,
               timed_steps=a.steps, repeats=a.repeats, build_s=time.perf_counter() - t0)

    ref, ref_err = None, None
    if not a.no_reference:
        try:
            mat = cloth.materials[0]
            # Stiffness ladder: the fabric's own stiffness (springs 1/α_warp N/m, seams 1/α_seam), then
            # springs of c·m̄/dt² for decreasing c; the first that stays finite, near the body and in
            # contact after PROBE_STEPS steps is timed. Every probe is reported.
            m_mean = float(np.mean(np.asarray(m.mass)))
            ladder = [("fabric", 1.0 / mat.warp_compliance, 1.0 / float(m.seam_compliance))]
            ladder += [(f"{c:g}*mean_mass/dt^2", c * m_mean / DT**2, c * m_mean / DT**2) for c in LADDER_C]
            probes, warmup_s = [], None
            for label, ke, seam_ke in ladder:
                ref = NewtonReference(cloth, g, body, a.iterations, ke, seam_ke, mat.bend_stiffness)
                tw = time.perf_counter()
                ref.steps(1)  # the first launch compiles (or loads) Warp's kernels
                if warmup_s is None:
                    warmup_s = time.perf_counter() - tw
                ref.steps(PROBE_STEPS - 1)
                st = summary(ref.x, g["x0"], cloth.solver)
                st.update(stiffness=label, spring_ke_N_per_m=ke, seam_ke_N_per_m=seam_ke, contacts=ref.num_contacts)
                probes.append(st)
                if not st["diverged"] and st["contacts"] > 0:
                    ref.ke = (label, ke, seam_ke)
                    break
                ref = None
            if ref is None:
                raise RuntimeError("Newton's XPBD diverged at every stiffness of the ladder: " + json.dumps(probes))
            ref.steps(1)
            ref.reset()
        except Exception as e:  # noqa: BLE001 - reported in the JSON, never faked
            ref, ref_err = None, f"{type(e).__name__}: {e}"
            traceback.print_exc()

    # Interleaved timing: ours (steps, then sweeps alone), Newton (steps), repeated.
    ours.steps(1)  # warm (allocations, first contact detection)
    ours.reset()
    # Ours twice: with the default sweep plan (lane-parallel on this model) and with the colour
    # plan (one parallel pass per colour, the plan of stop 15 and of small models).
    res = {"ours_step": [], "ours_step_cpu": [], "ours_sweep": [], "ours_sweep_cpu": [], "ref_step": [], "ref_step_cpu": [],
           "colour_step": [], "colour_step_cpu": [], "fast_step": [], "fast_step_cpu": []}
    plan = dict(cloth.sweep_plan)
    for _ in range(a.repeats):
        ours.plan(1)
        ours.reset()
        w, c = timed(lambda: ours.steps(a.steps))
        res["colour_step"].append(w / a.steps)
        res["colour_step_cpu"].append(c / a.steps)
        ours.plan(plan["lanes"])
        ours.reset()
        w, c = timed(lambda: ours.steps(a.steps))
        res["ours_step"].append(w / a.steps)
        res["ours_step_cpu"].append(c / a.steps)
        w, c = timed(lambda: ours.sweeps(a.iterations))
        res["ours_sweep"].append(w / a.iterations)
        res["ours_sweep_cpu"].append(c / a.iterations)
        ours.reset()   # the drape's sweep: single precision, vectorised (sim/fast_sweep.hpp), same plan
        w, c = timed(lambda: ours.steps(a.steps, fast=True))
        res["fast_step"].append(w / a.steps)
        res["fast_step_cpu"].append(c / a.steps)
        if ref is not None:
            ref.reset()
            w, c = timed(lambda: ref.steps(a.steps))
            res["ref_step"].append(w / a.steps)
            res["ref_step_cpu"].append(c / a.steps)
    ours.reset()
    ours.steps(a.steps)
    ours_state = summary(ours.x, g["x0"], cloth.solver)
    ours.reset()
    ours.steps(a.steps, fast=True)
    fast_state = summary(ours.x, g["x0"], cloth.solver)
    # Headline figures: the drape's sweep (single precision since 2026-11-25); the double one
    # (what the trajectory adjoint replays) as double_*.
    ms_step = 1e3 * min(res["fast_step"])
    ms_double = 1e3 * min(res["ours_step"])
    out.update(ms_per_step=ms_step, ms_per_iteration=ms_step / a.iterations, steps_per_s=1e3 / ms_step,
               cpu_ms_per_iteration=1e3 * min(res["fast_step_cpu"]) / a.iterations, sweep_precision="single",
               double_ms_per_step=ms_double, double_ms_per_iteration=ms_double / a.iterations,
               double_cpu_ms_per_iteration=1e3 * min(res["ours_step_cpu"]) / a.iterations,
               single_speedup_vs_double=ms_double / ms_step, state_after_timed_steps_single=fast_state,
               sweep_ms=1e3 * min(res["ours_sweep"]),
               contacts_after_timed_steps=int(cloth.solver.num_contacts), sweep_plan=plan,
               colour_plan_ms_per_step=1e3 * min(res["colour_step"]),
               colour_plan_ms_per_iteration=1e3 * min(res["colour_step"]) / a.iterations,
               lane_plan_speedup_vs_colour_plan=min(res["colour_step"]) / min(res["ours_step"]),
               state_after_timed_steps=ours_state)

    if ref is not None:
        ref.reset()
        ref.steps(a.steps)
        ref_ms = 1e3 * min(res["ref_step"])
        out.update(
            reference=(f"newton {_version('newton')} SolverXPBD (warp-lang {_version('warp-lang')}, device cpu, float32), "
                       "same mesh: one spring per edge + zero-length seam springs + dihedral bending + body as a "
                       "static mesh shape; no triangle FEM constraint in Newton's XPBD"),
            reference_threads=1,
            reference_ms_per_step=ref_ms, reference_ms_per_iteration=ref_ms / a.iterations,
            reference_steps_per_s=1e3 / ref_ms,
            reference_cpu_ms_per_iteration=1e3 * min(res["ref_step_cpu"]) / a.iterations,
            speedup_vs_reference=ref_ms / ms_step,
            speedup_vs_reference_cpu_time=min(res["ref_step_cpu"]) / min(res["fast_step_cpu"]),
            double_speedup_vs_reference=ref_ms / ms_double,
            double_speedup_vs_reference_cpu_time=min(res["ref_step_cpu"]) / min(res["ours_step_cpu"]),
            colour_plan_speedup_vs_reference=ref_ms / (1e3 * min(res["colour_step"])),
            reference_warmup_s=warmup_s, reference_counts=ref.counts,
            reference_contacts_after_timed_steps=ref.num_contacts,
            reference_state_after_timed_steps=summary(ref.x, g["x0"], cloth.solver),
            reference_stiffness={"label": ref.ke[0], "spring_ke_N_per_m": ref.ke[1], "seam_ke_N_per_m": ref.ke[2],
                                 "bend_ke_Nm": cloth.materials[0].bend_stiffness},
            reference_stiffness_probes=probes,
            reference_notes=(
                "Newton's XPBD sums the particle corrections of all constraints (Jacobi, no relaxation): with the "
                "garment's vertex masses (~1e-5 kg) it diverges at the fabric's own stiffness (springs 1/warp_compliance "
                "N/m, seams 1/seam_compliance; see reference_stiffness_probes), so the timed reference uses the stiffest "
                f"springs of a ladder c*mean_mass/dt^2 (c in {LADDER_C}) that stay finite, on the body and in contact "
                f"after {PROBE_STEPS} steps (reference_stiffness): far softer than the fabric. The cost per iteration does not "
                "depend on the stiffness. Warp launches CPU kernels on one thread; its first launch (kernel compile "
                "or cache load, reference_warmup_s) is excluded. Our solver is Gauss-Seidel over coloured constraints "
                "(orthotropic StVK triangles), so an iteration of ours does more per element; the headline figures "
                "are its single-precision vectorised sweep (the drape's), double_* its float64 sweep."),
        )
    else:
        out.update(reference=None, reference_ms_per_iteration=None, speedup_vs_reference=None,
                   reference_error=ref_err or "skipped (--no-reference)")
        if ref_err and "No module named" in ref_err:
            out["reference_error"] += " (install bench/requirements.txt: scripts/bench.sh does)"

    # The drape itself: XPBD until settled, then Newton refinement to equilibrium, within a budget.
    if a.drape_steps <= 0:
        out.update(converged=None, max_penetration_mm=None, drape="skipped (--drape-steps 0)")
        return _emit(out, t0, json_out)
    cloth.reset(g["x0"])
    sew_steps = cloth.sew()  # as `diffavatar drape` does: close the seams before draping
    r = cloth.drape(max_steps=a.drape_steps, iterations=a.drape_iterations, raise_on_divergence=False,
                    substeps=SUBSTEPS, fast=True)
    x = np.array(cloth.x)
    gap = float(np.linalg.norm(x[g["seams"][:, 0]] - x[g["seams"][:, 1]], axis=1).max())
    out.update(converged=bool(r.converged), max_penetration_mm=1e3 * r.max_penetration,
               drape={"sew_steps": sew_steps, "steps": r.steps, "step_budget": a.drape_steps, "iterations_per_step": a.drape_iterations,
                      "substeps": SUBSTEPS, "sweeps": "single",
                      "settled": r.settled, "converged": r.converged, "diverged": r.diverged, "residual": r.residual,
                      "refine_iterations": r.refine_iterations, "max_seam_gap_mm": 1e3 * gap, "wall_s": r.wall_s,
                      "message": r.message})
    _emit(out, t0, json_out)


def _emit(out, t0, json_out):
    out["load_average_end"] = [round(v, 2) for v in os.getloadavg()]
    out["total_s"] = time.perf_counter() - t0
    sys.stdout.flush()
    json_out.write(json.dumps(out, indent=2) + "\n")
    json_out.flush()


LADDER_C = (0.3, 0.1, 0.03, 0.01)  # see reference_notes
PROBE_STEPS = 3


def _version(name):
    from importlib.metadata import version
    try:
        return version(name)
    except Exception:  # noqa: BLE001
        return "?"


if __name__ == "__main__":
    main()
