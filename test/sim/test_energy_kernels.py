"""Every differentiable kernel of the simulator's energy (stretch, bending, seam, contact,
anchor, gravity) against central differences in double precision, plus rest-state and
rigid-motion invariants."""
import numpy as np
import pytest

from diffavatar_core import _core
from diffavatar_core.sim import Cloth, ClothMaterial
from diffavatar_core.sim.scenes import grid_sheet

G = np.array([0.0, -9.81, 0.0])


def _scene(rng):
    rest, F = grid_sheet(0.1, 0.1, 5, 5)
    x = np.column_stack([rest, np.zeros(len(rest))]) + 0.01 * rng.standard_normal((len(rest), 3))
    # a body plane (two big triangles) at z = 0.002 facing +z: the sheet's vertices near z≈0 touch it
    body_v = np.array([[-1, -1, 0.002], [1, -1, 0.002], [1, 1, 0.002], [-1, 1, 0.002]], float)
    body_f = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    cloth = Cloth(rest, F, x, seams=[[0, 24], [4, 20]], body=(body_v, body_f), thickness=0.004,
                  materials=ClothMaterial(bend_stiffness=1e-3, shear_compliance=3e-3, weft_compliance=2e-3))
    return cloth, x


def _gradient_by_differences(cloth, x, h=1e-7):
    num = np.zeros_like(x)
    for i in range(x.shape[0]):
        for k in range(3):
            xp, xm = x.copy(), x.copy()
            xp[i, k] += h
            xm[i, k] -= h
            num[i, k] = (cloth.solver.energy(xp, G) - cloth.solver.energy(xm, G)) / (2 * h)
    return num


def _hessian_by_differences(cloth, x, h=1e-6):
    num = np.zeros((x.size, x.size))
    for j in range(x.size):
        xp, xm = x.copy().reshape(-1), x.copy().reshape(-1)
        xp[j] += h
        xm[j] -= h
        num[:, j] = (cloth.solver.energy_gradient(xp.reshape(x.shape), G) -
                     cloth.solver.energy_gradient(xm.reshape(x.shape), G)).reshape(-1) / (2 * h)
    return num


def test_energy_gradient_matches_central_differences():
    rng = np.random.default_rng(0)
    cloth, x = _scene(rng)
    cloth.solver.detect_contacts(x, _core.SimParams())
    assert cloth.solver.num_contacts > 0
    g = cloth.solver.energy_gradient(x, G)
    num = _gradient_by_differences(cloth, x)
    err = np.abs(g - num) / (np.abs(num) + 1e-6 * np.abs(num).max())
    assert err.max() < 1e-5, err.max()


def test_energy_hessian_matches_central_differences_of_the_gradient():
    """The exact Hessian (what the Newton refinement and the equilibrium adjoint factorize): each
    column against (∇E(x + h eⱼ) − ∇E(x − h eⱼ)) / 2h (measured 1e-10 apart, relative);
    symmetric. The projected one (far from equilibrium) is positive semi-definite."""
    rng = np.random.default_rng(1)
    cloth, x = _scene(rng)
    cloth.solver.detect_contacts(x, _core.SimParams())
    assert cloth.solver.num_contacts > 0
    H = cloth.solver.energy_hessian(x, G, project=False).toarray()
    assert H.shape == (x.size, x.size)   # no pinned vertices: every coordinate is a dof
    num = _hessian_by_differences(cloth, x)
    assert np.abs(H - num).max() < 1e-8 * np.abs(num).max(), np.abs(H - num).max() / np.abs(num).max()
    np.testing.assert_allclose(H, H.T, atol=1e-9 * np.abs(H).max())
    Hp = cloth.solver.energy_hessian(x, G, project=True).toarray()
    assert np.linalg.eigvalsh(0.5 * (Hp + Hp.T)).min() > -1e-9 * np.abs(Hp).max()


@pytest.mark.parametrize("term", ["stretch", "bending"])
def test_each_closed_form_term_alone_matches_central_differences(term):
    """The closed forms Newton assembles (stretch_kernel.hpp stretch_derivatives: the StVK chain
    through F; bending_kernel.hpp HingeGeom::hessian: ∇²θ column by column), each term on its
    own — the other made negligible — on a sheet crumpled far from rest (strains up to ~30%, folds
    of up to ~90°) with the grain at 0.6 rad and unequal warp / weft / shear compliances:
    gradient against central differences of the energy, Hessian against those of the gradient
    (no body, no seams, no gravity term in the Hessian)."""
    rng = np.random.default_rng(7)
    rest, F = grid_sheet(0.1, 0.1, 5, 5)
    x = np.column_stack([rest, np.zeros(len(rest))])
    x[:, 2] = 0.03 * np.sin(40 * x[:, 0]) * np.cos(30 * x[:, 1])
    x = x * [1.2, 0.85, 1.0] + 0.004 * rng.standard_normal(x.shape)
    mat = (ClothMaterial(warp_compliance=1e-3, weft_compliance=3e-3, shear_compliance=2e-2, bend_stiffness=1e-9)
           if term == "stretch" else
           ClothMaterial(warp_compliance=1e6, weft_compliance=1e6, shear_compliance=1e6, bend_stiffness=1e-3))
    cloth = Cloth(rest, F, x, materials=mat, grain=np.full(len(F), 0.6))
    g = cloth.solver.energy_gradient(x, G)
    num = _gradient_by_differences(cloth, x)
    gravity = np.asarray(cloth.model.mass)[:, None] * -G   # its exact part: the scale is the term's own
    assert np.abs(g - num).max() < 1e-6 * np.abs(num - gravity).max()
    H = cloth.solver.energy_hessian(x, G, project=False).toarray()
    Hn = _hessian_by_differences(cloth, x)
    assert np.abs(H - Hn).max() < 1e-7 * np.abs(Hn).max(), np.abs(H - Hn).max() / np.abs(Hn).max()
    np.testing.assert_allclose(H, H.T, atol=1e-12 * np.abs(H).max())
    # translations are in the Hessian's null space at any state
    for d in range(3):
        t = np.zeros_like(x)
        t[:, d] = 1.0
        assert np.abs(H @ t.reshape(-1)).max() < 1e-9 * np.abs(H).max()


def _clamp(H):
    w, V = np.linalg.eigh(0.5 * (H + H.T))
    return (V * np.maximum(w, 0.0)) @ V.T


def test_projected_element_hessians_are_psd_clamps_and_gauss_newton():
    """Far from equilibrium Newton uses positive semi-definite element Hessians
    (cloth_energy.cpp element_hessians). A triangle's is its Hessian clamped to its non-negative
    eigenvalues, computed on the element's translation-free subspace (project_psd); it must equal
    the clamp of the whole element matrix: a single compressed, sheared triangle (indefinite).
    A hinge's is the Gauss–Newton part k w ∇θ∇θᵀ of its exact k w (∇θ∇θᵀ + θ∇²θ): checked on a
    hinge folded 60° between two stretched triangles against the bending energy E_b and gradient
    ∇E_b = k w θ ∇θ alone (the differences with and without bending), as ∇E_b ∇E_bᵀ / (2 E_b);
    the exact hinge part there is indefinite, the projected one PSD of rank one. With
    `hinge_clamp` (bench/newton.py's reference) the hinge block is clamped like a triangle's."""
    rest = np.array([[0.0, 0.0], [0.1, 0.0], [0.0, 0.1]])
    x = np.array([[0.0, 0.0, 0.0], [0.07, 0.01, 0.02], [0.03, 0.08, -0.01]])
    tri = Cloth(rest, np.array([[0, 1, 2]]), x, materials=ClothMaterial(weft_compliance=3e-3),
                grain=np.array([0.4]))
    H = tri.solver.energy_hessian(x, G, project=False).toarray()
    assert np.linalg.eigvalsh(H).min() < -1e-3 * np.abs(H).max()   # indefinite: the clamp acts
    Hp = tri.solver.energy_hessian(x, G, project=True).toarray()
    np.testing.assert_allclose(Hp, _clamp(H), atol=1e-12 * np.abs(H).max())

    bent, flat, x = _folded_hinge(np.pi / 3)
    Hs = flat.solver.energy_hessian(x, G, project=False).toarray()
    assert np.linalg.eigvalsh(Hs).min() > -1e-12 * np.abs(Hs).max()   # stretched: clamping keeps it
    Hh = bent.solver.energy_hessian(x, G, project=False).toarray() - Hs
    assert np.linalg.eigvalsh(Hh).min() < -1e-3 * np.abs(Hh).max()
    Eb = bent.solver.energy(x, G) - flat.solver.energy(x, G)
    gb = (np.asarray(bent.solver.energy_gradient(x, G)) - np.asarray(flat.solver.energy_gradient(x, G))).reshape(-1)
    assert Eb > 0
    gauss_newton = np.outer(gb, gb) / (2 * Eb)
    Hp = bent.solver.energy_hessian(x, G, project=True).toarray()
    np.testing.assert_allclose(Hp - Hs, gauss_newton, atol=1e-10 * np.abs(Hs + Hh).max())
    w = np.linalg.eigvalsh(Hp - Hs)
    assert w.min() > -1e-12 * w.max() and np.sum(w > 1e-9 * w.max()) == 1
    # the reference kept for bench/newton.py (the Newton of stops 31–58): the hinge block clamped
    bent.solver.hinge_clamp = True
    assert bent.clone().solver.hinge_clamp
    Hc = bent.solver.energy_hessian(x, G, project=True).toarray()
    np.testing.assert_allclose(Hc, Hs + _clamp(Hh), atol=1e-10 * np.abs(Hs + Hh).max())
    # the exact Hessian does not depend on the switch
    np.testing.assert_array_equal(bent.solver.energy_hessian(x, G, project=False).toarray(), Hs + Hh)


def test_the_recoverys_newton_hinge_blocks_reach_its_cloths_and_both_are_psd():
    """`newton_hinge_blocks` (RecoverOptions) sets how the recovery's cloths, and their clones,
    project a hinge's block: on a crumpled skirt (every hinge away from its rest angle) both
    projected Hessians are positive semi-definite, the clamp's and Gauss–Newton's differ, and
    the exact Hessian is the same for both."""
    from diffavatar_core.pattern.templates import make_template
    from diffavatar_core.pipeline.options import RecoverOptions
    from diffavatar_core.pipeline.recovery import _garment_cloth
    from diffavatar_core.sim.scenes import sphere
    g = make_template("skirt", edge_length=0.08)
    body = sphere(0.3, center=np.array([0.0, 0.5, 0.0]), subdivisions=1)
    x = g.x0 + 0.01 * np.random.default_rng(3).standard_normal(g.x0.shape)   # m: crumpled
    projected, exact = {}, {}
    for name, on in (("gauss_newton", False), ("clamp", True)):
        opts = RecoverOptions.coerce({"newton_hinge_blocks": name})
        c = _garment_cloth(g, g.rest, g.x0, ClothMaterial(bend_stiffness=1e-4), body,
                           newton_hinge_blocks=opts.newton_hinge_blocks)
        assert c.solver.hinge_clamp == on and c.clone().solver.hinge_clamp == on
        projected[name] = c.solver.energy_hessian(x, G, project=True).toarray()
        exact[name] = c.solver.energy_hessian(x, G, project=False).toarray()
    scale = np.abs(exact["clamp"]).max()
    np.testing.assert_array_equal(exact["gauss_newton"], exact["clamp"])
    assert np.linalg.eigvalsh(exact["clamp"]).min() < -1e-6 * scale   # indefinite: the projections act
    for H in projected.values():
        assert np.linalg.eigvalsh(H).min() > -1e-10 * scale
    assert np.abs(projected["clamp"] - projected["gauss_newton"]).max() > 1e-6 * scale


def test_projected_hinge_hessian_is_the_exact_one_at_the_rest_angle():
    """At its rest angle (θ = θ0: here a flat hinge of a flat pattern) the term θ∇²θ vanishes, so
    the Gauss–Newton hinge block far from equilibrium is the exact one: with the same stretched
    triangles, the projected and exact Hessians differ by the triangles' clamp alone — none."""
    bent, flat, x = _folded_hinge(0.0)
    for cloth in (bent, flat):
        H = cloth.solver.energy_hessian(x, G, project=False).toarray()
        Hp = cloth.solver.energy_hessian(x, G, project=True).toarray()
        np.testing.assert_allclose(Hp, H, atol=1e-10 * np.abs(H).max())
    Hb = bent.solver.energy_hessian(x, G, project=False).toarray()
    Hf = flat.solver.energy_hessian(x, G, project=False).toarray()
    assert np.abs(Hb - Hf).max() > 1e-6 * np.abs(Hf).max()   # the hinge does contribute


def _folded_hinge(angle):
    """Two triangles sharing the x axis, the second turned by `angle` (rad) about it, all
    stretched 10%; with bending (1e-3 N·m) and without."""
    rest = np.array([[0.0, 0.0], [0.1, 0.0], [0.05, 0.08], [0.05, -0.08]])
    F = np.array([[0, 1, 2], [0, 3, 1]])
    x = np.column_stack([rest, np.zeros(4)])
    x[3] = [0.05, -0.08 * np.cos(angle), 0.08 * np.sin(angle)]
    x *= 1.1
    bent = Cloth(rest, F, x, materials=ClothMaterial(bend_stiffness=1e-3))
    flat = Cloth(rest, F, x, materials=ClothMaterial(bend_stiffness=0.0))
    return bent, flat, x


def test_rest_state_has_zero_energy_and_no_correction():
    rest, F = grid_sheet(0.2, 0.1, 9, 5)
    x0 = np.column_stack([rest, np.zeros(len(rest))])
    cloth = Cloth(rest, F, x0, materials=ClothMaterial(bend_stiffness=1e-3))
    assert abs(cloth.energy(gravity=(0, 0, 0))) < 1e-20
    cloth.step(10, gravity=(0, 0, 0))
    assert np.abs(cloth.x - x0).max() < 1e-13


def test_rigid_motion_of_a_rest_sheet_stays_at_rest():
    rest, F = grid_sheet(0.2, 0.1, 9, 5)
    a = 0.7
    R = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]) @ \
        np.array([[1, 0, 0], [0, np.cos(0.3), -np.sin(0.3)], [0, np.sin(0.3), np.cos(0.3)]])
    x0 = np.column_stack([rest, np.zeros(len(rest))]) @ R.T + [0.3, 1.2, -0.4]
    cloth = Cloth(rest, F, x0, materials=ClothMaterial(bend_stiffness=1e-3))
    assert abs(cloth.energy(gravity=(0, 0, 0))) < 1e-18
    np.testing.assert_allclose(cloth.solver.energy_gradient(x0, np.zeros(3)), 0.0, atol=1e-12)
    cloth.step(10, gravity=(0, 0, 0))
    assert np.abs(cloth.x - x0).max() < 1e-12
