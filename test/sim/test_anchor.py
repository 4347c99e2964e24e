"""Anchors of the Newton equilibrium (the static-friction proxy, ½ κ Σ m_i |x_i − a_i|²) set
explicitly (Cloth.refine(anchor=...), the guided drapes of the recovery): the equilibrium of a
rigidly translated target is known exactly."""
import numpy as np
import pytest

from diffavatar_core.sim import Cloth, ClothMaterial
from diffavatar_core.sim.scenes import grid_sheet


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
