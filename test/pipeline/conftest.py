"""Fixtures shared by the recovery tests."""
import numpy as np
import pytest

from diffavatar_core.body import BodyModel
from diffavatar_core.pattern.templates import make_template
from diffavatar_core.sim.cloth import Cloth
from diffavatar_core.sim.material import ClothMaterial

SKIRT_TRUE_LENGTH = 0.55 * 1.08   # m: the target skirt of skirt_problem (the template's is 0.55)


def _draped_skirt(body, lm, contact_normals="face", **meas):
    g = make_template("skirt", landmarks=lm, edge_length=0.07, **meas)
    cloth = Cloth(g.rest, g.faces, g.x0, seams=g.seams, groups=g.panel[g.faces[:, 0]],
                  materials=[ClothMaterial()] * len(g.panels), body=body, contact_normals=contact_normals)
    cloth.sew()
    assert cloth.drape(max_steps=150, iterations=40, residual_tol=1e-8, refine_iterations=150).converged
    return g, cloth


@pytest.fixture
def skirt_true_length():
    return SKIRT_TRUE_LENGTH


def _skirt_problem(contact_normals):
    model = BodyModel.default()
    p = model.zero_params()
    body = (model.pose(p), model.faces)
    lm = model.landmarks(p)
    g, cloth = _draped_skirt(body, lm, contact_normals)
    gt, cgt = _draped_skirt(body, lm, contact_normals, length=SKIRT_TRUE_LENGTH)
    xg = np.array(cgt.x)
    scan_loops = {k: xg[v] for k, v in gt.boundaries.items()}
    scan_points = xg[np.unique(gt.faces)]
    return model, p, g, cloth, scan_points, scan_loops


@pytest.fixture(scope="module")
def skirt_problem():
    """A coarse skirt draped on the default body and a target: the same skirt 8% longer, draped
    (its surface vertices and openings as the scan). Tests that change the cloth restore it."""
    return _skirt_problem("face")


@pytest.fixture(scope="module")
def smooth_skirt_problem():
    """skirt_problem with the smooth contact plane (sim/contact_kernel.hpp)."""
    return _skirt_problem("smooth")
