"""Built-in parametric templates: geometric properties of the pattern and its 3D placement
(the drapes: test_template_drapes.py and test/sim/test_drape_cli.py)."""
import numpy as np
import pytest

from diffavatar_core.pattern import triangle_quality_2d
from diffavatar_core.pattern.regularizers import CurvatureRegularizer, SeamLengthRegularizer
from diffavatar_core.pattern.templates import TEMPLATES, default_landmarks, make_template, template_spec

LM = default_landmarks()
OPENINGS = {"tshirt": {"hem", "neckline", "sleeve_left", "sleeve_right"},
            "polo": {"hem", "neckline", "sleeve_left", "sleeve_right"},
            "longsleeve": {"hem", "neckline", "sleeve_left", "sleeve_right"},
            "dress": {"hem", "neckline", "sleeve_left", "sleeve_right"},
            "skirt": {"hem", "waist"},
            "pants": {"waist", "leg_left", "leg_right"}}   # config/labels.yaml garment_openings


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
    # (the polo's straight collar base is sewn to curved necklines: there the chords of the
    # arc-length samples differ by up to ~0.2%, i.e. (la² − lb²)² ≤ 4·(2e-3)²·l⁴ per pair)
    tol = 2e-5 if name == "polo" else 1e-6
    assert SeamLengthRegularizer(g).value_and_grad(g.rest)[0] < tol * np.sum(la ** 4)


def test_placement_is_sewable_and_outside_the_body(garment):
    name, g = garment
    if name == "pants":
        pytest.skip("trousers have leg panels: see test_pants_placement")
    d = np.linalg.norm(g.x0[g.seams[:, 0]] - g.x0[g.seams[:, 1]], axis=1)
    assert d.max() < 0.30          # m: seam partners within reach of the sewing springs
    # front/back panels stay outside the torso cylinder between the hips and the chest
    girth = LM.hip_girth if name == "skirt" else LM.chest_girth
    axis = LM.hip_center if name == "skirt" else LM.chest_center
    body = np.isin(g.panel, [i for i, p in enumerate(g.panels) if p.name in ("front", "back")])
    band = body & (g.x0[:, 1] > LM.hip_center[1] - 0.05) & (g.x0[:, 1] < LM.chest_center[1])
    assert band.sum() > 20
    r = np.hypot(g.x0[band, 0] - axis[0], g.x0[band, 2] - axis[2])
    if name == "skirt":   # laid on the torso's section at each height: waist → hip girth
        girth = np.interp(g.x0[band, 1], [LM.hip_center[1], LM.waist_center[1]], [LM.hip_girth, LM.waist_girth])
    assert np.all(r > girth / (2 * np.pi))
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


def test_templates_stand_where_the_body_stands(garment):
    """Every template is laid out around the body's landmarks wherever the body stands: for the
    same body moved by t (a scan off its rig's origin; the body fit's translation), the 3D layout
    moves by t — its centroid and bounding box (the triangulation may differ at round-off). The
    skirt and the trousers' torso part were centred on x = 0 (a body fitted 0.34 m off along X got
    a skirt beside it, which fell 12 m and was returned as a result)."""
    from diffavatar_core.body import BodyModel
    name, _ = garment
    model = BodyModel.default()
    p, q = model.zero_params(), model.zero_params()
    t = np.array([0.31, -0.07, 0.12])
    q.translation[:] = t
    a = make_template(name, landmarks=model.landmarks(p), edge_length=0.05)
    b = make_template(name, landmarks=model.landmarks(q), edge_length=0.05)
    np.testing.assert_allclose(b.x0.mean(axis=0), a.x0.mean(axis=0) + t, atol=1e-4)
    np.testing.assert_allclose(b.x0.min(axis=0), a.x0.min(axis=0) + t, atol=1e-4)
    np.testing.assert_allclose(b.x0.max(axis=0), a.x0.max(axis=0) + t, atol=1e-4)


def test_measurements_change_the_pattern():
    short = template_spec("tshirt", length=0.6).panels[0]
    long_ = template_spec("tshirt", length=0.8).panels[0]
    assert np.ptp(long_.vertices[:, 1]) - np.ptp(short.vertices[:, 1]) == pytest.approx(0.2)
    with pytest.raises(ValueError, match="unknown template"):
        template_spec("kilt")


def test_pants_pattern_and_placement():
    """Trousers: four panels (front/back × left/right), the openings the label map names for
    the 'pants' class, side seams, inseams and the centre front/back seams through the crotch;
    each leg placed as a tube around its leg axis, the seat around the hips."""
    import yaml
    from shared_data import REPO
    labels = yaml.safe_load((REPO / "config" / "labels.yaml").read_text())
    g = make_template("pants", edge_length=0.03)
    assert set(g.boundaries) == set(labels["garment_openings"]["pants"])
    assert sorted(g.panel_names) == ["back_left", "back_right", "front_left", "front_right"]
    # seam partners start on the same 3D positions (the placement maps them together)
    d = np.linalg.norm(g.x0[g.seams[:, 0]] - g.x0[g.seams[:, 1]], axis=1)
    assert np.median(d) < 1e-3 and d.max() < 0.06
    pid = {n: i for i, n in enumerate(g.panel_names)}
    pairs = {tuple(sorted((g.panel_names[g.panel[a]], g.panel_names[g.panel[b]]))) for a, b in g.seams}
    assert pairs == {("back_left", "front_left"), ("back_right", "front_right"),
                     ("front_left", "front_right"), ("back_left", "back_right")}
    # left leg on +X, front panels in front of the back ones
    for side, sgn in (("left", 1), ("right", -1)):
        assert sgn * g.x0[g.panel == pid[f"front_{side}"], 0].mean() > 0.05
        assert g.x0[g.panel == pid[f"front_{side}"], 2].mean() > g.x0[g.panel == pid[f"back_{side}"], 2].mean()
    # each leg opening surrounds its ankle, above it; the waist surrounds the waist centre
    for side, ankle in (("left", LM.ankle_left), ("right", LM.ankle_right)):
        X = g.x0[g.boundaries[f"leg_{side}"]]
        assert np.all(X[:, 1] > ankle[1])
        c = X.mean(0)
        assert np.hypot(c[0] - ankle[0], c[2] - ankle[2]) < 0.05
        assert np.min(np.hypot(X[:, 0] - ankle[0], X[:, 2] - ankle[2])) > 0.04
    W = g.x0[g.boundaries["waist"]]
    assert np.allclose(W[:, 1], LM.waist_center[1], atol=0.01)
    r = np.hypot(W[:, 0] - LM.waist_center[0], W[:, 2] - LM.waist_center[2])
    assert r.min() > LM.waist_girth / (2 * np.pi)
    # the crotch seam runs below the hips: the lowest point of the centre seams is between the legs
    centre = g.seams[np.isin(g.panel[g.seams[:, 0]], [pid["front_left"], pid["back_left"]])
                     & np.isin(g.panel[g.seams[:, 1]], [pid["front_right"], pid["back_right"]])]
    low = g.x0[centre.ravel()][:, 1].min()
    assert LM.knee_left[1] < low < LM.hip_center[1]
    # the waist is narrower than the hips (the trousers hang on them)
    spec = template_spec("pants")
    waist = sum(p.edge_length(k) for p in spec.panels for k, nm in p.boundary.items() if nm == "waist")
    assert LM.waist_girth < waist < LM.hip_girth


def test_polo_placket_fills_the_notch_cut_for_it():
    """The placket is a 3 cm × 12 cm rectangle; front + placket cover the un-notched front of
    the same measurements (the t-shirt's front with the polo's neckline) — up to the chords of
    the sampled neckline — and the placket is sewn on three sides with equal vertex counts."""
    def panel_area(g, name):
        k = [p.name for p in g.panels].index(name)
        F = g.faces[g.panel[g.faces[:, 0]] == k]
        a, b, c = g.rest[F[:, 0]], g.rest[F[:, 1]], g.rest[F[:, 2]]
        return float(0.5 * np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]).sum())

    polo = make_template("polo", edge_length=0.02)
    shirt = make_template("tshirt", edge_length=0.02, neck_width=0.18, front_neck_depth=0.06)
    assert panel_area(polo, "placket") == pytest.approx(0.03 * 0.12, rel=1e-9)
    assert panel_area(polo, "front") + panel_area(polo, "placket") == pytest.approx(panel_area(shirt, "front"), rel=1e-3)
    spec = template_spec("polo")
    panels = {p.name: np.asarray(p.vertices, float) for p in spec.panels}
    to_front = [s for s in spec.seams if {s.panel_a, s.panel_b} == {"placket", "front"}]
    assert len(to_front) == 3 and sum("placket" in (s.panel_a, s.panel_b) for s in spec.seams) == 4
    for s in to_front:   # placed where the notch was: each sewn edge pair coincides, reversed
        A, B = panels[s.panel_a], panels[s.panel_b]
        np.testing.assert_allclose(A[s.edge_a], B[(s.edge_b + 1) % len(B)], atol=1e-12)
        np.testing.assert_allclose(A[(s.edge_a + 1) % len(A)], B[s.edge_b], atol=1e-12)


@pytest.mark.parametrize("Wb,armhole", [(0.12, 0.22), (0.16, 0.25), (0.30, 0.20)])
def test_sleeve_cap_height_gives_the_armhole_length(Wb, armhole):
    """The sleeve cap's half-curve (as _top_spec draws it) at the solved height has the armhole's
    length, to 1e-12 m; a bicep too wide for the armhole is refused with the reason."""
    from diffavatar_core.pattern.spec import PanelSpec
    from diffavatar_core.pattern.templates import _solve_cap_height
    h = _solve_cap_height(Wb, armhole)
    cap = PanelSpec("c", np.array([[Wb / 2, 0], [0, h], [-Wb / 2, 0]]), None, curves={0: [[Wb / 4 + 0.02, 0.75 * h]]})
    assert abs(cap.edge_length(0) - armhole) < 1e-12
    with pytest.raises(ValueError, match="too wide"):
        _solve_cap_height(Wb, 0.5 * Wb)
