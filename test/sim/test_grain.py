"""Fabric grain (issue 3): the orthotropic StVK strain is measured in each triangle's grain
frame (grain_frame.hpp). Stiffness along/across the grain, invariance under rotating pattern
and grain together, exact quarter turns, grain 0 unchanged, and both adjoints' rest-coordinate
gradients through the rotation against central differences (double precision)."""
import numpy as np
import pytest

from diffavatar_core import _core
from diffavatar_core.adjoint import equilibrium_gradient, trajectory_gradient
from diffavatar_core.pattern.garment import Garment, PanelInfo
from diffavatar_core.sim import ClothMaterial
from diffavatar_core.sim.cloth import Cloth
from diffavatar_core.sim.scenes import grid_sheet, hanging_sheet, sheet_against_sphere

A_WARP, A_WEFT, A_SHEAR = 2e-3, 5e-3, 1e-2  # m/N, deliberately unequal
MAT = ClothMaterial(warp_compliance=A_WARP, weft_compliance=A_WEFT, shear_compliance=A_SHEAR, bend_stiffness=0.0)
ZERO_G = (0.0, 0.0, 0.0)


def _sheet(grain, rest=None, material=MAT):
    if rest is None:
        rest, F = grid_sheet(0.2, 0.1, 5, 4)
    else:
        _, F = grid_sheet(0.2, 0.1, 5, 4)
    x0 = np.column_stack([rest, np.zeros(len(rest))])
    return Cloth(rest, F, x0, materials=material, grain=np.full(len(F), grain) if np.isscalar(grain) else grain), rest


def _stiffness(cloth, rest, direction, lam=1.01):
    """Measured 2D stiffness (N/m) for a uniform stretch λ of the pattern along `direction`:
    x = u + (λ−1)(d·u)d, Green strain ε = (λ²−1)/2 along d, E = Ā ε²/(2α) → 1/α = 2E/(Ā ε²)."""
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    u = rest + (lam - 1.0) * np.outer(rest @ d, d)
    x = np.column_stack([u, np.zeros(len(u))])
    area = 0.2 * 0.1
    eps = 0.5 * (lam * lam - 1.0)
    return 2.0 * cloth.energy(x, gravity=ZERO_G) / (area * eps * eps)


@pytest.mark.parametrize("grain", [0.0, 0.37, np.pi / 2, -1.1])
def test_stretch_along_the_grain_feels_warp_across_it_weft(grain):
    cloth, rest = _sheet(grain)
    along = (np.cos(grain), np.sin(grain))
    across = (-np.sin(grain), np.cos(grain))
    np.testing.assert_allclose(_stiffness(cloth, rest, along), 1.0 / A_WARP, rtol=1e-10)
    np.testing.assert_allclose(_stiffness(cloth, rest, across), 1.0 / A_WEFT, rtol=1e-10)


def test_quarter_turn_swaps_warp_and_weft_exactly():
    """A grain of π/2 (exact cos/sin) only swaps ε00, ε11 and negates ε01: energy and force of
    any deformation equal, bit for bit, those of grain 0 with warp and weft compliances swapped."""
    swapped = ClothMaterial(warp_compliance=A_WEFT, weft_compliance=A_WARP, shear_compliance=A_SHEAR,
                            bend_stiffness=0.0)
    a, rest = _sheet(np.pi / 2)
    b, _ = _sheet(0.0, material=swapped)
    x = np.column_stack([rest, np.zeros(len(rest))]) + 0.01 * np.random.default_rng(3).standard_normal((len(rest), 3))
    assert a.energy(x, gravity=ZERO_G) == b.energy(x, gravity=ZERO_G)
    np.testing.assert_array_equal(a.solver.energy_gradient(x, np.zeros(3)), b.solver.energy_gradient(x, np.zeros(3)))
    # the measured stiffnesses along pattern x and y swap exactly with the grain
    c0, _ = _sheet(0.0)
    np.testing.assert_allclose(_stiffness(a, rest, (1, 0)), _stiffness(c0, rest, (0, 1)), rtol=1e-12)
    np.testing.assert_allclose(_stiffness(a, rest, (0, 1)), _stiffness(c0, rest, (1, 0)), rtol=1e-12)
    # the XPBD path (cached D̄⁻¹) honours it too: hanging sheets, same trajectory
    s1, _, _ = hanging_sheet(0.1, 0.2, 4, 7, material=MAT, grain=np.full(36, np.pi / 2))
    s2, _, _ = hanging_sheet(0.1, 0.2, 4, 7, material=swapped)
    s3, _, _ = hanging_sheet(0.1, 0.2, 4, 7, material=MAT)
    for s in (s1, s2, s3):
        s.step(40, dt=1 / 120, iterations=20)
    np.testing.assert_allclose(s1.x, s2.x, rtol=0, atol=1e-12)
    assert np.abs(s1.x - s3.x).max() > 1e-5  # unequal warp/weft: the grain matters


def test_rotating_pattern_and_grain_together_leaves_dynamics_unchanged():
    th, g = 0.7, 0.25
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    mat = ClothMaterial(warp_compliance=A_WARP, weft_compliance=A_WEFT, shear_compliance=A_SHEAR, bend_stiffness=1e-5)
    a, rest, pinned = hanging_sheet(0.1, 0.2, 4, 7, material=mat, grain=np.full(36, g))
    b, _, _ = hanging_sheet(0.1, 0.2, 4, 7, material=mat, grain=np.full(36, g + th))
    b.set_control(rest=rest @ R.T)
    for s in (a, b):
        s.step(60, dt=1 / 120, iterations=20)
    assert np.abs(a.x - np.array(hanging_sheet(0.1, 0.2, 4, 7, material=mat)[0].x)).max() > 1e-4  # it moved
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-10)
    x = np.array(a.x)
    np.testing.assert_allclose(a.energy(x), b.energy(x), rtol=1e-12)
    np.testing.assert_allclose(a.solver.energy_gradient(x, np.array([0, -9.81, 0])),
                               b.solver.energy_gradient(x, np.array([0, -9.81, 0])), rtol=0, atol=1e-9)


def test_grain_zero_is_the_default_bit_for_bit():
    """grain=None and an all-zero grain take the same (identity) path: the rest matrices are
    the untouched pattern's, so results equal the simulator without grain bit for bit."""
    a, _, _ = hanging_sheet(0.1, 0.2, 4, 7, material=MAT)
    b, _, _ = hanging_sheet(0.1, 0.2, 4, 7, material=MAT, grain=np.zeros(36))
    np.testing.assert_array_equal(a.model.tri_grain, np.zeros(36))
    for s in (a, b):
        s.step(30, dt=1 / 120, iterations=20)
    np.testing.assert_array_equal(a.x, b.x)
    W = np.random.default_rng(0).standard_normal(a.x.shape)
    ga = trajectory_gradient(a, 4, W, dt=1 / 60, iterations=4)
    gb = trajectory_gradient(b, 4, W, dt=1 / 60, iterations=4)
    np.testing.assert_array_equal(ga["rest"], gb["rest"])


def test_bad_grain_is_rejected():
    rest, F = grid_sheet(0.1, 0.1, 3, 3)
    x0 = np.column_stack([rest, np.zeros(len(rest))])
    with pytest.raises(ValueError, match="grain"):
        Cloth(rest, F, x0, grain=np.zeros(3))
    with pytest.raises(ValueError, match="grain"):
        Cloth(rest, F, x0, grain=np.full(len(F), np.nan))


def test_garment_face_grain_is_its_panels():
    rest, F = grid_sheet(0.1, 0.1, 3, 3)
    n = len(rest)
    g = Garment(rest=np.vstack([rest, rest + [0.2, 0]]), faces=np.vstack([F, F + n]).astype(np.int32),
                x0=np.zeros((2 * n, 3)), seams=np.zeros((0, 2), np.int32),
                panel=np.repeat(np.arange(2, dtype=np.int32), n),
                panels=[PanelInfo("a", np.array([0, 2, 8, 6], np.int32)),
                        PanelInfo("b", np.array([n, n + 2, n + 8, n + 6], np.int32), 0.3)],
                boundaries={})
    np.testing.assert_array_equal(g.face_grain(), np.r_[np.full(len(F), np.pi / 2), np.full(len(F), 0.3)])


# ---- adjoints w.r.t. the rest coordinates with a non-quarter-turn grain ----------------------

def _grains(nf, seed):
    return 0.4 + 0.3 * np.random.default_rng(seed).standard_normal(nf)


def test_equilibrium_adjoint_rest_gradient_with_grain():
    tol = 1e-10
    mat = ClothMaterial(warp_compliance=2e-2, weft_compliance=6e-2, shear_compliance=5e-2, bend_stiffness=2e-5)
    cloth = sheet_against_sphere(n=8, materials=mat, contact_stiffness=20.0, grain=_grains(98, 4))
    r = cloth.drape(max_steps=3000, residual_tol=tol, refine_iterations=200)
    assert r.converged, r
    x_star, control = cloth.x.copy(), cloth.control
    W = np.random.default_rng(1).standard_normal(x_star.shape)
    g = equilibrium_gradient(cloth, W)

    def phi(rest):
        cloth.state.x = x_star
        cloth.set_control(rest=rest)
        _, res = cloth.refine(keep_anchor=True, keep_contacts=True, residual_tol=tol, refine_iterations=200)
        assert res <= 10 * tol, res
        out = float(np.sum(W * cloth.x))
        cloth.state.x = x_star
        cloth.set_control(rest=control.rest)
        return out

    rng = np.random.default_rng(2)
    free = np.flatnonzero(cloth.model.inv_mass > 0)
    h = 1e-6
    adj, num = [], []
    for i, k in zip(rng.choice(free, 10, replace=False), rng.integers(0, 2, 10)):
        rp, rm = np.array(control.rest), np.array(control.rest)
        rp[i, k] += h
        rm[i, k] -= h
        num.append((phi(rp) - phi(rm)) / (2 * h))
        adj.append(g["rest"][i, k])
    adj, num = np.array(adj), np.array(num)
    floor = 1e-3 * np.abs(num).max()
    assert (np.abs(adj - num) / np.maximum(np.abs(num), floor)).max() <= 1e-3, (adj, num)
    # invariant: the equilibrium depends on the pattern only through differences
    np.testing.assert_allclose(g["rest"].sum(axis=0), 0.0, atol=1e-8 * np.abs(g["rest"]).max())


def test_trajectory_adjoint_rest_gradient_with_grain():
    T, kw = 8, dict(dt=1 / 60, iterations=4)
    mat = ClothMaterial(warp_compliance=2e-2, weft_compliance=6e-2, shear_compliance=5e-2, bend_stiffness=2e-5)
    cloth, rest, pinned = hanging_sheet(0.1, 0.1, 5, 5, material=mat, grain=_grains(32, 5))
    rng = np.random.default_rng(0)
    x = np.array(cloth.x) + 0.003 * rng.standard_normal(cloth.x.shape)
    x[pinned] = np.array(cloth.x)[pinned]
    cloth.state.x = x
    v = 0.05 * rng.standard_normal(x.shape)
    v[pinned] = 0
    cloth.state.v = v
    start = cloth.state.copy()
    W = rng.standard_normal(x.shape)
    g = trajectory_gradient(cloth, T, W, **kw)
    p = _core.SimParams()
    p.dt, p.iterations = kw["dt"], kw["iterations"]
    c0 = cloth.control

    def phi(r):
        c = cloth.control
        c.rest = r
        cloth.solver.set_control(c)
        s = start.copy()
        cloth.solver.step(s, p, T)
        cloth.solver.set_control(c0)
        return float(np.sum(W * s.x))

    h = 1e-6
    adj, num = [], []
    for i, k in zip(rng.choice(25, 10, replace=False), rng.integers(0, 2, 10)):
        rp, rm = np.array(c0.rest), np.array(c0.rest)
        rp[i, k] += h
        rm[i, k] -= h
        num.append((phi(rp) - phi(rm)) / (2 * h))
        adj.append(g["rest"][i, k])
    adj, num = np.array(adj), np.array(num)
    floor = 1e-6 * np.abs(num).max()
    assert (np.abs(adj - num) / np.maximum(np.abs(num), floor)).max() <= 1e-4, (adj, num)
    np.testing.assert_allclose(g["rest"].sum(axis=0), 0.0, atol=1e-9 * np.abs(g["rest"]).max())
