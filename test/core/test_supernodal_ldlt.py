"""The supernodal LDLᵀ (linalg/supernodal_ldlt.hpp) for the Newton refinement's steps:
x = A⁻¹ b to round-off against a dense solve and against Eigen's SimplicialLDLT (same ordering)
on the refinement's own Hessians (projected: SPD; exact: indefinite) and on symmetric matrices
whose patterns make every kind of supernode (one vertex block, long chains merged by relaxation,
a dense row, separate components, 1×1); one analysis serves every factorization of its pattern;
a zero pivot fails as SimplicialLDLT's does, and refine() reaches the same equilibrium with it."""
import numpy as np
import pytest
import scipy.sparse as sp

from diffavatar_core import _core
from diffavatar_core.sim import ClothMaterial
from diffavatar_core.sim.scenes import sphere
from sheet_on_sphere import sheet_on_sphere

G = np.array([0.0, -9.81, 0.0])


def _solve(cls, A, b):
    f = cls()
    f.analyze_pattern(A)
    f.factorize(A)
    assert f.ok
    return f.solve(b)


def _check(A, rng, tol=1e-10):
    A = sp.csc_matrix(A)
    b = rng.standard_normal(A.shape[0])
    x = _solve(_core.SupernodalLdlt, A, b)
    ref = np.linalg.solve(A.toarray(), b)
    assert np.linalg.norm(x - ref) <= tol * np.linalg.norm(ref)
    assert np.linalg.norm(A @ x - b) <= tol * np.linalg.norm(b) * max(1.0, abs(A).max())
    eig = _solve(_core.SimplicialLdlt, A, b)
    assert np.linalg.norm(x - eig) <= tol * np.linalg.norm(ref)
    return x


def _sym(pattern, rng, indefinite):
    """Symmetric values on a symmetric pattern: diagonally dominant (SPD), or with diagonals of
    both signs (indefinite but every pivot far from 0)."""
    P = sp.triu(sp.csc_matrix(pattern), 1)
    P = P + P.T
    P.data = rng.uniform(-1, 1, P.nnz)
    P = (P + P.T) * 0.5
    dom = np.asarray(abs(P).sum(axis=1)).ravel() + 1.0
    sign = np.where(rng.random(len(dom)) < 0.3, -1.0, 1.0) if indefinite else 1.0
    return sp.csc_matrix(P + sp.diags(sign * 2.0 * dom))


def _hung_sheet():
    """sheet_on_sphere (12×12, a finer sphere), its contacts detected at the rumpled state."""
    cloth = sheet_on_sphere(12, subdivisions=2)
    x = np.array(cloth.x)
    cloth.solver.detect_contacts(x, _core.SimParams())
    assert cloth.solver.num_contacts > 0
    return cloth, x


def test_the_refinements_hessians():
    rng = np.random.default_rng(0)
    cloth, x = _hung_sheet()
    Hp, He = (cloth.solver.newton_hessian(x, G, project) for project in (True, False))
    assert np.linalg.eigvalsh(Hp.toarray()).min() > 0
    assert np.linalg.eigvalsh(He.toarray()).min() < 0   # the exact Hessian of a rumpled sheet is indefinite
    for H in (Hp, He):
        _check(H, rng)


@pytest.mark.parametrize("indefinite", [False, True])
def test_patterns(indefinite):
    rng = np.random.default_rng(1)
    n = 60
    band = sp.diags([np.ones(n - k) for k in range(4)], list(range(4)))           # long chains: relaxed merges
    grid = sp.kron(sp.eye(3), sp.random(20, 20, 0.15, random_state=2) + sp.eye(20))  # three components
    arrow = sp.lil_matrix((n, n))
    arrow.setdiag(1.0)
    arrow[0, :] = 1.0                                                               # one dense row
    blocks = sp.kron(sp.random(20, 20, 0.1, random_state=3) + sp.eye(20), np.ones((3, 3)))  # vertex blocks
    for pattern in (band, grid, arrow, blocks, sp.eye(n), sp.csc_matrix(np.ones((n, n))), sp.eye(1)):
        _check(_sym(pattern, rng, indefinite), rng)


def test_one_analysis_serves_every_value_set():
    rng = np.random.default_rng(4)
    pattern = sp.kron(sp.random(30, 30, 0.1, random_state=5) + sp.eye(30), np.ones((3, 3)))
    A0 = _sym(pattern, rng, False)
    f = _core.SupernodalLdlt()
    f.analyze_pattern(A0)
    for k in range(4):
        A = A0.copy()
        A.data = _sym(pattern, np.random.default_rng(10 + k), k % 2 == 1).data
        f.factorize(A)
        assert f.ok
        b = rng.standard_normal(A.shape[0])
        x = f.solve(b)
        assert np.linalg.norm(A @ x - b) <= 1e-11 * np.linalg.norm(b) * abs(A).max()


@pytest.mark.parametrize("dense", [[[0.0, 1.0], [1.0, 0.0]], [[2.0, 0.0], [0.0, 0.0]]])
def test_zero_pivot_fails_as_simplicial_ldlt(dense):
    # every entry stored, zeros included: the pivot is 0 in value, not missing from the pattern
    A = sp.csc_matrix((np.array(dense).ravel(order="F"), np.tile([0, 1], 2), [0, 2, 4]), shape=(2, 2))
    for cls in (_core.SupernodalLdlt, _core.SimplicialLdlt):
        f = cls()
        f.analyze_pattern(A)
        f.factorize(A)
        assert not f.ok
        with pytest.raises(RuntimeError, match="zero pivot"):
            f.solve(np.ones(2))


def test_misuse_is_named_not_undefined():
    """Out of order or with another pattern, both bindings raise instead of reading garbage."""
    A = _sym(sp.kron(sp.eye(4), np.ones((3, 3))), np.random.default_rng(6), False)
    other = _sym(sp.eye(12), np.random.default_rng(7), False)
    for cls in (_core.SupernodalLdlt, _core.SimplicialLdlt):
        f = cls()
        with pytest.raises(ValueError, match="analyze it first"):
            f.factorize(A)
        with pytest.raises(RuntimeError, match="no successful factorization"):
            f.solve(np.ones(12))
        f.analyze_pattern(A)
        with pytest.raises(RuntimeError, match="no successful factorization"):
            f.solve(np.ones(12))
        with pytest.raises(ValueError, match="not the pattern"):
            f.factorize(other)
        f.factorize(A)
        with pytest.raises(ValueError, match="b has 5 entries, the matrix 12 rows"):
            f.solve(np.ones(5))
        with pytest.raises(ValueError, match="square"):
            f.analyze_pattern(sp.csc_matrix(np.ones((2, 3))))


def test_refine_reaches_the_same_equilibrium_with_it():
    """refine() with `supernodal_newton` (opt-in) solves its steps by SupernodalLdlt: from the
    rumpled sheet Newton's residual goes below the tolerance, the gradient there is zero to it
    (evaluated afresh), and the equilibrium is the one Eigen's SimplicialLDLT steps reach; a clone
    keeps the choice."""
    ends = []
    for on in (False, True):
        cloth, _ = _hung_sheet()
        cloth.solver.supernodal_newton = on
        assert cloth.clone().solver.supernodal_newton == on
        its, res = cloth.refine(keep_anchor=False, anchor_stiffness=1e-3, refine_iterations=200, residual_tol=1e-9)
        assert 1 < its < 200 and res <= 1e-9
        assert cloth.solver.residual(np.array(cloth.x), G) <= 1e-9
        ends.append(np.array(cloth.x))
    assert np.abs(ends[0] - ends[1]).max() < 1e-6   # m


def test_the_recoverys_option_reaches_every_cloth_it_makes():
    """`newton_solver: supernodal` sets the recovery's cloths (and so their clones) to it."""
    from diffavatar_core.pattern.templates import make_template
    from diffavatar_core.pipeline.recovery import _garment_cloth
    g = make_template("skirt", edge_length=0.08)
    body = sphere(0.3, center=np.array([0.0, 0.5, 0.0]), subdivisions=1)
    for name, on in (("simplicial", False), ("supernodal", True)):
        c = _garment_cloth(g, g.rest, g.x0, ClothMaterial(), body, newton_solver=name)
        assert c.solver.supernodal_newton == on and c.clone().solver.supernodal_newton == on
