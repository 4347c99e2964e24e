"""The drape's fast sweep (sim/fast_sweep.hpp): the same XPBD projections in the same order as the
double-precision sweep, in float and vectorised. It has to agree with the double sweep up to float
round-off, kernel by kernel, keep a rest sheet at rest under rigid motion, leave pinned vertices
untouched, not depend on the thread count, and give the same physics (hanging-strip elongation,
a drape that converges outside the body)."""
import numpy as np
import pytest

import diffavatar_core as dc
from diffavatar_core.sim import Cloth, ClothMaterial, drape_job
from diffavatar_core.sim.scenes import grid_sheet, hanging_sheet


def _both(cloth, state, **kw):
    """Positions after the same step(s) from `state` with the double and with the fast sweep."""
    out = []
    for fast in (False, True):
        cloth.state = state.copy()
        cloth.step(fast=fast, **kw)
        out.append(np.array(cloth.x))
    return out


@pytest.fixture(scope="module")
def falling_tshirt():
    """The 4 cm t-shirt, sewn and 40 steps into its fall: stretch, bending, seams and ~400 body
    contacts all active."""
    cloth, g, _ = drape_job.build("tshirt", edge=0.04)
    cloth.sew()
    cloth.step(n=40, iterations=20)
    return cloth


def test_one_sweep_agrees_with_the_double_sweep_up_to_float_round_off(falling_tshirt):
    cloth = falling_tshirt
    st, x0 = cloth.state.copy(), np.array(cloth.x)
    xd, xf = _both(cloth, st, n=1, iterations=1)
    assert cloth.solver.num_contacts > 100
    moved = np.abs(xd - x0).max()
    assert moved > 1e-3   # the step does move the cloth by millimetres
    # measured 4.3e-7 m: a few float ulps at 1 m (6e-8 m), against millimetres of motion
    assert np.abs(xf - xd).max() < 2e-6


def test_the_bending_kernel_agrees_with_the_double_one():
    """A clamped strip bent by gravity with stiff bending: what the hinges contribute to one step
    (double, stiffness 1e-3 against 0) is at least 10⁴× what separates the two sweeps (measured:
    2.8 mm against 2.3e-8 m; a wrong term in the float gradient would show at the millimetre)."""
    rest, F = grid_sheet(0.15, 0.06, 16, 7)
    # a curled start (quarter-circle about the clamp), so every hinge is far from its rest angle
    r = 0.1
    ang = rest[:, 0] / r
    x0 = np.column_stack([r * np.sin(ang), r * (np.cos(ang) - 1.0), rest[:, 1]])
    pinned = np.flatnonzero(rest[:, 0] < 0.015)
    res = {}
    for k in (0.0, 1e-3):
        cloth = Cloth(rest, F, x0, pinned=pinned,
                      materials=ClothMaterial(bend_stiffness=k, warp_compliance=1e-3, weft_compliance=1e-3))
        res[k] = _both(cloth, cloth.state, n=1, iterations=10)
    contribution = np.abs(res[1e-3][0] - res[0.0][0]).max()
    assert contribution > 1e-3
    assert np.abs(res[1e-3][1] - res[1e-3][0]).max() < 1e-4 * contribution


def test_a_rest_sheet_under_a_rigid_motion_stays_at_rest_and_pinned_vertices_do_not_move():
    rest, F = grid_sheet(0.2, 0.1, 9, 5)
    c, s = np.cos(0.7), np.sin(0.7)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]) @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    x0 = np.column_stack([rest, np.zeros(len(rest))]) @ R.T + np.array([0.3, 1.2, -0.4])
    cloth = Cloth(rest, F, x0, pinned=[0, 8], materials=ClothMaterial(bend_stiffness=1e-4))
    v = cloth.step(n=20, gravity=(0, 0, 0), fast=True)
    x = np.array(cloth.x)
    assert np.abs(x - x0).max() < 1e-6 and v < 1e-4   # C = 0 up to float round-off
    np.testing.assert_array_equal(x[[0, 8]], x0[[0, 8]])   # bit for bit


def test_the_fast_sweep_does_not_depend_on_the_thread_count(falling_tshirt):
    if dc.num_threads() < 2:
        pytest.skip("needs an OpenMP build with ≥ 2 threads")
    cloth = falling_tshirt
    cloth.set_sweep_plan(lanes=2, min_constraints=0)   # the lane plan (two lanes + interface)
    try:
        st = cloth.state.copy()
        old, xs = dc.num_threads(), []
        try:
            for threads in (1, 2):
                dc.set_num_threads(threads)
                cloth.state = st.copy()
                cloth.step(n=2, iterations=10, fast=True)
                xs.append(np.array(cloth.x))
        finally:
            dc.set_num_threads(old)
        np.testing.assert_array_equal(xs[0], xs[1])
    finally:
        cloth.set_sweep_plan(lanes=2, min_constraints=16384)


def test_hanging_strip_elongates_as_with_the_double_sweep():
    """XPBD alone (no Newton), 600 steps of 20 sweeps: the fast sweep's elongation is the double
    sweep's (Gauss–Seidel leaves the same excess over the analytic value; measured 3e-6 apart,
    relative)."""
    mat = ClothMaterial(density=0.15, warp_compliance=1.0, weft_compliance=0.05, shear_compliance=1.0,
                        bend_stiffness=0.0)
    length = {}
    for fast in (False, True):
        cloth, _, _ = hanging_sheet(0.1, 0.3, 5, 31, material=mat)
        r = cloth.drape(max_steps=600, min_steps=600, refine=False, iterations=20, fast=fast)
        assert not r.diverged
        length[fast] = 0.3 - np.asarray(cloth.x)[:, 1].min() - 0.3
    assert abs(length[True] / length[False] - 1.0) < 1e-4, length


def test_a_fast_drape_converges_outside_the_body():
    cloth, g, _ = drape_job.build("tshirt", edge=0.04)
    cloth.sew()
    r = cloth.drape(max_steps=1500, substeps=drape_job.SUBSTEPS, fast=True, raise_on_divergence=False)
    assert r.converged, r.message
    assert r.max_penetration <= 0.1 * float(cloth.model.thickness)
    x = np.asarray(cloth.x)
    assert np.linalg.norm(x[g["seams"][:, 0]] - x[g["seams"][:, 1]], axis=1).max() < 1e-3


def test_the_trajectory_adjoint_refuses_single_precision_sweeps():
    """Its replay records float64 projections; a float forward would not be what it reverses."""
    from diffavatar_core import _core
    from diffavatar_core.sim.cloth import _sim_params
    cloth, _, _ = hanging_sheet(0.1, 0.1, 4, 4)
    p = _sim_params(1 / 120, 5, (0, -9.81, 0), 4.0, 0.01, 50.0, fast=True)
    W = np.zeros_like(np.asarray(cloth.x))
    with pytest.raises(ValueError, match="not differentiable"):
        _core.trajectory_adjoint(cloth.solver, cloth.state, p, 2, W, W)


def test_the_drape_job_names_an_unknown_sweep_precision_before_any_work(tmp_path):
    with pytest.raises(ValueError, match="sweeps"):
        drape_job.execute(tmp_path / "out", "mannequin-skirt", sweeps="half")
    assert not (tmp_path / "out").exists()
