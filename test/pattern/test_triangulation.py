"""Panel triangulation and garment assembly: exact tiling, quality, seam vertex counts."""
import numpy as np
import pytest

from diffavatar_core.pattern import (PanelSpec, PatternSpec, Placement, SeamSpec, build_garment,
                                     polygon_area, triangle_quality_2d, triangulate_polygon)


def _sample(P, h):
    out = []
    for i in range(len(P)):
        a, b = P[i], P[(i + 1) % len(P)]
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / h)))
        out.append(a + (np.arange(n) / n)[:, None] * (b - a))
    return np.vstack(out)


SHAPES = {
    "rectangle": np.array([[0, 0], [0.3, 0], [0.3, 0.2], [0, 0.2]], float),
    "L": np.array([[0, 0], [0.3, 0], [0.3, 0.1], [0.1, 0.1], [0.1, 0.3], [0, 0.3]], float),
    "trapezoid": np.array([[0, 0], [0.4, 0], [0.3, 0.25], [0.05, 0.2]], float),
}


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_polygon_is_tiled_exactly_with_quality(name):
    h = 0.015
    B = _sample(SHAPES[name], h)
    X, F = triangulate_polygon(B, h)
    assert np.array_equal(X[:len(B)], B)          # boundary kept, in order
    q = triangle_quality_2d(X, F)
    assert q.min() >= 0.30
    a, b, c = X[F[:, 0]], X[F[:, 1]], X[F[:, 2]]
    signed = 0.5 * ((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    assert np.all(signed > 0)                      # counter-clockwise, no inverted triangle
    assert abs(signed.sum() - polygon_area(B)) <= 1e-9 * polygon_area(B)
    # edge lengths near the target
    E = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    L = np.linalg.norm(X[E[:, 0]] - X[E[:, 1]], axis=1)
    assert 0.7 * h < np.median(L) < 1.4 * h


def test_circle():
    th = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    B = 0.08 * np.column_stack([np.cos(th), np.sin(th)])
    X, F = triangulate_polygon(B, 2 * np.pi * 0.08 / 50)
    assert triangle_quality_2d(X, F).min() >= 0.30


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="counter-clockwise"):
        triangulate_polygon(SHAPES["rectangle"][::-1], 0.02)
    with pytest.raises(ValueError, match="h:"):
        triangulate_polygon(SHAPES["rectangle"], 0.0)


def _tube(curved=False):
    """Front and back rectangles sewn along both sides: a tube with hem and waist openings."""
    w, hgt = 0.3, 0.25
    V = np.array([[0, 0], [w, 0], [w, hgt], [0, hgt]], float)
    front = PanelSpec("front", V, Placement([0, 0, 0.1], [1, 0, 0], [0, 1, 0], u0=w / 2),
                      boundary={0: "hem", 2: "waist"})
    back = PanelSpec("back", V, Placement([0, 0, -0.1], [-1, 0, 0], [0, 1, 0], u0=w / 2),
                     boundary={0: "hem", 2: "waist"})
    if curved:   # a longer curved side on the back: still sewn with equal counts
        back.curves[1] = np.array([[w + 0.05, hgt / 2]])
    seams = [SeamSpec("front", 1, "back", 3), SeamSpec("front", 3, "back", 1)]
    return PatternSpec("tube", [front, back], seams)


@pytest.mark.parametrize("curved", [False, True])
def test_assembled_tube(curved):
    g = build_garment(_tube(curved), edge_length=0.02)
    assert g.panel_names == ["front", "back"]
    assert triangle_quality_2d(g.rest, g.faces).min() >= 0.30
    # each side seam sews every vertex of one side edge to one of the other: equal counts
    nside = int(np.ceil(0.25 / 0.02 - 0.25)) + 1
    assert len(g.seams) == 2 * nside
    assert len(g.seam_edge_pairs()) == 2 * (nside - 1)
    # the seams join positions at the same height (pattern v) and are between panels
    assert np.all(g.panel[g.seams[:, 0]] != g.panel[g.seams[:, 1]])
    if not curved:
        assert np.allclose(g.x0[g.seams[:, 0], 1], g.x0[g.seams[:, 1], 1])
        assert np.allclose(g.x0[g.seams[:, 0], 0], g.x0[g.seams[:, 1], 0])
    # hem: one closed loop through both panels' bottom edges, each sewn corner once
    hem = g.boundaries["hem"]
    nbottom = int(np.ceil(0.3 / 0.02 - 0.25))
    assert len(hem) == 2 * nbottom and len(set(hem.tolist())) == len(hem)
    assert np.allclose(g.x0[hem, 1], 0.0)
    assert set(g.boundaries) == {"hem", "waist"}
    # the rest area is the sum of the panel polygons'
    areas = [abs(polygon_area(g.rest[p.loop])) for p in g.panels]
    assert abs(g.total_area() - sum(areas)) <= 1e-9 * sum(areas)
    start = g.panel_vertex_start
    assert start[0] == 0 and start[-1] == len(g.rest)


def _panel_quality(g):
    q = triangle_quality_2d(g.rest, g.faces)
    return {p.name: float(q[g.panel[g.faces[:, 0]] == i].min()) for i, p in enumerate(g.panels)}


def _check_garment(g):
    """Every panel: min q ≥ 0.30, area = its outline's to 1e-9; seams sew equal vertex counts."""
    bad = {k: round(v, 3) for k, v in _panel_quality(g).items() if v < 0.30}
    assert not bad, f"panels below q = 0.30: {bad}"
    for i, p in enumerate(g.panels):
        F = g.faces[g.panel[g.faces[:, 0]] == i]
        a, b, c = g.rest[F[:, 0]], g.rest[F[:, 1]], g.rest[F[:, 2]]
        signed = 0.5 * ((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
        assert np.all(signed > 0)
        poly = polygon_area(g.rest[p.loop])
        assert abs(signed.sum() - poly) <= 1e-9 * poly
    # sewn boundary edges pair one to one: a seam is a set of edge pairs, each edge used once
    P = g.seam_edge_pairs()
    assert len(P) > 0
    ea = {tuple(sorted(r)) for r in P[:, :2].tolist()}
    eb = {tuple(sorted(r)) for r in P[:, 2:].tolist()}
    assert len(ea) == len(P) and len(eb) == len(P)


@pytest.mark.parametrize("name,edge", [(n, 0.03) for n in ("tshirt", "longsleeve", "dress", "skirt", "pants")]
                         + [("tshirt", 0.012), ("pants", 0.012)])
def test_templates_quality(name, edge):
    from diffavatar_core.pattern.templates import TEMPLATES, make_template
    if name not in TEMPLATES:
        pytest.skip(f"no built-in template {name!r}")
    _check_garment(make_template(name, edge_length=edge))


@pytest.mark.parametrize("name,edge", [(n, 0.03) for n in ("shirt_mean", "hoody_mean", "dress_pencil", "js_mean_all")]
                         + [("shirt_mean", 0.012)])
def test_garmentcode_quality(name, edge):
    """GarmentCode panels have source edges of a few mm next to long ones (shirt_mean's sleeves,
    js_mean_all's trousers): the boundary is graded from them, so every panel reaches q ≥ 0.30."""
    from shared_data import shared_file
    from diffavatar_core.pattern.garmentcode import load_garmentcode
    g = load_garmentcode(shared_file("garmentcode", f"{name}_specification.json"), edge_length=edge)
    _check_garment(g)


def test_graded_boundary_next_to_a_short_edge():
    """A 4 mm edge between long ones: the long edges' spacing grows from 4 mm towards h, the
    mesh keeps q ≥ 0.30, and a seam partner of a graded edge gets the same fractions."""
    V = np.array([[0, 0], [0.3, 0], [0.3, 0.2], [0.004, 0.2], [0, 0.2]], float)
    a = PanelSpec("a", V, Placement([0, 0, 0], [1, 0, 0], [0, 1, 0]))
    b = PanelSpec("b", np.array([[0, 0], [0.3, 0], [0.3, 0.2], [0, 0.2]], float),
                  Placement([0, 0, -0.1], [-1, 0, 0], [0, 1, 0]))
    g = build_garment(PatternSpec("t", [a, b], [SeamSpec("a", 2, "b", 0)]), edge_length=0.03)
    _check_garment(g)
    loop = g.panels[0].loop
    L = np.linalg.norm(g.rest[np.roll(loop, -1)] - g.rest[loop], axis=1)
    assert L.min() == pytest.approx(0.004, rel=1e-6) and L.max() < 0.03 * 1.01
    # neighbouring boundary segments differ by at most the grading (plus rounding of counts)
    ratio = np.maximum(L / np.roll(L, 1), np.roll(L, 1) / L)
    assert ratio.max() < 1.6
    # the seam's two sides (0.296 and 0.3 m) have equal counts at the same fractions: every
    # pair of sewn segments has the ratio of the edge lengths
    S = g.seam_edge_pairs()
    la = np.linalg.norm(g.rest[S[:, 1]] - g.rest[S[:, 0]], axis=1)
    lb = np.linalg.norm(g.rest[S[:, 3]] - g.rest[S[:, 2]], axis=1)
    assert np.allclose(la / lb, 0.296 / 0.3, rtol=1e-6) and la.min() < 0.01
