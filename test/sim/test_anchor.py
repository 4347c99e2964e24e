"""Anchors of the Newton equilibrium (the static-friction proxy, ½ κ Σ m_i |x_i − a_i|²) set
explicitly (Cloth.refine(anchor=...), the guided drapes of the recovery): the equilibrium of a
rigidly translated target is known exactly."""
import numpy as np
import pytest

from diffavatar_core.sim import Cloth, ClothMaterial
from diffavatar_core.sim.scenes import grid_sheet
from sheet_on_sphere import sheet_on_sphere


def _flat_sheet():
    rest, F = grid_sheet(0.2, 0.2, 9, 9)
    x0 = np.column_stack([rest[:, 0], np.full(len(rest), 1.0), rest[:, 1]])   # horizontal, at rest length
    return Cloth(rest, F, x0, materials=ClothMaterial(bend_stiffness=1e-5)), x0


@pytest.mark.parametrize("kappa", [1e2, 1e4])
def test_anchored_equilibrium_of_a_translated_target_is_the_translation_minus_g_over_kappa(kappa):
    """Internal forces vanish under a rigid translation of the unstretched flat sheet, so with
    every anchor at x0 + t the equilibrium is x0 + t − (g/κ) ŷ: each vertex's spring κ m d carries
    its weight m g (m: its lumped mass, whatever it is)."""
    cloth, x0 = _flat_sheet()
    t = np.array([0.03, 0.02, -0.01])
    it, res = cloth.refine(anchor=x0 + t, anchor_stiffness=kappa, residual_tol=1e-12, refine_iterations=50)
    assert res <= 1e-10
    expected = x0 + t - np.array([0.0, 9.81 / kappa, 0.0])
    np.testing.assert_allclose(np.array(cloth.x), expected, atol=1e-9)
    np.testing.assert_array_equal(cloth.solver.anchor, x0 + t)


def test_without_an_anchor_refine_ties_the_cloth_to_where_it_starts():
    """keep_anchor=False (the default of every re-equilibration) still sets the anchors to the
    current state, replacing explicit ones."""
    cloth, x0 = _flat_sheet()
    cloth.refine(anchor=x0 + 0.05, anchor_stiffness=1e4, residual_tol=1e-12, refine_iterations=50)
    x1 = np.array(cloth.x)
    cloth.refine(keep_anchor=False, anchor_stiffness=1e4, residual_tol=1e-12, refine_iterations=50)
    np.testing.assert_array_equal(cloth.solver.anchor, x1)


def test_bad_anchors_are_named():
    cloth, x0 = _flat_sheet()
    with pytest.raises(ValueError, match="anchor"):
        cloth.refine(anchor=x0[:-1])
    bad = x0.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match="anchor"):
        cloth.refine(anchor=bad)


def test_self_anchor_ends_at_an_equilibrium_without_anchor_forces():
    """A sheet hanging from two pinned corners, solved anchored to a state 1 cm off (an
    optimizer's warm start), then re-anchored at itself (Cloth.self_anchor, which converges
    geometrically): the anchor springs end unstretched, so the state is an equilibrium of
    gravity and the cloth alone — a fresh Cloth started there with anchors 10⁶× weaker stays
    within 1 µm, where from the anchored state it moves by more than 0.1 mm."""
    rest, F = grid_sheet(0.2, 0.2, 9, 9)
    x0 = np.column_stack([rest[:, 0], 1.0 - rest[:, 1], np.zeros(len(rest))])   # vertical, at rest length
    top = np.flatnonzero(rest[:, 1] < 1e-12)
    pinned = [int(top[np.argmin(rest[top, 0])]), int(top[np.argmax(rest[top, 0])])]

    def sheet(x):
        return Cloth(rest, F, x, pinned=pinned, materials=ClothMaterial(bend_stiffness=1e-5))

    def free_move(x):   # how far a solve with negligible anchors takes a fresh cloth started at x
        c = sheet(x)
        _, res = c.refine(keep_anchor=False, anchor_stiffness=1e-6, residual_tol=1e-9, refine_iterations=200)
        assert res <= 1e-9
        return np.abs(np.array(c.x) - x).max()
    cloth = sheet(x0)
    cloth.refine(anchor=x0 + np.array([0.0, 0.0, 0.01]), residual_tol=1e-9, refine_iterations=200)
    assert free_move(np.array(cloth.x)) > 1e-4
    move = cloth.self_anchor(1e-9, rounds=6, tol=1e-8)
    assert move <= 1e-8
    assert free_move(np.array(cloth.x)) < 1e-6
    assert cloth.self_anchor(1e-9, rounds=1) <= 1e-8      # and a converged state stays put


def _sheet_on_a_coarse_sphere():
    """The sheet (13×13 vertices) over an 80-face icosphere (sheet_on_sphere): with the face contact
    planes a vertex's plane jumps where its closest face changes. (The 11×11 sheet showed the jump
    until stop 58; since Newton's Gauss–Newton hinge blocks, stop 59, its rounds end where no plane
    switches, and the 13×13 one's do.)"""
    return sheet_on_sphere(13, subdivisions=1)


def test_self_anchor_ends_at_an_equilibrium_of_its_own_contact_planes(monkeypatch):
    """A Newton solve holds the contact planes of its start; a self-anchoring round whose end state
    has other closest faces re-solves with those. Converged, the state is an equilibrium with the
    planes detected there — a fresh Cloth (a reloaded asset) started there stays within 1 µm.
    Without the re-solves (CONTACT_REDETECTIONS = 0: the rounds before stop 34) the same rounds
    report convergence at a state whose own planes leave a residual above 1 (measured 462), as
    the sample skirt's under `--roundoff-seed 10`, which reloaded moved 0.75 mm."""
    import diffavatar_core.sim.cloth as cloth_module
    cloth = _sheet_on_a_coarse_sphere()
    assert cloth.self_anchor(1e-8, rounds=10, tol=1e-6) <= 1e-6
    assert cloth.own_contacts_residual() <= 1e-8
    x = np.array(cloth.x)
    fresh = Cloth(cloth.control.rest, cloth.model.faces, x, pinned=np.flatnonzero(np.asarray(cloth.model.inv_mass) == 0),
                  body=(cloth.control.body_vertices, cloth.body_faces), materials=ClothMaterial(bend_stiffness=1e-5))
    _, res = fresh.refine(keep_anchor=False, residual_tol=1e-8, refine_iterations=100)
    assert res <= 1e-8 and np.abs(np.array(fresh.x) - x).max() < 1e-6

    monkeypatch.setattr(cloth_module, "CONTACT_REDETECTIONS", 0)
    cloth = _sheet_on_a_coarse_sphere()
    assert cloth.self_anchor(1e-8, rounds=10, tol=1e-6) <= 1e-6
    assert cloth.own_contacts_residual() > 1.0


def test_self_anchor_undoes_a_round_that_misses_the_tolerance():
    """A round that cannot reach residual_tol (here: an unreachable 0) leaves the state as it was
    and reports no completed round (inf)."""
    cloth, x0 = _flat_sheet()
    assert cloth.self_anchor(0.0, rounds=2, refine_iterations=3) == float("inf")
    np.testing.assert_array_equal(np.array(cloth.x), x0)


def test_reseat_contacts_reaches_a_vertex_deeper_than_the_contact_search():
    """A vertex Newton carried into the body deeper than the contact search reach (collision
    thickness + contact_radius: it had no contact) is found by the re-detection and pushed out:
    after one Cloth.reseat_contacts round no vertex is deeper than 10% of the thickness (with the
    fixed reach the round left the bulge 10.4 mm deep, found only as it came within reach round by
    round; a skirt of test/pipeline ended its drape 28 mm deep that way)."""
    from diffavatar_core.sim.scenes import sheet_against_sphere
    cloth = sheet_against_sphere(n=8)
    assert cloth.drape(max_steps=400, residual_tol=1e-8, refine_iterations=200).converged
    x = np.array(cloth.x)
    centre, radius = np.array([0.1, 0.1, -0.06]), 0.08
    free = np.asarray(cloth.model.inv_mass) > 0
    x[free] += [0.0, 0.0, -0.03]               # the bulge 3 cm into the sphere
    cloth.reset(x)
    reach = cloth.model.thickness + cloth.params.contact_radius
    assert cloth.solver.max_penetration(x) > reach
    its, res, pen = cloth.reseat_contacts(1e-8, refine_iterations=200, rounds=1)
    assert res <= 1e-8
    assert pen <= 0.1 * cloth.model.thickness
    assert np.linalg.norm(np.array(cloth.x) - centre, axis=1).min() >= radius
