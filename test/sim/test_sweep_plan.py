"""The lane plan of the XPBD sweep (cpp/sim/sweep_plan.hpp): a partition of the constraints, the
same result for any thread count, the same equilibrium as the colour plan, and a short cut
whatever the vertex numbering."""
import numpy as np
import pytest

import diffavatar_core as dc
from diffavatar_core.adjoint import trajectory_gradient
from diffavatar_core.sim import Cloth, ClothMaterial
from diffavatar_core.sim.scenes import grid_sheet, sheet_against_sphere, sphere

MAT = ClothMaterial(bend_stiffness=1e-5)


def _sheet(n=21, perm=None, body=True):
    """A 0.2 m sheet (n×n vertices) pinned along its top, over a sphere; vertices renumbered
    by `perm` (new index of old vertex i is perm[i])."""
    rest, F = grid_sheet(0.2, 0.2, n, n)
    x0 = np.column_stack([rest[:, 0], 0.2 - rest[:, 1], np.zeros(len(rest))])
    pinned = np.flatnonzero(np.isclose(rest[:, 1], 0.0))
    if perm is not None:
        inv = np.argsort(perm)
        rest, x0, F, pinned = rest[inv], x0[inv], perm[F], perm[pinned]
    kw = dict(body=sphere(0.08, center=[0.1, 0.1, -0.06], subdivisions=3)) if body else {}
    return Cloth(rest, F, x0, pinned=pinned, materials=MAT, **kw)


def _partition(cloth):
    """Checks the plan is a partition of the constraints; returns the interface fraction."""
    p = cloth.sweep_plan
    m = cloth.model
    assert p["lanes"] == 2
    assert sum(p["lane_vertices"]) == m.num_vertices
    assert abs(p["lane_vertices"][0] - p["lane_vertices"][1]) <= 1  # balanced
    assert p["total_constraints"] == len(m.faces) + len(m.hinges) + len(m.seams)
    return p["interface_constraints"] / p["total_constraints"]


def test_small_models_keep_the_colour_plan_and_large_ones_get_lanes():
    a = _sheet(n=11)
    assert a.sweep_plan["lanes"] == 1 and a.sweep_plan["partition"] == "colours"
    a.set_sweep_plan(lanes=2, min_constraints=0)
    assert a.sweep_plan["lanes"] == 2
    a.set_sweep_plan(lanes=1)
    assert a.sweep_plan["lanes"] == 1
    with pytest.raises(ValueError, match="lanes"):
        a.set_sweep_plan(lanes=0)
    with pytest.raises(ValueError, match="min_constraints"):
        a.set_sweep_plan(min_constraints=-1)


def test_the_cut_stays_short_whatever_the_vertex_numbering():
    n = 31
    tidy = _sheet(n=n, body=False)
    tidy.set_sweep_plan(lanes=2, min_constraints=0)
    assert tidy.sweep_plan["partition"] == "index"
    f_tidy = _partition(tidy)
    # A row of the grid is one front: the cut is a few rows' constraints, O(√V) of O(V).
    assert f_tidy < 3.0 / n
    shuffled = _sheet(n=n, perm=np.random.default_rng(0).permutation(n * n), body=False)
    shuffled.set_sweep_plan(lanes=2, min_constraints=0)
    assert shuffled.sweep_plan["partition"] == "bfs"  # the numbering's cut would be ~half
    assert _partition(shuffled) < 3.0 / n


def _run(cloth, threads, steps=15):
    old = dc.num_threads()
    dc.set_num_threads(threads)
    try:
        cloth.reset(np.array(cloth.state.x))
        cloth.step(steps, iterations=20)
        return np.array(cloth.x)
    finally:
        dc.set_num_threads(old)


def test_the_lane_plan_gives_the_same_trajectory_and_gradient_for_any_thread_count():
    if dc.num_threads() < 2:
        pytest.skip("needs an OpenMP build with ≥ 2 threads")
    xs, gs = [], []
    for threads in (1, 2):
        c = _sheet()
        c.set_sweep_plan(lanes=2, min_constraints=0)
        xs.append(_run(c, threads))
        assert c.solver.num_contacts > 0
        W = np.random.default_rng(3).standard_normal(c.x.shape)
        old = dc.num_threads()
        dc.set_num_threads(threads)
        try:
            gs.append(trajectory_gradient(c, 3, W, dt=1 / 120, iterations=10))
        finally:
            dc.set_num_threads(old)
    np.testing.assert_array_equal(xs[0], xs[1])
    for key in ("rest", "stretch_compliance", "bend_stiffness", "body_vertices", "x0", "v0"):
        np.testing.assert_array_equal(gs[0][key], gs[1][key])


def test_both_plans_reach_the_same_equilibrium():
    """The plans order the Gauss–Seidel projections differently, so their trajectories differ;
    the equilibrium (Newton-refined, no contact: a unique energy minimum) does not."""
    out = []
    for lanes in (1, 2):
        c = _sheet(body=False)
        c.set_sweep_plan(lanes=lanes, min_constraints=0)
        r = c.drape(max_steps=3000, residual_tol=1e-9)
        assert r.converged
        out.append(np.array(c.x))
    np.testing.assert_allclose(out[1], out[0], rtol=0, atol=1e-8)


def test_lane_sweeps_project_contacts_last():
    """After a sweep of either plan no vertex is inside the contact layer it was projected
    against (the contacts run after every lane and the interface)."""
    c = sheet_against_sphere(n=21, bend_stiffness=1e-5)
    c.set_sweep_plan(lanes=2, min_constraints=0)
    c.step(40, iterations=30)
    assert c.solver.num_contacts > 0
    assert c.solver.max_penetration(c.x) <= 0.1 * float(c.model.thickness)
