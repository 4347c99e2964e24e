"""Built-in parametric templates: geometric properties of the pattern and its 3D placement
(the drape test waits for the simulator)."""
import numpy as np
import pytest

from diffavatar_core.pattern import triangle_quality_2d
from diffavatar_core.pattern.regularizers import CurvatureRegularizer, SeamLengthRegularizer
from diffavatar_core.pattern.templates import TEMPLATES, default_landmarks, make_template, template_spec

LM = default_landmarks()
OPENINGS = {"tshirt": {"hem", "neckline", "sleeve_left", "sleeve_right"},
            "longsleeve": {"hem", "neckline", "sleeve_left", "sleeve_right"},
            "dress": {"hem", "neckline", "sleeve_left", "sleeve_right"},
            "skirt": {"hem", "waist"}}


@pytest.fixture(scope="module", params=sorted(TEMPLATES))
def garment(request):
    return request.param, make_template(request.param, edge_length=0.03)


def test_pattern_quality_and_seams(garment):
    name, g = garment
    assert triangle_quality_2d(g.rest, g.faces).min() >= 0.30
    assert set(g.boundaries) == OPENINGS[name]
    # every sewn pair of edges has the same pattern length: Eq. 7 vanishes up to the chord vs
    # arc difference of curved edges sampled uniformly in arc length
    P = g.seam_edge_pairs()
    la = np.linalg.norm(g.rest[P[:, 1]] - g.rest[P[:, 0]], axis=1)
    lb = np.linalg.norm(g.rest[P[:, 3]] - g.rest[P[:, 2]], axis=1)
    assert np.max(np.abs(la - lb) / la) < 0.01
    assert CurvatureRegularizer(g).value_and_grad(g.rest)[0] < 1e-24
    assert SeamLengthRegularizer(g).value_and_grad(g.rest)[0] < 1e-6 * np.sum(la ** 4)


def test_placement_is_sewable_and_outside_the_body(garment):
    name, g = garment
    d = np.linalg.norm(g.x0[g.seams[:, 0]] - g.x0[g.seams[:, 1]], axis=1)
    assert d.max() < 0.30          # m: seam partners within reach of the sewing springs
    # front/back panels stay outside the torso cylinder between the hips and the chest
    girth = LM.hip_girth if name == "skirt" else LM.chest_girth
    axis = LM.hip_center if name == "skirt" else LM.chest_center
    body = np.isin(g.panel, [i for i, p in enumerate(g.panels) if p.name in ("front", "back")])
    band = body & (g.x0[:, 1] > LM.hip_center[1] - 0.05) & (g.x0[:, 1] < LM.chest_center[1])
    assert band.sum() > 20
    r = np.hypot(g.x0[band, 0] - axis[0], g.x0[band, 2] - axis[2])
    assert r.min() > girth / (2 * np.pi)
    # front in front, back behind, left sleeve on the body's left (+X)
    names = g.panel_names
    assert g.x0[g.panel == names.index("front"), 2].mean() > g.x0[g.panel == names.index("back"), 2].mean()
    if "sleeve_left" in names:
        xl = g.x0[g.panel == names.index("sleeve_left"), 0].mean()
        xr = g.x0[g.panel == names.index("sleeve_right"), 0].mean()
        assert xl > LM.shoulder_left[0] - 0.05 and xr < LM.shoulder_right[0] + 0.05
        # the sleeve tube surrounds the arm: its vertices are away from the arm axis
        sh, el = LM.shoulder_left, LM.elbow_left
        X = g.x0[g.panel == names.index("sleeve_left")]
        t = np.clip((X - sh) @ (el - sh) / np.dot(el - sh, el - sh), 0, 1)
        dist = np.linalg.norm(X - (sh + t[:, None] * (el - sh)), axis=1)
        assert np.median(dist) > 0.04


def test_measurements_change_the_pattern():
    short = template_spec("tshirt", length=0.6).panels[0]
    long_ = template_spec("tshirt", length=0.8).panels[0]
    assert np.ptp(long_.vertices[:, 1]) - np.ptp(short.vertices[:, 1]) == pytest.approx(0.2)
    with pytest.raises(ValueError, match="unknown template"):
        template_spec("kilt")
