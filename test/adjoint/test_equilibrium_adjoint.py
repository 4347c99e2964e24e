"""Equilibrium adjoint (issue 4, mode 2) against central finite differences of the converged
drape, for every control kind: rest coordinates, stretch compliances, bending stiffness, body
vertices; plus the rest-translation invariant and loss scaling."""
import numpy as np
import pytest

from diffavatar_core.adjoint import equilibrium_gradient
from diffavatar_core.sim import ClothMaterial
from diffavatar_core.sim.scenes import sheet_against_sphere

TOL = 1e-10


@pytest.fixture(scope="module", params=[("face", False), ("smooth", False), ("face", True), ("smooth", True)],
                ids=["face", "smooth", "face-self-anchored", "smooth-self-anchored"])
def scene(request):
    """Both contact planes (sim/contact_kernel.hpp); with the smooth one the body gradient also
    goes through the vertex normals and the held contacts' barycentrics, which follow the body.
    Self-anchored: the drape re-anchored at itself (Cloth.self_anchor), the state a recovery's
    output is left in — anchors at the equilibrium, so the anchor springs carry no force there
    but still stiffen the Hessian the adjoint solves with."""
    normals, self_anchored = request.param
    mat = ClothMaterial(warp_compliance=2e-2, weft_compliance=3e-2, shear_compliance=5e-2, bend_stiffness=2e-5)
    # A soft contact (k_c = 20 N/m) keeps every active contact's gap C well away from the kink
    # of the one-sided penalty at C = 0, so the FD steps below never toggle a contact.
    cloth = sheet_against_sphere(n=8, materials=mat, contact_stiffness=20.0, contact_normals=normals)
    r = cloth.drape(max_steps=3000, residual_tol=TOL, refine_iterations=200)
    assert r.converged, r
    if self_anchored:
        assert cloth.self_anchor(TOL, rounds=10, tol=1e-8) <= 1e-8
        assert np.abs(np.array(cloth.solver.anchor) - cloth.x).max() <= 1e-8
    assert cloth.solver.num_contacts > 0
    rng = np.random.default_rng(1)
    W = rng.standard_normal(cloth.x.shape)
    return cloth, W, cloth.x.copy(), cloth.control


def _phi_after(cloth, W, x_star, control, **change):
    cloth.state.x = x_star
    cloth.set_control(**change)
    # same forward computation: anchors and contact set (their body triangles) held fixed
    it, res = cloth.refine(keep_anchor=True, keep_contacts=True, residual_tol=TOL, refine_iterations=200)
    assert res <= TOL * 10, res
    phi = float(np.sum(W * cloth.x))
    cloth.state.x = x_star
    cloth.set_control(rest=control.rest, stretch_compliance=control.stretch_compliance,
                      bend_stiffness=control.bend_stiffness, body_vertices=control.body_vertices)
    return phi


def _check(adj, num):
    adj, num = np.asarray(adj), np.asarray(num)
    floor = 1e-3 * np.abs(num).max()
    rel = np.abs(adj - num) / np.maximum(np.abs(num), floor)
    assert rel.max() <= 1e-4, (rel.max(), adj, num)   # measured ≤ 4.3e-6 (body vertices, h = 1e-8 m)
    big = np.abs(num) > floor
    assert np.mean(np.sign(adj[big]) == np.sign(num[big])) >= 0.99


def _rest_fd(cloth, W, x_star, control, seed, h=1e-6):
    """(picks, central differences, adjoint) of φ for 10 random free rest coordinates."""
    g = equilibrium_gradient(cloth, W)
    rng = np.random.default_rng(seed)
    free = np.flatnonzero(cloth.model.inv_mass > 0)
    picks = [(int(i), int(k)) for i, k in zip(rng.choice(free, 10, replace=False), rng.integers(0, 2, 10))]
    num, adj = [], []
    for i, k in picks:
        rp, rm = control.rest.copy(), control.rest.copy()
        rp[i, k] += h
        rm[i, k] -= h
        num.append((_phi_after(cloth, W, x_star, control, rest=rp) - _phi_after(cloth, W, x_star, control, rest=rm)) / (2 * h))
        adj.append(g["rest"][i, k])
    return picks, np.array(num), np.array(adj)


def test_gradient_wrt_rest_coordinates(scene):
    _, num, adj = _rest_fd(*scene, seed=2)
    _check(adj, num)


def test_gradient_wrt_material(scene):
    cloth, W, x_star, control = scene
    g = equilibrium_gradient(cloth, W)
    num, adj = [], []
    for a in range(3):
        h = 1e-4 * control.stretch_compliance[0, a]
        sp, sm = control.stretch_compliance.copy(), control.stretch_compliance.copy()
        sp[0, a] += h
        sm[0, a] -= h
        num.append((_phi_after(cloth, W, x_star, control, stretch_compliance=sp)
                    - _phi_after(cloth, W, x_star, control, stretch_compliance=sm)) / (2 * h))
        adj.append(g["stretch_compliance"][0, a])
    _check(adj, num)
    h = 1e-4 * control.bend_stiffness[0]
    kp, km = control.bend_stiffness + h, control.bend_stiffness - h
    num_k = (_phi_after(cloth, W, x_star, control, bend_stiffness=kp)
             - _phi_after(cloth, W, x_star, control, bend_stiffness=km)) / (2 * h)
    _check([g["bend_stiffness"][0]], [num_k])


def test_gradient_wrt_body_vertices(scene):
    cloth, W, x_star, control = scene
    g = equilibrium_gradient(cloth, W)
    gb = g["body_vertices"]
    active = np.flatnonzero(np.abs(gb).sum(axis=1) > 0)
    assert len(active) >= 3  # the contact really couples body and garment
    rng = np.random.default_rng(3)
    h = 1e-8
    num, adj = [], []
    for i in rng.choice(active, min(6, len(active)), replace=False):
        for k in range(3):
            bp, bm = control.body_vertices.copy(), control.body_vertices.copy()
            bp[i, k] += h
            bm[i, k] -= h
            num.append((_phi_after(cloth, W, x_star, control, body_vertices=bp)
                        - _phi_after(cloth, W, x_star, control, body_vertices=bm)) / (2 * h))
            adj.append(gb[i, k])
    _check(adj, num)


def test_invariants(scene):
    cloth, W, x_star, control = scene
    g = equilibrium_gradient(cloth, W)
    # E depends on the rest shape only through differences: a uniform shift has zero effect.
    np.testing.assert_allclose(g["rest"].sum(axis=0), 0.0, atol=1e-9 * np.abs(g["rest"]).max())
    g3 = equilibrium_gradient(cloth, 3.0 * W)
    for key in ("rest", "stretch_compliance", "bend_stiffness", "body_vertices"):
        np.testing.assert_allclose(g3[key], 3.0 * g[key], rtol=1e-9, atol=1e-14)
    assert g["solve_residual"] < 1e-8


@pytest.fixture(scope="module")
def mass_scene():
    """The scene of `scene`, with masses that follow the rest shape."""
    mat = ClothMaterial(warp_compliance=2e-2, weft_compliance=3e-2, shear_compliance=5e-2, bend_stiffness=2e-5)
    cloth = sheet_against_sphere(n=8, materials=mat, contact_stiffness=20.0, masses_follow_rest=True)
    r = cloth.drape(max_steps=3000, residual_tol=TOL, refine_iterations=200)
    assert r.converged, r
    rng = np.random.default_rng(1)
    return cloth, rng.standard_normal(cloth.x.shape), cloth.x.copy(), cloth.control


def test_masses_follow_the_rest_shape(mass_scene):
    cloth, _, x_star, control = mass_scene
    m0 = cloth.model.mass.copy()
    pinned = cloth.model.inv_mass == 0
    try:
        cloth.set_control(rest=control.rest * 1.1)
        # lumped masses scale with the area; their total is ρ × the pattern's area
        np.testing.assert_allclose(cloth.model.mass, 1.21 * m0, rtol=1e-12)
        area = 0.2 * 0.2 * 1.21
        assert cloth.model.mass.sum() == pytest.approx(cloth.model.density * area, rel=1e-12)
        np.testing.assert_array_equal(cloth.model.inv_mass == 0, pinned)
        with pytest.raises(ValueError, match="inverted"):   # an inverted rest triangle is refused
            cloth.set_control(rest=control.rest * [-1.0, 1.0])
        np.testing.assert_allclose(cloth.model.mass, 1.21 * m0, rtol=1e-12)   # ...and changes nothing
    finally:
        cloth.set_control(rest=control.rest)
        cloth.state.x = x_star
    np.testing.assert_allclose(cloth.model.mass, m0, rtol=1e-12)
    fixed = sheet_against_sphere(n=8, contact_stiffness=20.0)   # the default: masses stay
    mf = fixed.model.mass.copy()
    fixed.set_control(rest=fixed.control.rest * 1.1)
    np.testing.assert_array_equal(fixed.model.mass, mf)


def test_gradient_wrt_rest_coordinates_with_masses_following(mass_scene):
    """The rest gradient includes ∂m/∂x̄ (gravity and the refinement's anchor springs are
    mass-weighted): central differences of the re-solved drape, masses recomputed each time."""
    cloth, W, x_star, control = mass_scene
    picks, num, adj = _rest_fd(cloth, W, x_star, control, seed=3)
    _check(adj, num)
    # the mass term matters: the fixed-mass gradient at the same drape misses it by far more
    # than the tolerance above
    mat = ClothMaterial(warp_compliance=2e-2, weft_compliance=3e-2, shear_compliance=5e-2, bend_stiffness=2e-5)
    fixed = sheet_against_sphere(n=8, materials=mat, contact_stiffness=20.0)
    fixed.state.x = x_star
    fixed.refine(residual_tol=TOL, refine_iterations=200)
    gf = np.array([equilibrium_gradient(fixed, W)["rest"][i, k] for i, k in picks])
    assert np.max(np.abs(gf - num) / np.abs(num).max()) > 10e-3   # 10× _check's tolerance
