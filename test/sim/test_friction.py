"""Coulomb friction of the cloth on the body (sim/friction_kernel.hpp): a flat sheet on an inclined
plane obeys the sliding-block law — it stays put when μ ≥ tan θ and otherwise slides with the
acceleration g (sin θ − μ cos θ) — in the double-precision and the fast sweeps; μ = 0 is the
frictionless slide g sin θ; Cloth.self_anchor with friction ends on a static Coulomb equilibrium
exactly when μ exceeds the slope; and nothing differentiated accepts friction."""
import numpy as np
import pytest

from diffavatar_core import _core
from diffavatar_core.sim import Cloth, ClothMaterial
from diffavatar_core.sim.scenes import grid_sheet

THETA = np.radians(20.0)
G = 9.81
DT = 1 / 240
H = 0.004      # collision thickness (m), Cloth's default


def inclined_sheet(theta=THETA):
    """A 10 cm sheet lying on a plane through the origin tilted by theta about the x axis (its
    downhill direction in the y–z plane), at the collision thickness above it. Returns the cloth
    and the unit downhill direction."""
    down = np.array([0.0, -np.sin(theta), np.cos(theta)])        # in the plane, pointing downhill
    normal = np.array([0.0, np.cos(theta), np.sin(theta)])       # outward, up the slope's side
    across = np.array([1.0, 0.0, 0.0])
    L = 2.0
    corners = np.array([-L * across - L * down, L * across - L * down, L * across + L * down, -L * across + L * down])
    Fb = np.array([[0, 2, 1], [0, 3, 2]], np.int32)
    assert np.dot(np.cross(corners[2] - corners[0], corners[1] - corners[0]), normal) > 0
    rest, F = grid_sheet(0.1, 0.1, 6, 6)
    x0 = rest[:, :1] * across + rest[:, 1:2] * down + H * normal
    cloth = Cloth(rest, F, x0, body=(corners, Fb), materials=ClothMaterial(bend_stiffness=1e-6), thickness=H)
    return cloth, down


def slide(mu, fast, seconds=0.5):
    cloth, down = inclined_sheet()
    x0 = np.array(cloth.x)
    cloth.step(int(round(seconds / DT)), dt=DT, iterations=20, damping=0.0, fast=fast, friction=mu)
    return float(((np.asarray(cloth.x) - x0) @ down).mean()), np.asarray(cloth.x) - x0


@pytest.mark.parametrize("fast", [False, True])
@pytest.mark.parametrize("mu", [0.0, 0.15, 0.3, 0.35])
def test_sliding_sheet_follows_the_coulomb_law(mu, fast):
    assert mu < np.tan(THETA)
    t = 0.5
    s, _ = slide(mu, fast, t)
    a = G * (np.sin(THETA) - mu * np.cos(THETA))
    # semi-implicit Euler travels ½ a t² (1 + dt/t)
    expected = 0.5 * a * t * t * (1 + DT / t)
    assert abs(s / expected - 1) < 0.01, (s, expected)


@pytest.mark.parametrize("fast", [False, True])
@pytest.mark.parametrize("mu", [0.4, 1.0])
def test_sheet_at_rest_when_friction_exceeds_the_slope(mu, fast):
    assert mu > np.tan(THETA)      # tan 20° = 0.364
    s, d = slide(mu, fast, 0.5)
    # frictionless, it would have slid ½ g sin θ t² = 42 cm
    assert np.abs(d).max() < 1e-4, (s, np.abs(d).max())


def test_friction_is_refused_where_it_would_be_differentiated():
    cloth, _ = inclined_sheet()
    p = _core.SimParams()
    p.friction = 0.3
    with pytest.raises(ValueError, match="friction"):
        _core.trajectory_forward(cloth.solver, cloth.state, p, 3, 1, None, None)
    with pytest.raises(ValueError, match="friction"):
        cloth.step(1, friction=-0.1)
    for bad in (float("nan"), float("inf"), "0.3", None, True):
        with pytest.raises(ValueError, match="friction"):
            cloth.step(1, friction=bad)
        with pytest.raises(ValueError, match="friction"):
            cloth.self_anchor(1e-8, rounds=1, friction=bad)


@pytest.mark.parametrize("mu", [0.0, 0.03, 0.04, 0.1])
def test_self_anchor_stops_on_a_slope_exactly_when_friction_can_hold(mu):
    """The anchored Newton equilibrium on a 2° slope slides until the anchors' pull balances
    the downhill weight (g sin θ / κ = 34 cm at κ = 1/s²): a frictionless cloth re-anchored at
    itself slides again every round; with friction the pull is a static friction force as long
    as μ ≥ tan 2° = 0.035, so the rounds stop and every vertex's anchor force lies in its cone."""
    theta = np.radians(2.0)
    cloth, down = inclined_sheet(theta)
    x0 = np.array(cloth.x)
    offset = cloth.self_anchor(1e-8, rounds=3, tol=1e-4, friction=mu)
    slid = float(((np.asarray(cloth.x) - x0) @ down).mean())
    per_round = G * np.sin(theta)
    if mu > np.tan(theta):
        assert offset == 0.0
        assert abs(slid / per_round - 1) < 0.02, slid    # one round: the anchored equilibrium
    else:
        assert offset > 0.5 * per_round                    # still sliding after three rounds
        assert slid > 2.5 * per_round


def test_contact_cone_violation_is_the_coulomb_condition():
    """A sheet resting on a level plane, pulled sideways by anchors offset by d: inside the
    cone iff κ m d ≤ μ m g (the weight is the normal force); lifted off the body, any pull fails."""
    cloth, _ = inclined_sheet(0.0)
    assert cloth.drape(max_steps=200, residual_tol=1e-9, anchor_stiffness=0.0).converged
    x = np.array(cloth.x)
    side = np.array([1.0, 0.0, 0.0])
    for d, mu, inside in ((0.5, 0.1, True), (1.5, 0.1, False), (0.02, 0.0, False), (0.0, 0.0, True)):
        v = cloth.contact_cone_violation(x + d * side, mu)
        assert np.all(v != inside), (d, mu)
    cloth.reset(x + [0.0, 0.05, 0.0])                      # 5 cm above the plane
    assert cloth.contact_cone_violation(x + [0.0, 0.05, 0.0] + 1e-3 * side, 1.0).all()
