"""The H¹ (Sobolev) metric on pattern parameters (pattern/sobolev.py): the cotangent Laplacian's
exact properties, and the metric's spectrum (unit top eigenvalue, zig-zags damped by (λ/ℓ)²)."""
import numpy as np
import pytest

from diffavatar_core.pattern.cage import build_cage
from diffavatar_core.pattern.sobolev import SobolevMetric, pattern_laplacian
from diffavatar_core.pattern.templates import make_template


def _grid(nx=7, ny=5, w=0.6, h=0.4, jitter=0.0, seed=0):
    xs, ys = np.meshgrid(np.linspace(0, w, nx), np.linspace(0, h, ny))
    X = np.column_stack([xs.ravel(), ys.ravel()])
    if jitter:   # move interior vertices: a non-uniform mesh, same boundary
        inner = (X[:, 0] > 0) & (X[:, 0] < w) & (X[:, 1] > 0) & (X[:, 1] < h)
        X[inner] += np.random.default_rng(seed).uniform(-jitter, jitter, (inner.sum(), 2))
    F = []
    for j in range(ny - 1):
        for i in range(nx - 1):
            a, b, c, d = j * nx + i, j * nx + i + 1, (j + 1) * nx + i, (j + 1) * nx + i + 1
            F += [[a, b, d], [a, d, c]]
    return X, np.array(F)


def test_laplacian_is_exact_on_linear_functions():
    """fᵀKf = ∫|∇f|² dA for a piecewise-linear f: exactly |a|²·area for f = a·x + b on any
    triangulation; K is symmetric, annihilates constants, is positive semi-definite; the lumped
    masses sum to the area."""
    X, F = _grid(jitter=0.02)
    K, m = pattern_laplacian(X, F)
    Kd = K.toarray()
    area = 0.6 * 0.4
    np.testing.assert_allclose(Kd, Kd.T, atol=1e-12)
    np.testing.assert_allclose(Kd @ np.ones(len(X)), 0, atol=1e-12)
    assert np.linalg.eigvalsh(Kd).min() > -1e-10
    assert m.sum() == pytest.approx(area, rel=1e-12) and np.all(m > 0)
    for a in ([1.0, 0.0], [0.3, -2.0]):
        f = X @ np.array(a) + 0.7
        assert f @ Kd @ f == pytest.approx(np.dot(a, a) * area, rel=1e-10)


def test_laplacian_rejects_degenerate_triangles_and_bad_faces():
    X, F = _grid()
    X2 = X.copy()
    X2[F[0, 2]] = 0.5 * (X2[F[0, 0]] + X2[F[0, 1]])   # a zero-area triangle
    with pytest.raises(ValueError, match="degenerate"):
        pattern_laplacian(X2, F)
    with pytest.raises(ValueError, match="faces"):
        pattern_laplacian(X, F + len(X))


def _dense_P(metric):
    n = 2 * metric.n
    return np.column_stack([metric(e) for e in np.eye(n)])


def test_metric_spectrum_on_a_template_cage():
    """On the t-shirt's cage: P is symmetric positive definite with mean eigenvalue 1; a zig-zag
    of the handles (alternate handles ±) keeps a far smaller share than a uniform move of the
    panel, and a longer length damps it more."""
    g = make_template("tshirt", edge_length=0.04)
    cage = build_cage(g)
    ratios = []
    for length in (0.1, 0.3):
        M = SobolevMetric(g.rest, g.faces, cage.W, length)
        P = _dense_P(M)
        np.testing.assert_allclose(P, P.T, atol=1e-10 * np.abs(P).max())
        ev = np.linalg.eigvalsh(0.5 * (P + P.T))
        assert ev.min() > 0 and ev.mean() == pytest.approx(1.0, rel=1e-8) and ev.max() > 2
        front = np.flatnonzero(cage.handle_panel == 0)
        move = np.zeros((M.n, 2))
        move[front, 1] = 1.0                      # the front panel translated in y
        zig = np.zeros((M.n, 2))
        zig[front, 1] = (-1.0) ** np.arange(len(front))
        rq = lambda v: float(v.ravel() @ M(v.ravel()) / (v.ravel() @ v.ravel()))
        ratios.append(rq(zig) / rq(move))
    assert ratios[1] < 0.1 and ratios[1] < 0.5 * ratios[0] < 0.25, ratios


def test_vertex_parametrization_and_sparse_path_agree_with_dense():
    """W = identity (every pattern vertex a parameter): the sparse factorization used above
    DENSE_MAX gives the same operator as the dense one, up to its normalisation (tr(G⁻¹) by
    Hutchinson's estimate: within 10%)."""
    X, F = _grid(9, 6, jitter=0.01)
    dense = SobolevMetric(X, F, None, 0.2)
    sparse = SobolevMetric.__new__(SobolevMetric)
    SobolevMetric.DENSE_MAX, old = 10, SobolevMetric.DENSE_MAX
    try:
        sparse.__init__(X, F, None, 0.2)
    finally:
        SobolevMetric.DENSE_MAX = old
    v = np.random.default_rng(1).normal(size=2 * len(X))
    a, b = sparse(v), dense(v)
    ratio = (a @ b) / (b @ b)
    np.testing.assert_allclose(a, ratio * b, rtol=1e-8)
    assert abs(ratio - 1) < 0.1, ratio
    with pytest.raises(ValueError, match="expected"):
        dense(v[:-1])
    with pytest.raises(ValueError, match="length"):
        SobolevMetric(X, F, None, -1.0)
