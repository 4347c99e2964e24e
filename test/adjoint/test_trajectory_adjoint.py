"""Trajectory adjoint (issue 4, mode 1) against central finite differences of the same forward
computation (T XPBD steps) for every parameter kind, checkpointing equivalence, invariants."""
import numpy as np
import pytest

from diffavatar_core import _core
from diffavatar_core.adjoint import record_trajectory, trajectory_gradient, trajectory_memory_mb
from diffavatar_core.sim import ClothMaterial
from diffavatar_core.sim.scenes import hanging_sheet, sheet_against_sphere

KW = dict(dt=1 / 60, iterations=4)
T = 8
MAT = ClothMaterial(warp_compliance=2e-2, weft_compliance=3e-2, shear_compliance=5e-2, bend_stiffness=2e-5)


def _params():
    p = _core.SimParams()
    p.dt, p.iterations = KW["dt"], KW["iterations"]
    return p


def _phi(cloth, W, start, **change):
    """φ = Σ W·x_T after T steps from `start` with a changed control or initial state."""
    c0 = cloth.control
    c = cloth.control
    for key in ("rest", "stretch_compliance", "bend_stiffness", "body_vertices"):
        if key in change:
            setattr(c, key, change[key])
    cloth.solver.set_control(c)
    s = start.copy()
    if "x0" in change:
        s.x = change["x0"]
    if "v0" in change:
        s.v = change["v0"]
    cloth.solver.step(s, _params(), T)
    cloth.solver.set_control(c0)
    return float(np.sum(W * s.x))


def _fd(cloth, W, start, key, base, idx, h):
    a, b = base.copy(), base.copy()
    a[idx] += h
    b[idx] -= h
    return (_phi(cloth, W, start, **{key: a}) - _phi(cloth, W, start, **{key: b})) / (2 * h)


def _check(cloth, W, start, g, key, base, picks, h, smooth_filter=False):
    """Relative error ≤ 1e-4 (floor 1e-6 of the largest) and ≥ 99% sign agreement; with
    smooth_filter, components whose FD changes between h and h/10 by more than 1e-6 (a contact
    entering/leaving or the λ ≥ 0 clamp switching inside the FD step) are left out."""
    adj, num = [], []
    for idx in picks:
        n1 = _fd(cloth, W, start, key, base, idx, h)
        if smooth_filter:
            n2 = _fd(cloth, W, start, key, base, idx, h / 10)
            if abs(n1 - n2) > 1e-6 * max(abs(n1), 1e-12) + 1e-9:
                continue
        num.append(n1)
        adj.append(np.asarray(g[key])[idx])
    assert len(num) >= max(1, len(picks) // 2), f"{key}: too few smooth components ({len(num)}/{len(picks)})"
    adj, num = np.array(adj), np.array(num)
    floor = 1e-6 * np.abs(num).max()
    rel = np.abs(adj - num) / np.maximum(np.abs(num), floor)
    assert rel.max() <= 1e-4, (key, rel.max(), adj, num)
    big = np.abs(num) > floor
    assert np.mean(np.sign(adj[big]) == np.sign(num[big])) >= 0.99


def _plan(cloth, plan):
    """"colours": the colour plan of small models; "lanes": the lane plan forced on (the adjoint
    must replay and reverse the same passes the forward ran)."""
    if plan == "lanes":
        cloth.set_sweep_plan(lanes=2, min_constraints=0)
        assert cloth.sweep_plan["lanes"] == 2 and cloth.sweep_plan["interface_constraints"] > 0
    else:
        assert cloth.sweep_plan["lanes"] == 1


@pytest.fixture(scope="module", params=["colours", "lanes"])
def free_sheet(request):
    """A hanging sheet swinging from a perturbed, moving state (no contact: a smooth map)."""
    cloth, rest, pinned = hanging_sheet(0.1, 0.1, 5, 5, material=MAT)
    _plan(cloth, request.param)
    rng = np.random.default_rng(0)
    x = np.array(cloth.x) + 0.003 * rng.standard_normal(cloth.x.shape)
    x[pinned] = np.array(cloth.x)[pinned]
    cloth.state.x = x
    v = 0.05 * rng.standard_normal(x.shape)
    v[pinned] = 0
    cloth.state.v = v
    W = rng.standard_normal(x.shape)
    g = trajectory_gradient(cloth, T, W, **KW)
    return cloth, W, cloth.state.copy(), g


def test_rest_material_and_initial_state_gradients(free_sheet):
    cloth, W, start, g = free_sheet
    c = cloth.control
    rng = np.random.default_rng(1)
    free = np.flatnonzero(cloth.model.inv_mass > 0)
    _check(cloth, W, start, g, "rest", np.array(c.rest),
           [(int(i), int(k)) for i, k in zip(rng.choice(25, 8, replace=False), rng.integers(0, 2, 8))], 1e-6)
    sc = np.array(c.stretch_compliance)
    for a in range(3):
        _check(cloth, W, start, g, "stretch_compliance", sc, [(0, a)], 1e-5 * sc[0, a])
    kb = np.array(c.bend_stiffness)
    _check(cloth, W, start, g, "bend_stiffness", kb, [(0,)], 1e-5 * kb[0])
    picks = [(int(i), int(k)) for i, k in zip(rng.choice(free, 6, replace=False), rng.integers(0, 3, 6))]
    _check(cloth, W, start, g, "x0", np.array(start.x), picks, 1e-6)
    _check(cloth, W, start, g, "v0", np.array(start.v), picks, 1e-6)


@pytest.mark.parametrize("contact", ["face", "smooth"])
@pytest.mark.parametrize("plan", ["colours", "lanes"])
def test_body_vertex_gradients_through_contact(plan, contact):
    """Through the contact planes (sim/contact_kernel.hpp); the smooth one also through the vertex
    normals and the barycentrics of each step's detection (region_barycentrics)."""
    cloth = sheet_against_sphere(n=5, materials=MAT, contact_stiffness=200.0, contact_normals=contact)
    _plan(cloth, plan)
    cloth.solver.step(cloth.state, _params(), 30)  # moving and touching
    start = cloth.state.copy()
    W = np.random.default_rng(2).standard_normal(start.x.shape)
    g = trajectory_gradient(cloth, T, W, **KW)
    gb = g["body_vertices"]
    active = np.flatnonzero(np.abs(gb).sum(axis=1) > 0)
    assert len(active) >= 3
    picks = [(int(i), k) for i in active[:4] for k in range(3)]
    _check(cloth, W, start, g, "body_vertices", np.array(cloth.control.body_vertices), picks, 1e-6,
           smooth_filter=True)
    # the start positions of vertices touching the sphere (through the detections, too)
    touching = np.unique([c for c in np.flatnonzero(np.abs(np.asarray(g["x0"])).sum(1) > 0)
                          if np.linalg.norm(start.x[c] - [0.1, 0.1, -0.06]) < 0.08 + 0.02])
    assert len(touching) >= 2
    _check(cloth, W, start, g, "x0", np.array(start.x), [(int(i), k) for i in touching[:4] for k in range(3)],
           1e-6, smooth_filter=True)


def test_checkpointing_gives_the_same_gradient(free_sheet):
    cloth, W, start, g = free_sheet
    for k in (3, 8):
        gk = trajectory_gradient(cloth, T, W, checkpoint_every=k, **KW)
        for key in ("rest", "stretch_compliance", "bend_stiffness", "x0", "v0"):
            np.testing.assert_allclose(gk[key], g[key], rtol=0, atol=1e-10 * np.abs(g[key]).max())
        np.testing.assert_array_equal(gk["x_final"], g["x_final"])


def test_checkpoint_interval_from_a_memory_budget(free_sheet):
    """Without checkpoint_every the adjoint takes the smallest (fastest) k whose peak fits the
    memory budget: k = 1 when it fits (the same computation as k = 1 given), a larger k under a
    tighter budget (its measured peak within the budget, the gradient that of k = 1 to 1e-10),
    and a clear error when none fits."""
    cloth, W, start, g = free_sheet  # g: checkpoint_every not given
    assert g["checkpoint_every"] == 1
    ga = trajectory_gradient(cloth, T, W, checkpoint_every=1, **KW)
    for key in ("rest", "stretch_compliance", "bend_stiffness", "x0", "v0"):
        np.testing.assert_array_equal(ga[key], g[key])
    it = KW["iterations"]
    assert trajectory_memory_mb(cloth, T, 1, it) >= g["peak_tape_mb"]  # the model bounds the measured peak
    budget = trajectory_memory_mb(cloth, T, 2, it)
    assert budget < trajectory_memory_mb(cloth, T, 1, it)
    gb = trajectory_gradient(cloth, T, W, memory_budget_mb=budget, **KW)
    assert gb["checkpoint_every"] == 2 and gb["peak_tape_mb"] <= budget
    for key in ("rest", "stretch_compliance", "bend_stiffness", "x0", "v0"):
        np.testing.assert_allclose(gb[key], g[key], rtol=0, atol=1e-10 * np.abs(g[key]).max())
    with pytest.raises(ValueError, match="memory budget"):
        trajectory_gradient(cloth, T, W, memory_budget_mb=0.5 * trajectory_memory_mb(cloth, T, 3, it), **KW)


def test_recorded_run_and_a_nonlinear_loss(free_sheet):
    """record_trajectory + gradient is the one-call adjoint split in two (bit-identical, k = 1
    and 3). A loss that is not linear in x_T, φ = ½|x_T − target|², gets ∂φ/∂x_T = x_T − target
    from the recorded run and its gradient from the same run, checked against central
    differences; the run can be reversed again with another loss; after the control is set
    again the run is refused."""
    cloth, W, start, g = free_sheet
    keys = ("rest", "stretch_compliance", "bend_stiffness", "x0", "v0")
    for k in (1, 3):
        run = record_trajectory(cloth, T, checkpoint_every=k, **KW)
        assert run.checkpoint_every == k and run.steps == T
        ref = g if k == 1 else trajectory_gradient(cloth, T, W, checkpoint_every=k, **KW)
        np.testing.assert_array_equal(run.x_final, ref["x_final"])
        gr = run.gradient(W)
        for key in keys:
            np.testing.assert_array_equal(gr[key], ref[key])
    np.testing.assert_array_equal(cloth.state.x, start.x)

    target = np.array(start.x) + 0.01 * np.random.default_rng(5).standard_normal(start.x.shape)

    def phi(**change):
        c0 = cloth.control
        c = cloth.control
        for key, value in change.items():
            setattr(c, key, value)
        cloth.solver.set_control(c)
        s = start.copy()
        cloth.solver.step(s, _params(), T)
        cloth.solver.set_control(c0)
        return 0.5 * float(np.sum((np.array(s.x) - target) ** 2))

    run = record_trajectory(cloth, T, **KW)
    gq = run.gradient(np.array(run.x_final) - target)
    g2 = run.gradient(W)  # reversed again with the linear loss
    for key in keys:
        np.testing.assert_array_equal(g2[key], g[key])
    cloth.solver.set_control(cloth.control)  # (the finite differences below set it too)
    with pytest.raises(ValueError, match="set since the forward run"):
        run.gradient(W)
    rest = np.array(cloth.control.rest)
    for idx in [(3, 0), (7, 1), (12, 0), (18, 1)]:
        a, b = rest.copy(), rest.copy()
        a[idx] += 1e-6
        b[idx] -= 1e-6
        fd = (phi(rest=a) - phi(rest=b)) / 2e-6
        assert abs(gq["rest"][idx] - fd) <= 1e-4 * max(abs(fd), 1e-6 * np.abs(gq["rest"]).max()), (idx, gq["rest"][idx], fd)
    kb = np.array(cloth.control.bend_stiffness)
    h = 1e-5 * kb[0]
    a, b = kb.copy(), kb.copy()
    a[0] += h
    b[0] -= h
    fd = (phi(bend_stiffness=a) - phi(bend_stiffness=b)) / (2 * h)
    assert abs(gq["bend_stiffness"][0] - fd) <= 1e-4 * abs(fd)


def test_invariants(free_sheet):
    cloth, W, start, g = free_sheet
    # the dynamics depend on the rest shape only through differences
    np.testing.assert_allclose(g["rest"].sum(axis=0), 0.0, atol=1e-9 * np.abs(g["rest"]).max())
    g2 = trajectory_gradient(cloth, T, -2.5 * W, **KW)
    for key in ("rest", "stretch_compliance", "bend_stiffness", "x0", "v0"):
        np.testing.assert_allclose(g2[key], -2.5 * g[key], rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(cloth.state.x, start.x)  # the cloth's own state is untouched


def test_progress_cancellation_and_tape_size(free_sheet):
    """Progress is reported (rate-limited, so at least the first event) in 2T units; a cancel
    raises Cancelled; one step's tape is exactly one record per projection of each of its sweeps
    (sim/sweep_tape.hpp: positions read and λ before it — 12 doubles per triangle, 14 per hinge
    with its angle, 9 per seam; this sheet has no body, so no contacts)."""
    from diffavatar_core import CancelToken, Cancelled
    cloth, W, start, g = free_sheet
    seen = []
    trajectory_gradient(cloth, T, W, progress=lambda ev: seen.append((ev.stage, ev.done, ev.total)), **KW)
    assert seen and {s for s, _, _ in seen} <= {"trajectory forward", "trajectory backward"}
    assert all(tot == 2 * T for _, _, tot in seen)
    token = CancelToken()

    def progress(ev):
        token.cancel()

    with pytest.raises(Cancelled):
        trajectory_gradient(cloth, T, W, progress=progress, cancel=token, **KW)
    m = cloth.model
    nf, nh, ns = len(m.faces), len(m.hinges), len(m.seams)
    per_sweep = 12 * nf + 14 * nh + 9 * ns
    assert g["step_tape_mb"] == pytest.approx(KW["iterations"] * per_sweep * 8 / 2**20, rel=1e-12)
    assert g["peak_tape_mb"] >= g["step_tape_mb"]


def test_a_cloth_whose_masses_follow_its_rest_is_refused():
    """The replay holds masses fixed, so its rest gradient would miss ∂m/∂x̄: refused, named."""
    cloth = sheet_against_sphere(n=5, materials=MAT, masses_follow_rest=True)
    W = np.ones(cloth.x.shape)
    with pytest.raises(ValueError, match="masses_follow_rest"):
        trajectory_gradient(cloth, T, W, **KW)
    run = record_trajectory(cloth, T, **KW)   # the forward pass alone is fine
    with pytest.raises(ValueError, match="masses_follow_rest"):
        run.gradient(W)
