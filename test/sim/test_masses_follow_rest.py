"""Cloth(masses_follow_rest=True): after set_control(rest=...) the simulation weighs what the
new pattern's area does, in both sweep kinds (the single-precision sweep caches inverse masses
per solver revision). The equilibrium adjoint's mass term is FD-tested in
test/adjoint/test_equilibrium_adjoint.py."""
import numpy as np
import pytest

from diffavatar_core.sim import ClothMaterial
from diffavatar_core.sim.cloth import Cloth
from diffavatar_core.sim.scenes import hanging_sheet

# compliant enough (0.3 m/N) that the sheet's own weight stretches it by millimetres
MAT = ClothMaterial(warp_compliance=0.3, weft_compliance=0.3, shear_compliance=0.3, bend_stiffness=1e-7)


def _hang(cloth, rest, fast):
    cloth.reset(np.column_stack([rest[:, 0], 0.3 - rest[:, 1], np.zeros(len(rest))]))
    cloth.step(60, iterations=50, fast=fast)
    return np.array(cloth.x)


@pytest.mark.parametrize("fast", [False, True], ids=["float64", "single"])
def test_a_wider_pattern_hangs_as_a_cloth_built_on_it(fast):
    cloth, rest, pinned = hanging_sheet(material=MAT, masses_follow_rest=True)
    wide = rest * [1.5, 1.0]   # 1.5× the area, so 1.5× the weight on each column
    reference = Cloth(wide, cloth.model.faces, np.zeros((len(wide), 3)), pinned=pinned, materials=MAT)
    x_ref = _hang(reference, wide, fast)
    cloth.set_control(rest=wide)
    np.testing.assert_allclose(cloth.model.mass, reference.model.mass, rtol=1e-12)
    x = _hang(cloth, wide, fast)
    assert np.abs(x - x_ref).max() < 1e-5   # m (single precision: round-off)
    fixed, _, _ = hanging_sheet(material=MAT)   # the default keeps the narrow pattern's masses
    fixed.set_control(rest=wide)
    assert np.abs(_hang(fixed, wide, fast) - x_ref).max() > 1e-3   # it hangs measurably higher
