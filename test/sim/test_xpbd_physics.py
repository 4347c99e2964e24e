"""Physics of the XPBD drape (issue 3): analytic hanging elongation, orthotropy, bending,
sewing, contact, translation invariance, convergence and divergence detection."""
import numpy as np
import pytest
import trimesh
from scipy.optimize import brentq

from diffavatar_core import CancelToken, Cancelled
from diffavatar_core.sim import Cloth, ClothMaterial, SimulationDiverged
from diffavatar_core.sim.scenes import grid_sheet

from diffavatar_core.sim.scenes import hanging_sheet, sheet_against_sphere, sphere

RHO, GRAV = 0.15, 9.81


def analytic_length(alpha, length, rho=RHO, g=GRAV, n=4000):
    """Hanging strip, uniaxial Green strain ε = ½(λ²−1), energy ε²/(2α) per rest area: the first
    Piola stress λε/α balances the weight below, ρ g (L − Y) per rest width."""
    Y = (np.arange(n) + 0.5) / n * length
    lam = [brentq(lambda l: l * 0.5 * (l * l - 1) / alpha - rho * g * (length - y), 1.0, 3.0) for y in Y]
    return float(np.sum(lam) * length / n)


def test_hanging_strip_matches_analytic_elongation():
    alpha = 0.05
    mat = ClothMaterial(density=RHO, warp_compliance=1.0, weft_compliance=alpha, shear_compliance=1.0,
                        bend_stiffness=0.0)
    cloth, rest, pinned = hanging_sheet(0.1, 0.3, 5, 31, material=mat)
    r = cloth.drape(max_steps=3000, anchor_stiffness=0.0, residual_tol=1e-9)
    assert r.converged and np.all(np.isfinite(cloth.x))
    sim = 0.3 - cloth.x[:, 1].min()
    exact = analytic_length(alpha, 0.3)
    assert abs((sim - 0.3) / (exact - 0.3) - 1) < 0.05, (sim, exact)


def test_warp_and_weft_compliances_give_the_expected_elongation_ratio():
    elong = {}
    for axis in (0, 1):
        mat = ClothMaterial(density=RHO, warp_compliance=0.04, weft_compliance=0.02, shear_compliance=1.0,
                            bend_stiffness=0.0)
        cloth, _, _ = hanging_sheet(0.1, 0.3, 5, 31, material=mat, vertical_axis=axis)
        assert cloth.drape(max_steps=3000, anchor_stiffness=0.0, residual_tol=1e-9).converged
        elong[axis] = 0.3 - cloth.x[:, 1].min() - 0.3
    expected = (analytic_length(0.04, 0.3) - 0.3) / (analytic_length(0.02, 0.3) - 0.3)
    assert abs(elong[0] / elong[1] / expected - 1) < 0.05, (elong, expected)


def test_flat_sheet_without_load_stays_flat():
    rest, F = grid_sheet(0.2, 0.2, 11, 11)
    x0 = np.column_stack([rest, np.zeros(len(rest))])
    cloth = Cloth(rest, F, x0, materials=ClothMaterial(bend_stiffness=1e-3))
    cloth.step(50, gravity=(0, 0, 0))
    assert np.abs(cloth.x[:, 2]).max() < 1e-14


def test_cantilever_sag_decreases_monotonically_with_bending_stiffness():
    sags = []
    for k in (1e-6, 1e-5, 1e-4, 1e-3):
        rest, F = grid_sheet(0.15, 0.06, 16, 7)
        x0 = np.column_stack([rest[:, 0], np.zeros(len(rest)), rest[:, 1]])  # horizontal in XZ
        pinned = np.flatnonzero(rest[:, 0] < 0.015)  # clamp: the first two columns
        cloth = Cloth(rest, F, x0, pinned=pinned,
                      materials=ClothMaterial(bend_stiffness=k, warp_compliance=1e-3, weft_compliance=1e-3))
        r = cloth.drape(max_steps=4000, anchor_stiffness=0.0)
        assert r.converged, r
        sags.append(-cloth.x[:, 1].min())
    assert all(a > b for a, b in zip(sags, sags[1:])), sags
    assert sags[0] > 3 * sags[-1], sags


def _tube_around_cylinder(gap_deg=25.0, r_cloth=0.14, n_around=14, n_up=11, height=0.3):
    """Two panels, each spanning (180° − gap) of a cylinder of radius r_cloth around a
    body cylinder of radius 0.1 m; seams pair their side edges across the gaps."""
    width = np.pi * 0.125  # rest width of each panel: sewn girth 2πr with r = 0.125 m
    rest1, F1 = grid_sheet(width, height, n_around, n_up)
    n = len(rest1)
    rest = np.vstack([rest1, rest1 + [width + 0.05, 0.0]])
    F = np.vstack([F1, F1 + n])
    u = rest1[:, 0] / width
    span = np.radians(180.0 - gap_deg)
    xs = []
    for start in (np.radians(gap_deg / 2), np.pi + np.radians(gap_deg / 2)):
        ang = start + u * span
        xs.append(np.column_stack([r_cloth * np.cos(ang), rest1[:, 1] - height / 2, r_cloth * np.sin(ang)]))
    x0 = np.vstack(xs)
    j = np.arange(n_up)
    first, last = j * n_around, j * n_around + n_around - 1
    # panel 1's end (angle 180°−gap/2) meets panel 2's start (180°+gap/2) and vice versa
    seams = np.vstack([np.column_stack([last, n + first]), np.column_stack([n + last, first])])
    # panel orientation: increasing angle is counter-clockwise seen from +Y; pattern CCW too
    return rest, F, x0, seams


def test_sewing_closes_a_tube_around_a_cylinder():
    rest, F, x0, seams = _tube_around_cylinder()
    cyl = trimesh.creation.cylinder(radius=0.1, height=0.5, sections=48)
    # trimesh's cylinder axis is Z: turn it to Y
    V = np.asarray(cyl.vertices)[:, [0, 2, 1]] * [1, 1, -1]
    Fb = np.asarray(cyl.faces, dtype=np.int32)
    if trimesh.Trimesh(V, Fb).volume < 0:
        Fb = Fb[:, ::-1].copy()
    cloth = Cloth(rest, F, x0, seams=seams, body=(V, Fb), materials=ClothMaterial(bend_stiffness=1e-6))
    gap0 = np.linalg.norm(x0[seams[:, 0]] - x0[seams[:, 1]], axis=1).max()
    assert gap0 > 0.05
    r = cloth.drape(max_steps=1500, gravity=(0, 0, 0), refine=False)
    assert r.settled and not r.diverged
    gap = np.linalg.norm(cloth.x[seams[:, 0]] - cloth.x[seams[:, 1]], axis=1).max()
    assert gap < 1e-3, gap
    assert r.max_penetration <= 0.1 * 0.004


def _sheet_over_sphere(offset=np.zeros(3)):
    """A tablecloth on a ball: its centre vertex is pinned on top of the sphere (contact is
    frictionless, so an unpinned sheet slides off, as it should)."""
    rest, F = grid_sheet(0.5, 0.5, 21, 21)
    x0 = np.column_stack([rest[:, 0] - 0.25, np.full(len(rest), 0.205), 0.25 - rest[:, 1]]) + offset
    V, Fb = sphere(0.2, center=offset)
    centre = [int(np.argmin(np.linalg.norm(rest - 0.25, axis=1)))]
    return Cloth(rest, F, x0, pinned=centre, body=(V, Fb), materials=ClothMaterial(bend_stiffness=1e-5))


def test_drape_on_a_sphere_does_not_penetrate():
    a = _sheet_over_sphere()
    ra = a.drape(max_steps=150, min_steps=150, refine=False)
    assert not ra.diverged and np.all(np.isfinite(a.x))
    assert ra.max_penetration <= 0.1 * 0.004, ra.max_penetration
    assert a.x[:, 1].min() < 0.0  # it really draped over the sphere


def test_translating_the_body_translates_the_drape():
    a = sheet_against_sphere()
    ra = a.drape(max_steps=2000)
    assert ra.converged and ra.max_penetration <= 0.1 * 0.004
    assert a.x[:, 2].max() > 0.01  # the sphere bulges the sheet forward
    t = np.array([0.7, -0.3, 1.1])
    b = sheet_against_sphere(offset=t)
    rb = b.drape(max_steps=2000)
    assert rb.converged
    # Not to round-off: the translated coordinates round differently, the unconverged XPBD phase
    # amplifies that, and the static-friction anchor (its end state) keeps it in the equilibrium.
    # Measured 0.85 µm; a round-off-level rewrite of the stretch kernel moved it to 1.02 µm (and
    # was taken out again). 5 µm = 1/800 of the collision thickness.
    np.testing.assert_allclose(b.x - t, a.x, atol=5e-6)


def test_drape_converges_and_reports_residual():
    cloth, _, _ = hanging_sheet(material=ClothMaterial(bend_stiffness=1e-5))
    events = []
    r = cloth.drape(max_steps=3000, progress=events.append)
    assert r.converged and r.residual <= 1e-5 and r.settled
    assert np.all(np.isfinite(cloth.x))
    drape_done = [e.done for e in events if e.stage == "drape"]
    assert drape_done == sorted(drape_done) and len(drape_done) >= 1


def test_absurd_time_step_is_detected_not_returned_as_nan():
    cloth, _, _ = hanging_sheet()
    before = cloth.x.copy()
    with pytest.raises(SimulationDiverged) as info:
        cloth.drape(dt=100.0, iterations=2)
    assert info.value.result.diverged
    assert "diverged" in str(info.value)
    assert np.all(np.isfinite(cloth.x))
    np.testing.assert_array_equal(cloth.x, before)  # nothing finite was lost


def test_drape_is_deterministic_and_cancellable():
    xs = []
    for _ in range(2):
        a = _sheet_over_sphere()
        a.drape(max_steps=60, refine=False, min_steps=60)
        xs.append(a.x.copy())
    np.testing.assert_array_equal(xs[0], xs[1])
    token = CancelToken()
    seen = []

    def progress(ev):
        seen.append(ev.done)
        if ev.done >= 3:
            token.cancel()

    a = _sheet_over_sphere()
    with pytest.raises(Cancelled):
        a.drape(max_steps=10000, progress=progress, cancel=token)
    assert max(seen) < 20


def test_bad_inputs_are_named():
    rest, F = grid_sheet(0.1, 0.1, 3, 3)
    x0 = np.column_stack([rest, np.zeros(len(rest))])
    with pytest.raises(ValueError, match="clockwise"):
        Cloth(rest, F[:, ::-1], x0)
    bad = x0.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="x0"):
        Cloth(rest, F, bad)
    with pytest.raises(ValueError, match="seams"):
        Cloth(rest, F, x0, seams=[[0, 99]])


def test_skirt_sews_and_drapes_on_the_body_like_mannequin():
    from diffavatar_core.sim.scenes import mannequin, two_panel_skirt
    V, Fb = mannequin(48, 40)
    sk = two_panel_skirt(edge=0.04)
    cloth = Cloth(sk["rest"], sk["faces"], sk["x0"], seams=sk["seams"], groups=sk["groups"],
                  materials=[ClothMaterial()] * 2, body=(V, Fb))
    r = cloth.drape(max_steps=1500)
    assert r.converged, r
    assert r.max_penetration <= 0.1 * 0.004
    x = cloth.x
    assert np.linalg.norm(x[sk["seams"][:, 0]] - x[sk["seams"][:, 1]], axis=1).max() < 1e-3
    waist = x[sk["boundaries"]["waist"]]
    assert 0.9 < waist[:, 1].mean() < 1.3  # held by the hips (frictionless: it may ride up), not fallen off


def test_an_equilibrium_inside_the_body_is_not_reported_converged():
    """A small sheet pinned at the centre of a 20 cm ball hangs in equilibrium inside it, out of
    the contacts' reach: Newton reaches the force residual, but a drape whose cloth is inside the
    body (deeper than 10% of the thickness) is not converged — and says why."""
    rest, F = grid_sheet(0.06, 0.06, 7, 7)
    x0 = np.column_stack([rest[:, 0] - 0.03, np.zeros(len(rest)), 0.03 - rest[:, 1]])
    V, Fb = sphere(0.2)
    centre = [int(np.argmin(np.linalg.norm(rest - 0.03, axis=1)))]
    inside = Cloth(rest, F, x0, pinned=centre, body=(V, Fb), materials=ClothMaterial(bend_stiffness=1e-5))
    r = inside.drape(max_steps=2000)
    assert r.residual <= 1e-5 and r.max_penetration > 0.15
    assert not r.converged and "inside the body" in r.message
    free = Cloth(rest, F, x0, pinned=centre, materials=ClothMaterial(bend_stiffness=1e-5))   # no body
    rf = free.drape(max_steps=2000)
    assert rf.converged and rf.max_penetration == 0.0
    np.testing.assert_allclose(inside.x, free.x, atol=1e-9)   # the body was never touched
