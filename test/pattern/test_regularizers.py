"""Seam-length (Eq. 7) and boundary-curvature (Eq. 8) regularizers: zero at the template,
invariances, and gradients against central differences (w.r.t. rest and through W to ζ)."""
import numpy as np
import pytest

from diffavatar_core.pattern import PanelSpec, PatternSpec, Placement, SeamSpec, build_garment
from diffavatar_core.pattern.cage import build_cage
from diffavatar_core.pattern.regularizers import CurvatureRegularizer, SeamLengthRegularizer


def _garment(curved):
    w, h = 0.3, 0.25
    V = np.array([[0, 0], [w, 0], [w, h], [0, h]], float)
    front = PanelSpec("front", V, Placement([0, 0, 0.1], [1, 0, 0], [0, 1, 0]), curves={2: [[0.15, 0.2]]})
    back = PanelSpec("back", V, Placement([0, 0, -0.1], [-1, 0, 0], [0, 1, 0]))
    if curved:
        back.curves[1] = [[w + 0.04, h / 2]]
    seams = [SeamSpec("front", 1, "back", 3), SeamSpec("front", 3, "back", 1)]
    return build_garment(PatternSpec("t", [front, back], seams), edge_length=0.04)


def _fd_check(f, X0, rng, n=12, eps=1e-6):
    _, G = f(X0)
    worst = 0.0
    for _ in range(n):
        i, c = rng.integers(len(X0)), rng.integers(2)
        X = X0.copy()
        X[i, c] += eps
        lp = f(X)[0]
        X[i, c] -= 2 * eps
        lm = f(X)[0]
        fd = (lp - lm) / (2 * eps)
        worst = max(worst, abs(fd - G[i, c]) / max(np.abs(G).max(), 1e-300))
    return worst


def test_zero_at_template():
    g = _garment(False)
    assert SeamLengthRegularizer(g).value_and_grad(g.rest)[0] < 1e-24
    v, G = CurvatureRegularizer(g).value_and_grad(g.rest)
    assert v < 1e-24 and np.abs(G).max() < 1e-12
    gc = _garment(True)   # eased seam: only zero when the template's ease is kept
    assert SeamLengthRegularizer(gc).value_and_grad(gc.rest)[0] > 0
    assert SeamLengthRegularizer(gc, keep_template_ease=True).value_and_grad(gc.rest)[0] < 1e-24


def test_curvature_is_similarity_invariant_per_panel():
    g = _garment(False)
    reg = CurvatureRegularizer(g)
    th, s = 0.7, 1.3
    R = s * np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    X = g.rest.copy()
    m = g.panel == 1
    X[m] = X[m] @ R.T + np.array([0.2, -0.1])
    assert reg.value_and_grad(X)[0] < 1e-20


@pytest.mark.parametrize("which", ["seam", "curvature"])
def test_gradients_match_central_differences(which):
    g = _garment(True)
    reg = SeamLengthRegularizer(g) if which == "seam" else CurvatureRegularizer(g)
    rng = np.random.default_rng(2)
    X0 = g.rest + rng.normal(scale=0.01, size=g.rest.shape)
    # evaluate on boundary vertices (the only ones the terms touch) and random ones
    _, G = reg.value_and_grad(X0)
    assert np.abs(G).max() > 0
    assert _fd_check(reg.value_and_grad, X0, rng) <= 1e-6
    touched = np.flatnonzero(np.abs(G).sum(1) > 0)
    worst = 0.0
    for i in touched[:: max(1, len(touched) // 10)]:
        for c in range(2):
            X = X0.copy(); X[i, c] += 1e-6
            lp = reg.value_and_grad(X)[0]
            X[i, c] -= 2e-6
            lm = reg.value_and_grad(X)[0]
            worst = max(worst, abs((lp - lm) / 2e-6 - G[i, c]) / np.abs(G).max())
    assert worst <= 1e-6


def test_gradient_through_the_cage():
    g = _garment(True)
    cage = build_cage(g)
    seam, curv = SeamLengthRegularizer(g), CurvatureRegularizer(g)
    rng = np.random.default_rng(5)
    Z0 = cage.zeta0 + rng.normal(scale=0.01, size=cage.zeta0.shape)

    def f(Z):
        X = cage.rest(Z)
        v1, g1 = seam.value_and_grad(X)
        v2, g2 = curv.value_and_grad(X)
        return v1 + v2, cage.grad_zeta(g1 + g2)
    assert _fd_check(f, Z0, rng, n=len(Z0)) <= 1e-6
