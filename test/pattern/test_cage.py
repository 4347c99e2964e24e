"""Control-cage handles and mean value coordinates (paper §4.2.2)."""
import numpy as np
import pytest

from diffavatar_core.pattern import PanelSpec, PatternSpec, Placement, SeamSpec, build_garment
from diffavatar_core.pattern.cage import build_cage, cage_handles, mean_value_coordinates


def _sample(P, n_per_edge):
    return np.vstack([P[i] + (np.arange(n_per_edge) / n_per_edge)[:, None] * (P[(i + 1) % len(P)] - P[i])
                      for i in range(len(P))])


RECT = np.array([[0, 0], [0.4, 0], [0.4, 0.3], [0, 0.3]], float)
LSHAPE = np.array([[0, 0], [0.3, 0], [0.3, 0.1], [0.1, 0.1], [0.1, 0.3], [0, 0.3]], float)


def test_rectangle_gets_its_four_corners():
    B = _sample(RECT, 7)
    h = cage_handles(B)
    assert np.array_equal(B[h], RECT)


def test_l_shape_gets_its_six_corners():
    B = _sample(LSHAPE, 5)
    h = cage_handles(B)
    assert np.array_equal(B[h], LSHAPE)


def test_circle_hull_vertices_are_handles():
    th = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    B = np.column_stack([np.cos(th), np.sin(th)])
    assert len(cage_handles(B)) == 40
    # a larger threshold than the turning angle (9°) still keeps them all: they are on the hull
    assert len(cage_handles(B, 45.0)) == 40


@pytest.mark.parametrize("outline", [RECT, LSHAPE, np.array([[0, 0], [0.03, 0], [0.03, 0.12], [0, 0.12]], float)],
                         ids=["rectangle", "l_shape", "placket_3x12cm"])
def test_round_off_does_not_change_the_handles(outline):
    """Noise of 1e-13 m (another CPU's round-off) leaves every outline's handles as they were.
    Before stop 37 the hull's monotone chain took a straight vertical edge's points, whose x
    then differed by 1e-13 m, in noise's order and kept one from the middle of the edge in place
    of its end; and its absolute area tolerance let noise make a small panel's edge points
    corners: the t-shirt's and long sleeve's cages had 80–89 handles instead of 75 under
    test/roundoff.py (the polo's 106–111 instead of 97)."""
    B = _sample(outline, 6)
    exact = cage_handles(B)
    assert np.array_equal(B[exact], outline)
    for seed in range(40):
        noisy = B + np.random.default_rng(seed).normal(scale=1e-13, size=B.shape)
        assert np.array_equal(cage_handles(noisy), exact), seed


def test_round_off_does_not_change_the_built_in_templates_cages():
    """Every built-in template's rest shape with test/roundoff.py's noise (1e-13 m) gets the
    cage of the exact one."""
    from diffavatar_core.body.model import BodyModel
    from diffavatar_core.pattern.templates import make_template
    model = BodyModel.default()
    lm = model.landmarks(model.zero_params())
    for n in ("tshirt", "longsleeve", "polo", "dress", "skirt", "pants"):
        g = make_template(n, landmarks=lm, edge_length=0.04)
        exact = build_cage(g).handles
        rest = g.rest.copy()
        for seed in (1, 2, 3, 4):
            g.rest[...] = rest + np.random.default_rng(seed).normal(scale=1e-13, size=rest.shape)
            assert np.array_equal(build_cage(g).handles, exact), (n, seed)


def test_threshold_is_configurable():
    # a shallow concave notch (turn 2·atan(0.02/0.2) ≈ 11.4°) is a handle at 10°, not at 15°
    B = np.array([[0, 0], [0.2, 0.02], [0.4, 0], [0.4, 0.3], [0, 0.3]], float)
    assert 1 in cage_handles(B, 10.0)
    assert 1 not in cage_handles(B, 15.0)


@pytest.mark.parametrize("cage", [RECT, LSHAPE])
def test_mvc_partition_of_unity_reproduction_and_linear_precision(cage):
    rng = np.random.default_rng(0)
    B = _sample(cage, 6)
    pts = np.vstack([B, rng.uniform(0, 0.3, size=(200, 2)), cage])   # incl. boundary and outside points
    W = mean_value_coordinates(cage, pts)
    assert np.allclose(W.sum(1), 1.0, atol=1e-12)
    assert np.max(np.abs(W @ cage - pts)) <= 1e-9 * np.abs(pts).max()
    A = np.array([[1.3, 0.4], [-0.2, 0.8]])
    t = np.array([0.05, -0.7])
    mapped = W @ (cage @ A.T + t)
    assert np.max(np.abs(mapped - (pts @ A.T + t))) <= 1e-9
    # interpolation on the cage's vertices
    k = len(pts) - len(cage)
    assert np.allclose(W[k:], np.eye(len(cage)))


def test_mvc_of_points_just_off_an_edge_are_the_edge_interpolation():
    """A pattern's boundary vertex between two handles lies on the cage edge up to round-off. At
    1e-14 ... 1e-6 m off the edge (either side; the on-edge tolerance is 1e-12 of the cage's
    size) the coordinates stay finite, reproduce the point and tend to the edge's linear
    interpolation. tan(α/2) = sin α / (1 + cos α) was 0/0 there (a 1e-13 m perturbation of the
    polo's pattern gave a NaN row)."""
    cage = np.array([[0.0, 0.0], [0.3, 0.0], [0.3, 0.5], [0.0, 0.5]])   # m
    s = 0.37
    on = (1 - s) * cage[1] + s * cage[2]                                 # on the edge 1 → 2
    offs = np.array([1e-14, 1.5e-14, 3e-13, 1e-10, 1e-8, 1e-6])
    pts = np.vstack([on + np.outer(offs, [1.0, 0.0]), on - np.outer(offs, [1.0, 0.0])])
    W = mean_value_coordinates(cage, pts)
    assert np.isfinite(W).all()
    assert np.allclose(W.sum(1), 1.0, atol=1e-12)
    assert np.max(np.abs(W @ cage - pts)) <= 1e-12
    edge = np.array([0.0, 1 - s, s, 0.0])
    dev = np.abs(W - edge).max(axis=1)
    assert (dev <= 1e3 * np.concatenate([offs, offs]) + 1e-12).all(), dev   # O(distance) m⁻¹


def test_garment_cage_reproduces_the_pattern_and_maps_gradients():
    V = np.array([[0, 0], [0.3, 0], [0.3, 0.25], [0, 0.25]], float)
    front = PanelSpec("front", V, Placement([0, 0, 0.1], [1, 0, 0], [0, 1, 0]), curves={2: [[0.15, 0.2]]})
    back = PanelSpec("back", V, Placement([0, 0, -0.1], [-1, 0, 0], [0, 1, 0]))
    g = build_garment(PatternSpec("t", [front, back], [SeamSpec("front", 1, "back", 3)]), edge_length=0.03)
    cage = build_cage(g)
    assert np.max(np.abs(cage.rest(cage.zeta0) - g.rest)) <= 1e-9 * np.abs(g.rest).max()
    # Eq. 5: ∂L/∂ζ = Wᵀ ∂L/∂x̄ — check on L = Σ c·x̄ against central differences
    rng = np.random.default_rng(1)
    C = rng.normal(size=g.rest.shape)
    gz = cage.grad_zeta(C)
    k, eps = 3, 1e-6
    Z = cage.zeta0.copy()
    Z[k, 0] += eps
    lp = np.sum(C * cage.rest(Z))
    Z[k, 0] -= 2 * eps
    lm = np.sum(C * cage.rest(Z))
    assert abs((lp - lm) / (2 * eps) - gz[k, 0]) <= 1e-6 * max(1.0, abs(gz[k, 0]))
    assert set(np.unique(cage.handle_panel)) == {0, 1}


def test_seam_partners_of_handles_are_handles():
    from diffavatar_core.pattern.templates import make_template
    g = make_template("tshirt", edge_length=0.04)
    cage = build_cage(g)
    h = np.zeros(len(g.rest), bool)
    h[cage.handles] = True
    assert np.array_equal(h[g.seams[:, 0]], h[g.seams[:, 1]])
    assert np.max(np.abs(cage.rest(cage.zeta0) - g.rest)) <= 1e-9 * np.abs(g.rest).max()
    assert len(cage.handles) < sum(len(p.loop) for p in g.panels)
