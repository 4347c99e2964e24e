"""Small steps in the drape (Cloth.drape(substeps=k); Macklin et al. 2019, "Small steps in physics
simulation"): k XPBD steps of dt/k with 1/k of the sweeps each make as many sweeps as one step
and leave a fine mesh stiffer. With one 1/120 s step of 100 sweeps, the pants at the CLI's
2.5 cm edge (1,870 vertices) stretched their waistband over the hips in the first fall and slid
to the floor (waist at 0.5 m after 1 s); the 4 cm pants held."""
import numpy as np
import pytest

from diffavatar_core.sim import drape_job


def _hip_height():
    from diffavatar_core.body import BodyModel
    model = BodyModel.default()
    return model.landmarks(model.zero_params()).hip_center[1]


def test_pants_at_the_cli_edge_stay_on_the_hips_with_the_drape_substeps():
    cloth, g, _ = drape_job.build("pants", edge=0.025)
    cloth.sew()
    # the first second of the drape (120 steps of 1/120 s), where the pants fell before
    r = cloth.drape(max_steps=120, min_steps=120, refine=False, substeps=drape_job.SUBSTEPS,
                    raise_on_divergence=False)
    assert not r.diverged and r.steps == 120
    x = np.asarray(cloth.x)
    waist = x[g["boundaries"]["waist"]]
    assert waist[:, 1].min() > _hip_height()


def test_substeps_bring_the_xpbd_elongation_of_a_hanging_strip_toward_the_analytic_one():
    """Same sweeps per 1/120 s (20), XPBD alone (no Newton): the strip's excess elongation over
    the analytic one (test_xpbd_physics.analytic_length) shrinks with every doubling of the
    substeps (measured 3.5×, 2.1×, 1.5× the exact elongation for 1, 2, 4)."""
    from test_xpbd_physics import RHO, analytic_length
    from diffavatar_core.sim import ClothMaterial
    from diffavatar_core.sim.scenes import hanging_sheet
    alpha = 0.05
    exact = analytic_length(alpha, 0.3) - 0.3
    excess = []
    for k in (1, 2, 4):
        mat = ClothMaterial(density=RHO, warp_compliance=1.0, weft_compliance=alpha, shear_compliance=1.0,
                            bend_stiffness=0.0)
        cloth, _, _ = hanging_sheet(0.1, 0.3, 5, 31, material=mat)
        r = cloth.drape(max_steps=600, min_steps=600, refine=False, iterations=20, substeps=k)
        assert not r.diverged
        length = 0.3 - np.asarray(cloth.x)[:, 1].min()   # top row pinned at y = 0.3 m, rest length 0.3 m
        excess.append((length - 0.3) / exact - 1.0)
    assert excess[0] > excess[1] > excess[2] > 0.0, excess
    assert excess[2] < 0.5 * excess[0], excess


def test_substeps_must_be_positive(tmp_path):
    cloth, g, _ = drape_job.build("mannequin-skirt", edge=0.05)
    with pytest.raises(ValueError, match="substeps"):
        cloth.drape(max_steps=1, substeps=0)
    # the drape job (CLI) refuses before it builds, sews or writes anything
    with pytest.raises(ValueError, match="substeps"):
        drape_job.execute(tmp_path / "out", "mannequin-skirt", substeps=0)
    assert not (tmp_path / "out").exists()
