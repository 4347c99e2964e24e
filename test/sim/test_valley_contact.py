"""Contact over concave body edges (contact_normals="valley"; sim/body_collider.hpp,
BodyCollider::detect valleys). Over a valley the free space is above both faces' planes; a vertex
holding one plane — whichever face is closer ("face") — is pushed out of it into the other, and
re-detected it holds the other one: the solves alternate between two states and none is an
equilibrium of the planes detected at it (the skirt test fixture: 0.34 mm for ever, residual ~2,
all at valleys of 0.6–6°). With "valley" the quasi-static solves hold both planes there.
Geometry on an inverted pyramid (a bowl whose diagonals are valleys) and a pyramid (ridges); the
equilibrium adjoint through doubled contacts against central differences."""
import numpy as np
import pytest

from diffavatar_core import _core
from diffavatar_core.adjoint import equilibrium_gradient
from diffavatar_core.sim import Cloth, ClothMaterial
from diffavatar_core.sim.scenes import grid_sheet

SLOPE = np.tan(np.radians(4.0))   # the faces' slope; the diagonals' dihedral is ~3.3°


def _pyramid(sign, n=6, half=0.15):
    """y = sign·SLOPE·max(|x|, |z|) (m, Y up) on a (2n+1)² grid, each cell split along the diagonal
    through the apex's side so that the diagonals x = ±z are mesh edges: sign +1 a bowl (valleys),
    −1 a tent (ridges)."""
    t = np.linspace(-half, half, 2 * n + 1)
    X, Z = np.meshgrid(t, t, indexing="ij")
    V = np.column_stack([X.ravel(), sign * SLOPE * np.maximum(np.abs(X), np.abs(Z)).ravel(), Z.ravel()])
    idx = np.arange(V.shape[0]).reshape(X.shape)
    F = []
    for i in range(2 * n):
        for j in range(2 * n):
            a, b, c, d = idx[i, j], idx[i + 1, j], idx[i + 1, j + 1], idx[i, j + 1]
            if (i < n) == (j < n):   # cells on the x = z diagonal: split along it
                F += [[a, d, c], [a, c, b]]
            else:
                F += [[a, d, b], [b, d, c]]
    return V, np.array(F, np.int32)


def _sheet(body, height, n=11, size=0.2, contact_normals="valley", **kw):
    """A size² sheet (m) lying flat `height` above the origin, free (no pins), over `body`."""
    rest, F = grid_sheet(size, size, n, n)
    x0 = np.column_stack([rest[:, 0] - size / 2, np.full(len(rest), height), rest[:, 1] - size / 2])
    return Cloth(rest, F, x0, body=body, materials=kw.pop("materials", ClothMaterial(bend_stiffness=1e-5)),
                 contact_normals=contact_normals, **kw)


def _gaps(cloth):
    """Per contact: the vertex and its gap (m) to its face plane (thickness included)."""
    bv = np.asarray(cloth.control.body_vertices)
    bf = np.asarray(cloth.body_faces)
    x = np.asarray(cloth.x)
    out = []
    for v, t in cloth.solver.contact_pairs:
        a, b, d = bv[bf[t]]
        nrm = np.cross(b - a, d - a)
        nrm /= np.linalg.norm(nrm)
        out.append((v, nrm @ (x[v] - a) - cloth.model.thickness))
    return out


@pytest.mark.parametrize("normals", ["valley", "face"])
@pytest.mark.parametrize("sign", [1, -1])
def test_a_vertex_over_a_valley_holds_both_planes_and_over_a_ridge_one(sign, normals):
    """Points 2 mm above the surface: over the bowl's diagonals (valleys) the vertices within reach
    of both faces hold two planes, every other vertex one — its closest face's; over the tent's
    diagonals (ridges) every vertex holds one. With the face plane every vertex holds one."""
    V, F = _pyramid(sign)
    cloth = _sheet((V, F), 0.0, n=21, contact_normals=normals)
    x = np.array(cloth.x)
    x[:, 1] = sign * SLOPE * np.maximum(np.abs(x[:, 0]), np.abs(x[:, 2])) + 0.002
    cloth.reset(x)
    cloth.solver.detect_contacts(cloth.x, _core.SimParams())
    pairs = cloth.solver.contact_pairs
    per_vertex = np.bincount(pairs[:, 0], minlength=len(x))
    tri, _, _ = _core.contact_planes(V, F, x, False)
    assert (per_vertex >= 1).all()    # all within the contact reach
    closest = {(int(v), int(t)) for v, t in pairs}
    assert all((i, int(tri[i])) in closest for i in range(len(x)))
    # the faces' edges on the diagonals |x| = |z| (the creases; elsewhere neighbours are coplanar)
    on = np.isclose(np.abs(V[:, 0]), np.abs(V[:, 2]))
    creases = np.array([sum(on[f[k]] and on[f[(k + 1) % 3]] for k in range(3)) for f in F])
    if sign < 0 or normals == "face":
        assert per_vertex.max() == 1
    else:
        # 2 mm above a 2.5 cm face, every neighbour's plane is within reach (±14 mm)
        np.testing.assert_array_equal(per_vertex, 1 + creases[tri])
        assert (per_vertex >= 2).sum() >= 40
        for v, t in pairs:   # a second plane is a crease neighbour's
            assert t == tri[v] or len(set(F[t]) & set(F[tri[v]])) == 2


def test_a_sheet_in_a_bowl_reaches_an_equilibrium_of_its_own_contact_planes():
    """A free sheet dropped into the bowl converges; 3 mm of noise added (an optimizer's warm
    start), every solve from where the last ended, with the planes detected there, ends at an
    equilibrium of the planes detected at its end (residual ≤ 1e-8), above every plane it holds
    within 0.1 mm of the collision thickness. Each solve is tied to its start (refine without an
    anchor), so the free sheet's sliding relaxes over the solves: < 1 µm by the tenth. With one
    plane per vertex ("face") the drape did not converge (relative residual 1.9e4) and the re-solves
    carried the sheet through the bowl."""
    V, F = _pyramid(1)
    cloth = _sheet((V, F), 0.02)
    r = cloth.drape(max_steps=600, residual_tol=1e-8, refine_iterations=200)
    assert r.converged, r
    x = np.array(cloth.x)
    x += np.random.default_rng(0).normal(scale=0.003, size=x.shape)
    cloth.reset(x)
    moves = []
    for _ in range(10):
        x0 = np.array(cloth.x)
        _, res = cloth.refine(keep_anchor=False, keep_contacts=False, residual_tol=1e-8, refine_iterations=200)
        assert res <= 1e-8
        moves.append(float(np.abs(np.array(cloth.x) - x0).max()))
        assert cloth.own_contacts_residual() <= 1e-8
        assert min(g for _, g in _gaps(cloth)) > -1e-4
    assert moves[-1] < 1e-6, moves
    assert np.bincount(cloth.solver.contact_pairs[:, 0]).max() >= 2    # it does lie across the valleys


def test_valley_contacts_need_the_face_plane():
    V, F = _pyramid(1)
    with pytest.raises(ValueError, match="valley"):
        _core.build_cloth_model(4, np.array([[0, 1, 2], [0, 2, 3]], np.int32),
                                np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]), np.zeros(2, np.int32),
                                np.zeros((0, 2), np.int32), [], F, 0.15, 0.004, 2e3, 1e-5, np.zeros(0), False, True, True)
    assert _sheet((V, F), 0.02).model.valley_contact and not _sheet((V, F), 0.02, contact_normals="face").model.valley_contact


def test_equilibrium_adjoint_through_valley_contacts_matches_central_differences():
    """dφ/d(body vertices) of φ = Σ W·x* for the sheet resting in the bowl (contacts held, soft
    k_c = 20 N/m so no gap crosses 0 within the steps) with vertices holding two planes, against
    central differences in double precision, on the body vertices of doubled contacts' faces."""
    V, F = _pyramid(1)
    mat = ClothMaterial(warp_compliance=2e-2, weft_compliance=3e-2, shear_compliance=5e-2, bend_stiffness=2e-5)
    cloth = _sheet((V, F), 0.02, n=9, materials=mat, contact_stiffness=20.0)
    assert cloth.drape(max_steps=3000, residual_tol=1e-10, refine_iterations=200).converged
    # settle on its own planes, then hold them
    for _ in range(4):
        cloth.refine(keep_anchor=False, keep_contacts=False, residual_tol=1e-10, refine_iterations=200)
    pairs = cloth.solver.contact_pairs
    doubled = np.flatnonzero(np.bincount(pairs[:, 0]) >= 2)
    assert len(doubled) >= 2
    W = np.random.default_rng(1).standard_normal(cloth.x.shape)
    g = equilibrium_gradient(cloth, W)["body_vertices"]
    x_star, body0 = np.array(cloth.x), np.array(cloth.control.body_vertices)
    body = sorted({int(b) for v, t in pairs if v in set(doubled.tolist()) for b in F[t]})
    rng = np.random.default_rng(2)
    h = 1e-7
    num, adj = [], []
    for i in rng.choice(body, min(6, len(body)), replace=False):
        for k in range(3):
            side = []
            for s in (h, -h):
                bp = body0.copy()
                bp[i, k] += s
                cloth.state.x = x_star    # the held contacts stay (reset would not change them either)
                cloth.set_control(body_vertices=bp)
                _, res = cloth.refine(keep_anchor=True, keep_contacts=True, residual_tol=1e-10, refine_iterations=200)
                assert res <= 1e-9
                side.append(float(np.sum(W * cloth.x)))
            cloth.state.x = x_star
            cloth.set_control(body_vertices=body0)
            num.append((side[0] - side[1]) / (2 * h))
            adj.append(g[i, k])
    num, adj = np.array(num), np.array(adj)
    assert np.abs(num).max() > 1e-3   # the body really moves the sheet
    assert np.abs(adj - num).max() <= 1e-4 * np.abs(num).max(), (adj, num)
