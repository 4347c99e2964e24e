"""Coarse-to-fine output (pipeline/refine.py): the recovered pattern carried to a finer mesh of
the same template through the control cage, and the coarse drape carried to its vertices."""
import numpy as np
import pytest

from diffavatar_core.body import BodyModel
from diffavatar_core.demo import SAMPLE
from diffavatar_core.pattern.cage import build_cage
from diffavatar_core.pattern.templates import make_template
from diffavatar_core.pipeline import RecoverOptions, recover
from diffavatar_core.pipeline.refine import transfer_pattern, transfer_positions
from edge_strain import mean_edge_strain
from bundled_sample import NO_BENDING_SEARCH, QUICK


@pytest.fixture(scope="module")
def skirts():
    model = BodyModel.default()
    lm = model.landmarks(model.zero_params())
    coarse = make_template("skirt", landmarks=lm, edge_length=0.06)
    fine = make_template("skirt", landmarks=lm, edge_length=0.025)
    return coarse, fine, build_cage(coarse)


def test_the_template_cage_maps_the_fine_template_to_itself(skirts):
    coarse, fine, cage = skirts
    assert len(fine.rest) > 3 * len(coarse.rest)
    out = transfer_pattern(coarse, cage, cage.zeta0, fine)
    np.testing.assert_allclose(out, fine.rest, rtol=0, atol=1e-9 * np.abs(fine.rest).max())


def test_an_affine_map_of_the_handles_maps_the_fine_pattern_alike(skirts):
    """Linear precision of mean value coordinates: ζ → A ζ + b moves every fine vertex by A x̄ + b."""
    coarse, fine, cage = skirts
    A, b = np.array([[1.07, 0.02], [-0.03, 0.91]]), np.array([0.01, -0.02])
    out = transfer_pattern(coarse, cage, cage.zeta0 @ A.T + b, fine)
    np.testing.assert_allclose(out, fine.rest @ A.T + b, rtol=0, atol=1e-9)


def test_positions_of_an_affine_drape_are_reproduced_inside_the_coarse_mesh(skirts):
    """A coarse 'drape' that is an affine function of the pattern carries over exactly to fine
    vertices inside the coarse triangles (barycentric interpolation); all others lie within the
    boundary's chord error of it."""
    coarse, fine, _ = skirts
    M = np.array([[0.8, 0.1], [0.2, 1.1], [0.05, -0.3]])
    c = np.array([0.1, 1.0, 0.2])
    x_fine = transfer_positions(coarse, coarse.rest @ M.T + c + 0.5 * coarse.panel[:, None], fine)
    want = fine.rest @ M.T + c + 0.5 * fine.panel[:, None]
    err = np.linalg.norm(x_fine - want, axis=1)
    assert np.median(err) < 1e-9 and err.max() < 0.01, err.max()


def test_recover_writes_a_finer_settled_mesh():
    """recover(..., output_edge_length < edge_length): the result is the finer mesh, draped until
    it stands still (Cloth.settle), outside the body, close to the optimized coarse one, with the
    same pattern area (to the discretisation of the curved outline). Its stretch is the coarse
    Newton equilibrium's: the same pattern, material and body carry the same weight (unconverged
    XPBD sweeps would leave it softer, stretched further: 1.6× here at 100 sweeps per step)."""
    opts = {"units": "cm", "iterations": 2, "edge_length": 0.07, **NO_BENDING_SEARCH}
    coarse = recover(SAMPLE, opts)
    fine = recover(SAMPLE, {**opts, "output_edge_length": 0.035})
    assert fine.metrics["output_vertices"] > 2.5 * coarse.metrics["output_vertices"]
    assert fine.metrics["optimized_vertices"] == coarse.metrics["output_vertices"]
    assert len(fine.garment_vertices) == fine.metrics["output_vertices"]
    assert not any("fine output" in w for w in fine.warnings)
    od = fine.metrics["output_drape"]
    assert od["criterion"] == "settled" and od["settled"]
    assert od["max_displacement_mm"] < 1e3 * RecoverOptions.from_config().output_settle_tol
    assert od["max_penetration_mm"] <= 0.4 and od["seam_gap_max_mm"] < 2.0
    assert coarse.metrics["output_drape"]["criterion"] == "equilibrium"
    assert fine.garment.total_area() == pytest.approx(coarse.garment.total_area(), rel=0.02)
    assert fine.metrics["chamfer_final_cm"] <= 1.2 * coarse.metrics["chamfer_final_cm"]
    assert fine.metrics["mesh_quality_min"] >= 0.2
    assert fine.metrics["chamfer_optimized_cm"] == pytest.approx(coarse.metrics["chamfer_final_cm"], rel=0.25)
    assert "chamfer_optimized_cm" not in coarse.metrics
    s_coarse, s_fine = (mean_edge_strain(r.garment_vertices, r.garment_uv, r.garment_faces) for r in (coarse, fine))
    assert 0 < s_coarse and 0 < s_fine <= 1.3 * s_coarse, (s_coarse, s_fine)


def test_an_unsettled_fine_mesh_keeps_the_coarse_result():
    """A fine drape that cannot settle within its step budget is reported and the coarse result
    (here, QUICK, the template's coarse equilibrium) is returned: nothing already produced is lost."""
    r = recover(SAMPLE, {**QUICK, "edge_length": 0.07, "output_edge_length": 0.035, "output_drape_steps": 10})
    assert any("fine output" in w and "budget" in w for w in r.warnings), r.warnings
    assert r.metrics["output_vertices"] == r.metrics["optimized_vertices"]
    assert r.metrics["output_drape"]["criterion"] == "equilibrium"

