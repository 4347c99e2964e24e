"""The Newton refinement's Hessian assembly (sim/newton_system.hpp: in place on a pattern cached
across iterations and calls) against the triplet assembly (cloth_energy.cpp energy_hessian, the
one the equilibrium adjoint and the Hessian's central-difference tests use): the same sparsity
and every value equal bit for bit — the same entries summed in the same order — whatever
changes between calls: the state, the active contacts, the anchors, the projection, the
control, pinned vertices."""
import numpy as np
import pytest

from diffavatar_core import _core
from diffavatar_core.sim import Cloth, ClothMaterial
from diffavatar_core.sim.scenes import grid_sheet

G = np.array([0.0, -9.81, 0.0])


def _cloth(pinned=None):
    rest, F = grid_sheet(0.1, 0.1, 6, 6)
    rng = np.random.default_rng(3)
    x = np.column_stack([rest, np.zeros(len(rest))]) + 0.004 * rng.standard_normal((len(rest), 3))
    body_v = np.array([[-1, -1, 0.002], [1, -1, 0.002], [1, 1, 0.002], [-1, 1, 0.002]], float)
    body_f = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    cloth = Cloth(rest, F, x, seams=[[0, 35], [5, 30]], body=(body_v, body_f), thickness=0.004, pinned=pinned,
                  materials=ClothMaterial(bend_stiffness=1e-3, shear_compliance=3e-3, weft_compliance=2e-3))
    return cloth, x, rng


def _same(A, B):
    A, B = A.tocsc(), B.tocsc()
    assert A.shape == B.shape
    np.testing.assert_array_equal(A.indptr, B.indptr)
    np.testing.assert_array_equal(A.indices, B.indices)
    assert np.array_equal(A.data, B.data), np.abs(A.data - B.data).max()


@pytest.mark.parametrize("pinned", [None, [0, 7, 20]])
def test_newton_hessian_is_the_triplet_hessian_bit_for_bit(pinned):
    cloth, x, rng = _cloth(pinned)
    s = cloth.solver
    p = _core.SimParams()
    seen_contacts = set()
    for k in range(6):
        xk = x + 0.003 * rng.standard_normal(x.shape)   # different vertices below the contact plane
        s.detect_contacts(xk, p)
        seen_contacts.add(s.num_contacts)
        for project in (False, True):
            _same(s.newton_hessian(xk, G, project), s.energy_hessian(xk, G, project))
    assert len(seen_contacts) > 1   # the active set changed between the calls
    # anchors (refine sets them, κ m_i on the diagonal) and a new control (bending, rest shape)
    cloth.refine(anchor_stiffness=1.0, refine_iterations=3, residual_tol=0.0)
    assert np.asarray(s.anchor).shape == x.shape
    xr = np.array(cloth.x)
    for project in (False, True):
        _same(s.newton_hessian(xr, G, project), s.energy_hessian(xr, G, project))
    cloth.set_control(bend_stiffness=np.array([3e-4]), rest=np.asarray(cloth.control.rest) * 1.02)
    for project in (False, True):
        _same(s.newton_hessian(xr, G, project), s.energy_hessian(xr, G, project))


def test_newton_hessian_is_the_exact_hessian():
    """Not only the same as the triplet matrix: against central differences of the gradient (the
    assembled matrix over all vertices, no pins)."""
    cloth, x, _ = _cloth()
    s = cloth.solver
    s.detect_contacts(x, _core.SimParams())
    assert s.num_contacts > 0
    H = s.newton_hessian(x, G, False).toarray()
    h = 1e-6
    num = np.zeros_like(H)
    for j in range(x.size):
        xp, xm = x.copy().reshape(-1), x.copy().reshape(-1)
        xp[j] += h
        xm[j] -= h
        num[:, j] = (s.energy_gradient(xp.reshape(x.shape), G) - s.energy_gradient(xm.reshape(x.shape), G)).reshape(-1) / (2 * h)
    assert np.abs(H - num).max() < 1e-8 * np.abs(num).max()
