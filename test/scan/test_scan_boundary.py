"""Boundary loops (tracing, orientation, descriptors) and the classification rules of each
garment class on hand-made loops with known answers."""
import numpy as np
import pytest

from diffavatar_core.scan.boundary import LoopGeometry, boundary_loops, classify_loops, start_at_front
from diffavatar_core.scan.cleaning import (compact, components_to_drop, degenerate_or_duplicate_faces,
                                           merge_duplicate_vertices, small_components)


def _grid(n, hole=None):
    """(V, F) of an n×n-cell unit square grid in the XY plane (normals +Z), optionally without
    the cells in `hole` (a set of (i, j))."""
    x = np.linspace(0, 1, n + 1)
    X, Y = np.meshgrid(x, x, indexing="ij")
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    idx = lambda i, j: i * (n + 1) + j  # noqa: E731
    F = []
    for i in range(n):
        for j in range(n):
            if hole and (i, j) in hole:
                continue
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            F += [[a, b, c], [a, c, d]]
    return V, np.array(F)


def test_square_with_a_hole_has_two_loops_following_the_winding():
    V, F = _grid(4, hole={(1, 1), (1, 2), (2, 1), (2, 2)})
    loops = boundary_loops(F)
    assert sorted(len(lp) for lp in loops) == [8, 16]
    directed = {tuple(e) for f in F for e in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    for lp in loops:
        assert all((a, b) in directed for a, b in zip(lp, np.roll(lp, -1)))
        g = LoopGeometry.of(V[lp])
        # outer loop counter-clockwise about +Z (like the faces), the hole clockwise
        assert g.normal[2] == pytest.approx(1.0 if len(lp) == 16 else -1.0)
        assert g.perimeter == pytest.approx(4.0 if len(lp) == 16 else 2.0)
        np.testing.assert_allclose(g.centroid, [0.5, 0.5, 0.0], atol=1e-12)


def test_closed_surface_has_no_loops_and_start_at_front():
    import trimesh
    m = trimesh.creation.icosphere(subdivisions=1)
    assert boundary_loops(np.asarray(m.faces)) == []
    V = np.array([[0, 0, 0], [1, 0, 0.5], [1, 1, 2.0], [0, 1, 2.0]])
    np.testing.assert_array_equal(start_at_front(np.array([0, 1, 2, 3]), V), [2, 3, 0, 1])


def test_inconsistent_winding_still_gives_one_loop():
    V, F = _grid(3)
    F[::3] = F[::3, ::-1]
    loops = boundary_loops(F)
    assert len(loops) == 1 and len(loops[0]) == 12


def _ring(center, radius, axis, n=40):
    t = 2 * np.pi * np.arange(n) / n
    u = np.array([1.0, 0, 0]) if abs(axis[0]) < 0.9 else np.array([0, 1.0, 0])
    a = np.cross(axis, u)
    a /= np.linalg.norm(a)
    b = np.cross(axis, a)
    return np.asarray(center) + radius * (np.outer(np.cos(t), a) + np.outer(np.sin(t), b))


Y = np.array([0.0, 1.0, 0.0])
X = np.array([1.0, 0.0, 0.0])


def test_circle_descriptors():
    g = LoopGeometry.of(_ring([0.1, 1.0, 0.2], 0.2, Y, n=2000))
    assert g.perimeter == pytest.approx(2 * np.pi * 0.2, rel=1e-5)
    np.testing.assert_allclose(g.centroid, [0.1, 1.0, 0.2], atol=1e-12)
    assert abs(g.normal[1]) == pytest.approx(1.0) and g.horizontal


def test_skirt_waist_and_hem_with_a_hole():
    loops = [_ring([0, 0.6, 0], 0.35, Y),       # hem (wide, low)
             _ring([0, 1.0, 0], 0.12, Y),       # waist
             _ring([0.1, 0.8, 0.15], 0.03, np.array([0, 0, 1.0]))]   # a hole
    V = np.concatenate(loops)
    found, holes = classify_loops(loops, ("waist", "hem"), V, 0.1)
    assert found == {"hem": 0, "waist": 1} and holes == [2]


def test_pants_waist_and_legs_left_on_plus_x():
    loops = [_ring([-0.1, 0.1, 0], 0.06, Y),    # right leg (-X)
             _ring([0, 1.0, 0], 0.13, Y),       # waist
             _ring([0.1, 0.1, 0], 0.06, Y)]     # left leg (+X)
    V = np.concatenate([loops[1], loops[0] * [1.6, 1, 1], loops[2] * [1.6, 1, 1]])
    found, holes = classify_loops(loops, ("waist", "leg_left", "leg_right"), V, 0.1)
    assert found == {"waist": 1, "leg_left": 2, "leg_right": 0} and holes == []


def test_upper_garment_rules_prefer_the_most_lateral_loop_and_ignore_short_ones():
    loops = [_ring([0, 1.0, 0], 0.17, Y),          # hem
             _ring([0.0, 1.6, 0], 0.08, Y),        # neckline
             _ring([0.35, 1.4, 0], 0.06, X),       # sleeve_left
             _ring([-0.35, 1.4, 0], 0.06, X),      # sleeve_right
             _ring([0.2, 1.25, 0], 0.04, X),       # under-arm occlusion hole, lateral but inner
             _ring([0.0, 1.7, 0.05], 0.01, Y)]     # tiny hole above the neckline
    V = np.concatenate(loops)
    found, holes = classify_loops(loops, ("hem", "neckline", "sleeve_left", "sleeve_right"), V, 0.1)
    assert found == {"hem": 0, "neckline": 1, "sleeve_left": 2, "sleeve_right": 3}
    assert holes == [4, 5]


def test_cleaning_helpers():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1e-8, 0, 0], [5, 5, 5.0]])
    F = np.array([[0, 1, 2], [3, 1, 2], [2, 1, 0]])
    V2, F2, o2n = merge_duplicate_vertices(V, F, 1e-6)
    assert len(V2) == 4 and o2n[3] == 0 and np.array_equal(V2[0], V[0])
    bad, n_deg, n_dup = degenerate_or_duplicate_faces(V2, F2, 0.0)
    assert (n_deg, n_dup) == (0, 2) and bad.tolist() == [False, True, True]
    Vg, Fg = _grid(2)
    Vs = np.concatenate([Vg, Vg[:3] * 0.01 + 3])
    Fs = np.concatenate([Fg, [[len(Vg), len(Vg) + 1, len(Vg) + 2]]])
    drop, dropped = small_components(Vs, Fs, 0.01)
    assert drop.tolist() == [False] * len(Fg) + [True] and len(dropped) == 1
    assert dropped[0].faces == 1 and dropped[0].vertices == 3
    Vc, Fc, kept = compact(Vs, Fs, ~drop)
    np.testing.assert_array_equal(Vc, Vg)
    np.testing.assert_array_equal(Fc, Fg)
    np.testing.assert_array_equal(kept, np.arange(len(Vg)))


@pytest.mark.parametrize("scale", [1.0, 100.0])
def test_a_small_part_near_the_large_ones_is_kept(scale):
    """A unit square (diagonal √2) and two small triangles: one 2 cm beyond its edge (a piece
    cut off by occlusion: within 3% of the diagonal, 4.2 cm), one 20 cm away (a floating
    fragment). With keep_fraction 0.03 only the far one is dropped; the same at 100× the size
    (the rule is relative, as a scan read in the wrong units needs); without it both are."""
    Vg, Fg = _grid(2)
    tri = np.array([[0, 0, 0], [0.01, 0, 0], [0, 0.01, 0]])
    V = np.concatenate([Vg, tri + [1.02, 0.5, 0], tri + [1.2, 0.5, 0]]) * scale
    F = np.concatenate([Fg, [[len(Vg), len(Vg) + 1, len(Vg) + 2]], [[len(Vg) + 3, len(Vg) + 4, len(Vg) + 5]]])
    drop, dropped, near = components_to_drop(V, F, 0.01, 0.03)
    assert drop.tolist() == [False] * len(Fg) + [False, True]
    assert len(dropped) == 1 and len(near) == 1
    np.testing.assert_allclose(near[0].centroid, (np.array([1.02, 0.5, 0]) + 0.01 / 3 * np.array([1, 1, 0])) * scale)
    np.testing.assert_allclose(dropped[0].centroid, (np.array([1.2, 0.5, 0]) + 0.01 / 3 * np.array([1, 1, 0])) * scale)
    drop, _ = small_components(V, F, 0.01)
    assert drop.tolist() == [False] * len(Fg) + [True, True]


@pytest.mark.parametrize("hole,sizes", [({(1, 1), (2, 2)}, [4, 4, 16]),    # two holes touching at a corner
                                        ({(1, 2), (2, 1)}, [4, 4, 16]),    # the other diagonal
                                        ({(0, 0), (1, 1)}, [4, 16])])      # a hole touching the rim
def test_loops_touching_at_a_vertex_come_out_separate(hole, sizes):
    V, F = _grid(4, hole=hole)
    loops = boundary_loops(F, V)
    assert sorted(len(lp) for lp in loops) == sizes
    for lp in loops:
        assert len(np.unique(lp)) == len(lp)                      # no figure-of-eight
    # the 4-vertex loops are exactly the removed cells' corners
    cells = sorted(sorted(lp.tolist()) for lp in loops if len(lp) == 4)
    n = 5
    want = sorted(sorted([i * n + j, (i + 1) * n + j, (i + 1) * n + j + 1, i * n + j + 1])
                  for i, j in hole if 0 < i < 3 and 0 < j < 3)
    assert cells == want
