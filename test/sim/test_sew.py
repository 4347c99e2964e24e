"""Cloth.sew: quasi-static sewing closes wide seam gaps without turning the closure into speed."""
import numpy as np

from diffavatar_core.sim import Cloth
from diffavatar_core.sim.scenes import grid_sheet


def _two_panels(gap: float):
    """Two 0.3 m squares in the plane z = 0, the right edge of A sewn to the left edge of B,
    B placed `gap` m to the right of A."""
    rest, faces = grid_sheet(0.3, 0.3, 7, 7)
    n = len(rest)
    x_a = np.column_stack([rest, np.zeros(n)])
    x_b = x_a + [0.3 + gap, 0.0, 0.0]
    right = np.flatnonzero(np.isclose(rest[:, 0], 0.3))
    left = np.flatnonzero(np.isclose(rest[:, 0], 0.0))
    seams = np.column_stack([right, left + n])
    rest2 = np.vstack([rest, rest + [0.5, 0.0]])
    return Cloth(rest2, np.vstack([faces, faces + n]), np.vstack([x_a, x_b]), seams=seams), seams


def test_sew_closes_a_wide_gap_and_leaves_the_cloth_at_rest():
    cloth, seams = _two_panels(0.2)
    m = np.asarray(cloth.model.mass)
    com0 = m @ cloth.x / m.sum()
    steps = cloth.sew(max_steps=60, gap_tol=1e-3)
    x = np.array(cloth.x)
    assert 0 < steps <= 60
    assert np.linalg.norm(x[seams[:, 0]] - x[seams[:, 1]], axis=1).max() < 1e-3
    assert np.abs(np.array(cloth.state.v)).max() == 0.0
    # seam constraints are internal forces between equal masses: the centre of mass stays put
    np.testing.assert_allclose(m @ x / m.sum(), com0, atol=1e-9)


def test_sew_does_nothing_when_already_sewn():
    cloth, _ = _two_panels(0.0)
    x0 = np.array(cloth.x)
    assert cloth.sew() == 0
    np.testing.assert_array_equal(np.array(cloth.x), x0)
