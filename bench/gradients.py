"""Benchmark (issue 4): cost of the two adjoints on the >= 10k-vertex garment of bench/simulate.py
relative to the forward computation they differentiate, the trajectory adjoint's memory with
and without checkpointing, and finite-difference checks of every parameter kind on a small mesh
computed here by central differences. Prints JSON.

Run: `.venv/bin/python bench/gradients.py [--quick] [--threads N]`.

Definitions (also written into the JSON under "definitions"):
  forward_s               wall time of the forward drape: cloth.drape() on the garment from its
                          initial placement (XPBD steps of dt = 1/120 s with --iterations sweeps
                          until settled or --drape-steps, then Newton refinement to equilibrium).
  equilibrium_adjoint_s   equilibrium_gradient() at the draped state (one sparse LDLT solve).
  forward_step_s          one XPBD step without tape (XpbdSolver.step): the best of 2 runs of the
                          --traj-steps steps the adjoint covers, per step, from the state the
                          trajectory adjoint starts at (the initial placement).
  trajectory_adjoint_s    the backward pass: run.gradient() over a record_trajectory() run (the
                          forward pass that keeps the checkpoints, run once for the loss anyway,
                          is timed apart as record_s), extrapolated from runs over 1 and
                          --traj-steps steps (k = 1): fixed_s + per_step_s × the drape's steps
                          (extrapolated: true). per_step_s = (bw(T) − bw(1))/(T − 1) is the marginal
                          cost of a step (replay with recording, reverse); fixed_s = bw(1) −
                          per_step_s is the per-call cost (rest derivatives, first touch of the
                          tape). trajectory_over_forward = per_step_s / forward_step_s;
                          trajectory_end_to_end_over_forward adds the recording forward pass
                          (what trajectory_gradient() costs in one call).
  peak_memory_mb          peak_tape_mb reported by trajectory_gradient (checkpoints + one segment
                          of step starts + one step's tape): measured at --traj-steps without
                          checkpointing (k = 1: every state kept) and with (k = --traj-steps),
                          and extrapolated to a 2,000-step drape (k = 1 vs k = ceil(sqrt(2000)))
                          with the model peak = tape_step + 2 state (ceil(T/k) + k).
  full_trajectory         (--full-steps N) over N steps, for each k of --full-k (default
                          ceil(sqrt(N))): the recording forward pass and the backward pass measured
                          (record_s, trajectory_adjoint_s, end_to_end_s), peak tape and RSS, next to
                          the same N forward steps timed in the same process.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import resource
import time

os.environ.setdefault("OMP_WAIT_POLICY", "passive")  # see bench/simulate.py

import numpy as np  # noqa: E402

import diffavatar_core as dc  # noqa: E402
from diffavatar_core import _core  # noqa: E402
from diffavatar_core.adjoint import equilibrium_gradient, record_trajectory, trajectory_gradient  # noqa: E402
from diffavatar_core.sim import ClothMaterial  # noqa: E402
from diffavatar_core.sim.cloth import _sim_params  # noqa: E402
from diffavatar_core.sim.drape_job import build  # noqa: E402
from diffavatar_core.sim.scenes import hanging_sheet, sheet_against_sphere  # noqa: E402

DT = 1.0 / 120.0


def parse_args(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="small garment (edge 0.025 m), short budgets")
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--garment", default="tshirt")
    ap.add_argument("--edge", type=float, default=None, help="target edge (m); default 0.01 (>= 10k vertices), quick 0.025")
    ap.add_argument("--iterations", type=int, default=20, help="sweeps per XPBD step (drape and trajectory)")
    ap.add_argument("--drape-steps", type=int, default=None, help="step budget of the forward drape (default 200, quick 100)")
    ap.add_argument("--refine-iterations", type=int, default=60,
                    help="Newton cap of the forward drape (60 as in the earlier runs: the 200-step drape is not settled, "
                         "and the drape CLI's 200-step cap with its re-detection rounds took 937 s there)")
    ap.add_argument("--traj-steps", type=int, default=8, help="steps the trajectory adjoint is measured over (>= 2)")
    ap.add_argument("--skip-trajectory", action="store_true")
    ap.add_argument("--full-steps", type=int, default=0,
                    help="also run the trajectory adjoint end to end over this many steps with checkpointing "
                         "and measure its peak memory and time (e.g. 2000)")
    ap.add_argument("--full-k", type=int, nargs="*", default=None,
                    help="checkpoint intervals of the --full-steps runs (default: ceil(sqrt(N)))")
    a = ap.parse_args(argv)
    a.edge = a.edge or (0.025 if a.quick else 0.01)
    a.traj_steps = max(2, a.traj_steps)
    a.drape_steps = a.drape_steps or (100 if a.quick else 200)
    return a


def rss_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


# --- finite-difference checks on a small mesh (the same forward computation, T XPBD steps) -------
FD_T, FD_KW = 8, dict(dt=1 / 60, iterations=4)
FD_MAT = ClothMaterial(warp_compliance=2e-2, weft_compliance=3e-2, shear_compliance=5e-2, bend_stiffness=2e-5)


def _fd_params():
    p = _core.SimParams()
    p.dt, p.iterations = FD_KW["dt"], FD_KW["iterations"]
    return p


def _phi(cloth, W, start, key=None, value=None):
    """φ = Σ W·x_T after FD_T steps from `start` with one control or initial-state entry changed."""
    c0 = cloth.control
    c = cloth.control
    s = start.copy()
    if key in ("rest", "stretch_compliance", "bend_stiffness", "body_vertices"):
        setattr(c, key, value)
    elif key in ("x0", "v0"):
        setattr(s, "x" if key == "x0" else "v", value)
    cloth.solver.set_control(c)
    cloth.solver.step(s, _fd_params(), FD_T)
    cloth.solver.set_control(c0)
    return float(np.sum(W * s.x))


def _central(cloth, W, start, key, base, idx, h):
    a, b = base.copy(), base.copy()
    a[idx] += h
    b[idx] -= h
    return (_phi(cloth, W, start, key, a) - _phi(cloth, W, start, key, b)) / (2 * h)


def _fd_kind(cloth, W, start, g, key, base, picks, h, smooth_filter=False):
    """Max relative error |adjoint − FD| / max(|FD|, 1e-6·max|FD|) over the picked components;
    with smooth_filter, components whose FD changes between h and h/10 by more than 1e-6
    relative (a contact switching inside the FD step: the map is not smooth there) are excluded."""
    adj, num, excluded = [], [], 0
    for idx in picks:
        n1 = _central(cloth, W, start, key, base, idx, h)
        if smooth_filter:
            n2 = _central(cloth, W, start, key, base, idx, h / 10)
            if abs(n1 - n2) > 1e-6 * max(abs(n1), 1e-12) + 1e-9:
                excluded += 1
                continue
        num.append(n1)
        adj.append(float(np.asarray(g[key])[idx]))
    adj, num = np.array(adj), np.array(num)
    floor = 1e-6 * np.abs(num).max() if len(num) else 0.0
    rel = np.abs(adj - num) / np.maximum(np.abs(num), floor) if len(num) else np.array([np.nan])
    big = np.abs(num) > floor
    return dict(fd_max_rel_error=float(rel.max()), components=int(len(num)), excluded_not_smooth=excluded,
                sign_agreement=float(np.mean(np.sign(adj[big]) == np.sign(num[big]))) if big.any() else None,
                fd_step=float(h) if np.isscalar(h) else None)


def fd_checks():
    t0 = time.perf_counter()
    out = {}
    # A free hanging 5×5 sheet swinging from a perturbed, moving state (no contact: a smooth map).
    cloth, rest, pinned = hanging_sheet(0.1, 0.1, 5, 5, material=FD_MAT)
    rng = np.random.default_rng(0)
    x = np.array(cloth.x) + 0.003 * rng.standard_normal(cloth.x.shape)
    x[pinned] = np.array(cloth.x)[pinned]
    cloth.state.x = x
    v = 0.05 * rng.standard_normal(x.shape)
    v[pinned] = 0
    cloth.state.v = v
    W = rng.standard_normal(x.shape)
    start = cloth.state.copy()
    g = trajectory_gradient(cloth, FD_T, W, **FD_KW)
    c = cloth.control
    nv = len(rest)
    out["rest"] = _fd_kind(cloth, W, start, g, "rest", np.array(c.rest),
                           [(int(i), int(k)) for i in range(nv) for k in range(2)], 1e-6)
    sc = np.array(c.stretch_compliance)
    per = [_fd_kind(cloth, W, start, g, "stretch_compliance", sc, [(0, a)], 1e-5 * sc[0, a]) for a in range(3)]
    out["stretch_compliance"] = dict(fd_max_rel_error=max(p["fd_max_rel_error"] for p in per), components=3,
                                     excluded_not_smooth=0, fd_step="1e-5 relative")
    kb = np.array(c.bend_stiffness)
    out["bend_stiffness"] = _fd_kind(cloth, W, start, g, "bend_stiffness", kb, [(0,)], 1e-5 * kb[0])
    out["bend_stiffness"]["fd_step"] = "1e-5 relative"
    free = np.flatnonzero(cloth.model.inv_mass > 0)
    picks = [(int(i), k) for i in free for k in range(3)]
    out["x0"] = _fd_kind(cloth, W, start, g, "x0", np.array(start.x), picks, 1e-6)
    out["v0"] = _fd_kind(cloth, W, start, g, "v0", np.array(start.v), picks, 1e-6)
    # Body vertices: a sheet bulged by a sphere, moving and touching.
    cloth = sheet_against_sphere(n=5, materials=FD_MAT, contact_stiffness=200.0)
    cloth.solver.step(cloth.state, _fd_params(), 30)
    start = cloth.state.copy()
    W = np.random.default_rng(2).standard_normal(start.x.shape)
    g = trajectory_gradient(cloth, FD_T, W, **FD_KW)
    active = np.flatnonzero(np.abs(g["body_vertices"]).sum(axis=1) > 0)
    out["body_vertices"] = _fd_kind(cloth, W, start, g, "body_vertices", np.array(cloth.control.body_vertices),
                                    [(int(i), k) for i in active[:8] for k in range(3)], 1e-6, smooth_filter=True)
    out["body_vertices"]["active_body_vertices"] = int(len(active))
    return dict(scene=(f"trajectory adjoint over {FD_T} XPBD steps (dt {FD_KW['dt']:.4g} s, {FD_KW['iterations']} sweeps), "
                       "loss sum(W*x_T) with random W; rest/material/x0/v0 on a free 5x5 hanging sheet (25 vertices) "
                       "from a perturbed moving state; body_vertices on a 5x5 sheet touching a sphere (642 body "
                       "vertices), components whose FD is not smooth (contact switching within the step) excluded"),
                kinds=out, fd_max_rel_error={k: v["fd_max_rel_error"] for k, v in out.items()},
                wall_s=time.perf_counter() - t0)


def timed_adjoint(cloth, W, steps, k, iterations):
    """record_trajectory then run.gradient(W), each timed: (record_s, backward_s, run, gradient)."""
    t0 = time.perf_counter()
    run = record_trajectory(cloth, steps, checkpoint_every=k, dt=DT, iterations=iterations)
    t1 = time.perf_counter()
    gt = run.gradient(W)
    return t1 - t0, time.perf_counter() - t1, run, gt


def full_trajectory(cloth, g, W, p, a):
    """The trajectory adjoint end to end over a.full_steps steps from the initial placement, for
    each checkpoint interval of a.full_k: measured time, the implementation's peak tape and the
    process's peak RSS, next to the forward steps alone (no tape) in the same process."""
    N = a.full_steps
    ks = a.full_k or [math.ceil(math.sqrt(N))]
    s = cloth.solver.make_state(g["x0"])
    t0 = time.perf_counter()
    cloth.solver.step(s, p, N)
    forward_s = time.perf_counter() - t0
    cloth.reset(g["x0"])
    runs = []
    for k in sorted(ks, reverse=True):  # the lighter run first: ru_maxrss is a high-water mark
        rss0 = rss_mb()
        rec_s, bw_s, run, gt = timed_adjoint(cloth, W, N, k, a.iterations)
        finite = all(bool(np.all(np.isfinite(np.asarray(gt[key])))) for key in
                     ("rest", "stretch_compliance", "bend_stiffness", "body_vertices", "x0", "v0"))
        runs.append(dict(checkpoint_every=k, record_s=rec_s, trajectory_adjoint_s=bw_s,
                         trajectory_over_forward=bw_s / forward_s,
                         end_to_end_s=rec_s + bw_s, end_to_end_over_forward=(rec_s + bw_s) / forward_s,
                         peak_tape_mb=float(gt["peak_tape_mb"]), step_tape_mb=float(gt["step_tape_mb"]),
                         checkpoint_mb=float(run.checkpoint_mb),
                         process_peak_rss_mb=rss_mb(), process_peak_rss_growth_mb=rss_mb() - rss0,
                         gradient_finite=finite,
                         final_state_finite=bool(np.all(np.isfinite(np.asarray(gt["x_final"]))))))
        del run
    return dict(steps=N, iterations_per_step=a.iterations, forward_steps_s=forward_s, runs=runs,
                note="measured (no extrapolation): record_s = the forward pass storing checkpoints "
                     "(record_trajectory); trajectory_adjoint_s = the backward pass over it (run.gradient: per segment "
                     "a re-run storing step starts, none when k = 1, then per step a replay recording every projection "
                     "and the reverse); end_to_end = both, as trajectory_gradient() runs them")


def main(argv=None):
    a = parse_args(argv)
    if a.threads:
        dc.set_num_threads(a.threads)
    t_all = time.perf_counter()
    out = {"benchmark": "adjoint_gradients", "date": time.strftime("%Y-%m-%d"),
           "machine": f"{platform.machine()}, {os.cpu_count()} logical cores", "threads": dc.num_threads(),
           "omp_wait_policy": os.environ.get("OMP_WAIT_POLICY"),
           "load_average_start": [round(v, 2) for v in os.getloadavg()], "quick": a.quick}
    out["definitions"] = {k.strip(): v for k, v in (
        ("forward_s", "wall s of the forward drape: cloth.drape() from the initial placement (XPBD steps dt=1/120 s, "
                      "`iterations` sweeps each, until settled or the step budget, then Newton refinement)"),
        ("equilibrium_adjoint_s", "wall s of equilibrium_gradient() at the draped state, loss sum(W*x) with random W"),
        ("forward_step_s", "wall s per XPBD step without tape (XpbdSolver.step) over the traj_steps steps the adjoint "
                           "covers, best of 2 runs, from the initial placement"),
        ("trajectory_adjoint_s", "the backward pass (run.gradient() over a record_trajectory() run) wall s "
                                 "extrapolated to the drape's XPBD steps: fixed_s + per_step_s × steps, from k=1 runs "
                                 "over 1 and traj_steps steps; like equilibrium_adjoint_s it excludes the forward "
                                 "computation the loss needs anyway"),
        ("trajectory_over_forward", "per_step_s (the backward pass's marginal cost of one step: replay with recording, "
                                    "reverse) / forward_step_s (both measured)"),
        ("trajectory_end_to_end_over_forward", "the same with the forward pass that records the checkpoints "
                                               "(trajectory_gradient() in one call) / forward_step_s"),
        ("equilibrium_over_forward", "equilibrium_adjoint_s / forward_s"),
        ("peak_memory_mb", "peak_tape_mb of trajectory_gradient (checkpoints + segment starts + one step's tape)"),
    )}

    cloth, g, body = build(a.garment, edge=a.edge)
    m = cloth.model
    out.update(garment=a.garment, edge_m=a.edge, vertices=int(m.num_vertices), triangles=int(len(m.faces)),
               body_triangles=int(len(body[1])), iterations=a.iterations)
    V = int(m.num_vertices)
    rng = np.random.default_rng(0)
    W = rng.standard_normal((V, 3))
    p = _sim_params(DT, a.iterations, (0, -9.81, 0), 4.0, 0.01, 50.0)

    # --- forward drape and equilibrium adjoint ---------------------------------------------------
    t0 = time.perf_counter()
    r = cloth.drape(max_steps=a.drape_steps, iterations=a.iterations, refine_iterations=a.refine_iterations,
                    raise_on_divergence=False)
    forward_s = time.perf_counter() - t0
    out.update(forward_s=forward_s,
               forward_drape={"steps": r.steps, "step_budget": a.drape_steps, "settled": r.settled,
                              "converged": r.converged, "residual": r.residual, "refine_iterations": r.refine_iterations,
                              "xpbd_and_refine_wall_s": r.wall_s, "message": r.message})
    t0 = time.perf_counter()
    ge = equilibrium_gradient(cloth, W)
    eq_s = time.perf_counter() - t0
    out.update(equilibrium_adjoint_s=eq_s, equilibrium_over_forward=eq_s / forward_s,
               equilibrium_adjoint={"dofs": int(ge["dofs"]), "solve_residual": float(ge["solve_residual"]),
                                    "valid": bool(r.converged),
                                    "note": "valid at a converged drape (contact set held fixed); timed either way"})

    # --- trajectory adjoint over a few steps from the initial placement -------------------------
    if not a.skip_trajectory:
        T = a.traj_steps
        start = cloth.solver.make_state(g["x0"])
        fw = []
        for _ in range(2):  # the same T steps the adjoint runs cover (one step alone varied by 1.5x)
            s = start.copy()
            t0 = time.perf_counter()
            cloth.solver.step(s, p, T)
            fw.append((time.perf_counter() - t0) / T)
        forward_step_s = min(fw)
        cloth.reset(g["x0"])
        runs = {}
        for steps, k in ((T, T), (1, 1), (T, 1)):  # the lighter runs first: ru_maxrss is a high-water mark
            rss0 = rss_mb()
            rec_s, bw_s, run, gt = timed_adjoint(cloth, W, steps, k, a.iterations)
            runs[(steps, k)] = dict(steps=steps, checkpoint_every=k, record_s=rec_s, backward_s=bw_s,
                                    wall_s=rec_s + bw_s, peak_tape_mb=float(gt["peak_tape_mb"]),
                                    step_tape_mb=float(gt["step_tape_mb"]),
                                    process_peak_rss_growth_mb=rss_mb() - rss0)
            del run
        per_step_e2e = (runs[(T, 1)]["wall_s"] - runs[(1, 1)]["wall_s"]) / (T - 1)
        per_step = (runs[(T, 1)]["backward_s"] - runs[(1, 1)]["backward_s"]) / (T - 1)
        fixed = runs[(1, 1)]["backward_s"] - per_step
        state_mb = V * 3 * 8 / 1048576.0

        def slots(steps, k):
            return math.ceil(steps / k) + min(k, steps)

        tape_step_mb = runs[(T, 1)]["step_tape_mb"]
        n2000, k2000 = 2000, math.ceil(math.sqrt(2000))
        out.update(
            forward_step_s=forward_step_s,
            trajectory_adjoint_s=fixed + per_step * r.steps, extrapolated=True,
            trajectory_over_forward=per_step / forward_step_s,
            trajectory_over_forward_incl_fixed=(per_step + fixed / T) / forward_step_s,
            trajectory_end_to_end_over_forward=per_step_e2e / forward_step_s,
            peak_memory_mb={
                "measured": {"steps": T, "without_checkpointing": runs[(T, 1)]["peak_tape_mb"],
                             f"with_checkpointing_k{T}": runs[(T, T)]["peak_tape_mb"]},
                "extrapolated_2000_steps": {
                    "without_checkpointing": tape_step_mb + 2 * state_mb * slots(n2000, 1),
                    f"with_checkpointing_k{k2000}": tape_step_mb + 2 * state_mb * slots(n2000, k2000),
                    "model": "tape_step_mb + 2*state_mb*(ceil(T/k)+k)", "tape_step_mb": tape_step_mb,
                    "state_mb": state_mb},
            },
            trajectory_adjoint={"measured_steps": T, "iterations_per_step": a.iterations,
                                "per_step_s": per_step, "fixed_s": fixed, "per_step_end_to_end_s": per_step_e2e,
                                "runs": [v for v in runs.values()],
                                "extrapolated_to_steps": r.steps,
                                "note": "fixed_s + per_step_s × the drape's steps; per_step_s is the marginal "
                                        "cost of a step between the 1- and T-step runs"})
    if a.full_steps > 0:
        out["full_trajectory"] = full_trajectory(cloth, g, W, p, a)
    out["fd_check"] = fd_checks()
    out["fd_max_rel_error"] = out["fd_check"]["fd_max_rel_error"]
    out["process_peak_rss_mb"] = rss_mb()
    out["load_average_end"] = [round(v, 2) for v in os.getloadavg()]
    out["total_s"] = time.perf_counter() - t_all
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
