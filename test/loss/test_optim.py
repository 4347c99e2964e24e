"""The outer optimizer: convergence on badly scaled groups, rejection of invalid steps, best
iterate kept, cancellation."""
import numpy as np
import pytest

from diffavatar_core.lbfgs import minimize_lbfgs
from diffavatar_core.optim import GroupAdam, minimize


def _quadratic(scale):
    target = {"a": np.array([1.0, -2.0]), "b": np.array([3e-3])}

    def evaluate(p):
        ra, rb = p["a"] - target["a"], (p["b"] - target["b"]) / scale
        value = float(ra @ ra + rb @ rb)
        return value, {"a": 2 * ra, "b": 2 * rb / scale}, {"a": float(ra @ ra), "b": float(rb @ rb)}
    return evaluate, target


def test_converges_on_groups_with_different_scales():
    evaluate, target = _quadratic(scale=1e-3)
    res = minimize(evaluate, {"a": np.zeros(2), "b": np.zeros(1)}, {"a": 0.1, "b": 1e-4},
                   max_iterations=2000, rel_tol=1e-10, patience=50)
    np.testing.assert_allclose(res.params["a"], target["a"], atol=1e-3)
    np.testing.assert_allclose(res.params["b"], target["b"], atol=1e-6)
    values = [h["value"] for h in res.history]
    assert res.value == min(values) and res.value < 1e-5 * values[0]


def test_invalid_proposals_are_rejected_and_step_sizes_shrink():
    evaluate, _ = _quadratic(scale=1.0)

    def constrained(p):  # the region a[0] > 0.5 is 'invalid' (e.g. an inverted rest triangle)
        if p["a"][0] > 0.5:
            raise ValueError("inverted triangle")
        return evaluate(p)

    seen = []
    res = minimize(constrained, {"a": np.zeros(2), "b": np.zeros(1)}, {"a": 0.3, "b": 0.3},
                   max_iterations=200, on_iteration=seen.append)
    assert res.rejected > 0
    assert all(h["lr"]["a"] <= 0.3 for h in seen) and seen[-1]["lr"]["a"] < 0.3
    assert res.params["a"][0] <= 0.5  # never left the valid region
    assert res.value == min(h["value"] for h in res.history)


def test_cancel_returns_the_best_iterate_so_far():
    evaluate, _ = _quadratic(scale=1.0)
    calls = []
    res = minimize(evaluate, {"a": np.zeros(2), "b": np.zeros(1)}, {"a": 0.1, "b": 0.1},
                   max_iterations=100, on_iteration=calls.append, cancelled=lambda: len(calls) >= 4)
    assert res.stopped == "cancelled" and res.iterations == 3
    assert res.value == min(h["value"] for h in res.history)


def test_non_finite_gradient_and_bad_step_sizes_are_errors():
    with pytest.raises(ValueError, match="lr"):
        GroupAdam({"a": 0.0})
    opt = GroupAdam({"a": 0.1})
    with pytest.raises(FloatingPointError, match="a"):
        opt.propose({"a": np.zeros(2)}, {"a": np.array([np.nan, 0])})


def _rosenbrock(p):
    x, y = p["a"][0], p["b"][0] * 100.0   # 'b' is a group 100× smaller than 'a'
    v = (1 - x) ** 2 + 100 * (y - x * x) ** 2
    gx = -2 * (1 - x) - 400 * x * (y - x * x)
    gy = 200 * (y - x * x) * 100.0
    return float(v), {"a": np.array([gx]), "b": np.array([gy])}, {}


def test_lbfgs_finds_the_rosenbrock_minimum_across_scaled_groups():
    """The curved valley of Rosenbrock's function (minimum at x = y = 1), one coordinate in a
    group 100× smaller: L-BFGS with per-group scales reaches it in far fewer steps than Adam."""
    res = minimize_lbfgs(_rosenbrock, {"a": np.array([-1.2]), "b": np.array([0.01])}, {"a": 0.1, "b": 1e-3},
                         max_iterations=200, rel_tol=1e-12, patience=3)
    assert abs(res.params["a"][0] - 1) < 1e-4 and abs(res.params["b"][0] * 100 - 1) < 1e-4, res.params
    values = [h["value"] for h in res.history]
    assert all(b <= a for a, b in zip(values, values[1:]))   # Armijo: monotone
    assert res.value == values[-1] < 1e-8 and res.iterations < 100
    adam = minimize(_rosenbrock, {"a": np.array([-1.2]), "b": np.array([0.01])}, {"a": 0.1, "b": 1e-3},
                    max_iterations=res.iterations)
    assert adam.value > 100 * res.value


def test_lbfgs_backtracks_out_of_invalid_regions():
    evaluate, target = _quadratic(scale=1.0)

    def constrained(p):  # a[0] > 0.5 is invalid; the unconstrained minimum (a[0] = 1) lies there
        if p["a"][0] > 0.5:
            raise ValueError("inverted triangle")
        return evaluate(p)

    res = minimize_lbfgs(constrained, {"a": np.zeros(2), "b": np.zeros(1)}, {"a": 0.3, "b": 0.3},
                         max_iterations=100)
    assert res.rejected > 0 and res.params["a"][0] <= 0.5   # never left the valid region
    values = [h["value"] for h in res.history]
    assert all(b <= a for a, b in zip(values, values[1:])) and res.value < 0.3 * values[0]


def test_lbfgs_cancel_and_bad_scales():
    evaluate, _ = _quadratic(scale=1.0)
    calls = []
    res = minimize_lbfgs(evaluate, {"a": np.zeros(2), "b": np.zeros(1)}, {"a": 0.01, "b": 0.01},
                         max_iterations=100, on_iteration=calls.append, cancelled=lambda: len(calls) >= 3)
    assert res.stopped == "cancelled" and res.iterations == 2
    with pytest.raises(ValueError, match="step"):
        minimize_lbfgs(evaluate, {"a": np.zeros(2), "b": np.zeros(1)}, {"a": 0.0, "b": 1.0})


def _chain_quadratic(n=24):
    """½ uᵀAu − bᵀu with A a 1D Laplacian + 1e-3 I (condition ~ 4e3): smooth modes are cheap,
    zig-zags stiff — the structure of the cage handles' loss."""
    A = 2.0 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1) + 1e-3 * np.eye(n)
    b = np.random.default_rng(0).normal(size=n)
    x_star = np.linalg.solve(A, b)

    def evaluate(p):
        u = p["h"]
        return float(0.5 * u @ A @ u - b @ u), {"h": A @ u - b}, {}
    return A, x_star, evaluate


def test_lbfgs_initial_metric_preconditions_and_identity_changes_nothing():
    """precondition = the exact inverse Hessian (normalised to a unit top eigenvalue) solves the
    ill-conditioned quadratic in a few steps, where the Euclidean start needs many more; an identity
    operator reproduces the unpreconditioned iterates exactly; an unknown group is refused."""
    A, x_star, evaluate = _chain_quadratic()
    Ainv = np.linalg.inv(A)
    P = Ainv / np.linalg.eigvalsh(Ainv).max()
    fmin = evaluate({"h": x_star})[0]
    kw = dict(max_iterations=200, rel_tol=0.0, patience=1000, max_step=1e6)
    x0 = {"h": np.zeros(len(A))}

    def iterations_to(res, tol=1e-8):
        gap = [h["value"] - fmin for h in res.history]
        return next((i for i, v in enumerate(gap) if v <= tol * abs(fmin)), None)

    pre = minimize_lbfgs(evaluate, x0, {"h": 1.0}, precondition={"h": lambda v: P @ v}, **kw)
    plain = minimize_lbfgs(evaluate, x0, {"h": 1.0}, **kw)
    n_pre, n_plain = iterations_to(pre), iterations_to(plain)
    assert n_pre is not None and n_pre <= 3, n_pre
    assert n_plain is None or n_plain > 3 * n_pre, (n_plain, n_pre)
    np.testing.assert_allclose(pre.params["h"], x_star, rtol=1e-5, atol=1e-6)
    same = minimize_lbfgs(evaluate, x0, {"h": 1.0}, precondition={"h": lambda v: v.copy()}, **kw)
    assert [h["value"] for h in same.history] == [h["value"] for h in plain.history]
    with pytest.raises(ValueError, match="precondition"):
        minimize_lbfgs(evaluate, x0, {"h": 1.0}, precondition={"other": lambda v: v})


def test_lbfgs_rejects_a_trial_that_does_not_reevaluate_from_itself():
    """reevaluate: an accepted trial becomes the anchor (on_accept) and is evaluated again; when
    that fails (in the recovery: its drape does not re-drape from itself) the trial is rejected
    like an invalid one, after on_revert() undoes the anchor — the optimizer never stands on it."""
    evaluate, target = _quadratic(scale=1.0)
    state = {"anchor": None, "prev": None, "reverts": 0}

    def anchored(p):   # a[0] > 0.5 evaluates as a trial but not from its own anchor
        key = tuple(np.round(np.concatenate([p["a"], p["b"]]), 12))
        if p["a"][0] > 0.5 and key == state["anchor"]:
            raise ValueError("re-drape left the cloth inside the body")
        state["last"] = key
        return evaluate(p)

    def accept():
        state["prev"], state["anchor"] = state["anchor"], state["last"]

    def revert():
        state["anchor"] = state["prev"]
        state["reverts"] += 1
    res = minimize_lbfgs(anchored, {"a": np.zeros(2), "b": np.zeros(1)}, {"a": 0.3, "b": 0.3},
                         max_iterations=100, on_accept=accept, on_revert=revert, reevaluate=True)
    assert state["reverts"] > 0 and res.rejected >= state["reverts"]
    assert res.params["a"][0] <= 0.5 and state["anchor"][0] <= 0.5
    values = [h["value"] for h in res.history]
    assert res.value < 0.3 * values[0]


def test_lbfgs_reevaluates_until_the_value_settles_and_reverts_every_commit():
    """reevaluate N with reevaluate_tol: an accepted trial is re-evaluated from its own anchor until
    φ changes by ≤ tol (here a drift of 20%·2⁻ᵏ on the k-th evaluation in a row: 8%, 4.5%, 2.4% →
    3 re-evaluations at tol 3%), at most N times; a failure at the k-th re-evaluation reverts all k
    commits of that trial (the ill-conditioned chain quadratic: no step is ever zero)."""
    A, x_star, evaluate = _chain_quadratic()

    def run(n, tol, fail_at=None):
        st = {"key": None, "k": 0, "ks": [], "reverts": 0}

        def drifting(p):
            key = p["h"].tobytes()
            st["k"] = st["k"] + 1 if key == st["key"] else 0
            st["key"] = key
            if fail_at is not None and st["k"] == fail_at and p["h"][0] > 0.5 * x_star[0]:
                raise ValueError("no equilibrium from its own drape")
            st["ks"].append(st["k"])
            v, g, t = evaluate(p)
            return v - 0.2 * abs(v) * 0.5 ** st["k"], g, t   # re-evaluations come out higher, as in the recovery

        def revert():
            st["reverts"] += 1
        res = minimize_lbfgs(drifting, {"h": np.zeros(len(A))}, {"h": 1.0}, max_iterations=8,
                             on_accept=lambda: None, on_revert=revert, reevaluate=n, reevaluate_tol=tol)
        return res, st

    res, st = run(5, 0.03)
    assert max(st["ks"]) == 3 and st["reverts"] == 0 and res.iterations == 8
    res, st = run(2, 0.03)
    assert max(st["ks"]) == 2
    res, st = run(3, 0.0, fail_at=2)
    assert st["reverts"] > 0 and st["reverts"] % 2 == 0
