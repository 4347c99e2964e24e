"""Triangle conditioning quality q = 3A/Σl² (Shewchuk 2002; paper Table 1)."""
import numpy as np
import pytest

import diffavatar_core as dc


def _hand_q(a, b, c):
    a, b, c = map(np.asarray, (a, b, c))
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a))
    return 3 * area / (np.sum((b - a) ** 2) + np.sum((c - b) ** 2) + np.sum((a - c) ** 2))


def test_known_triangles_match_hand_values():
    V = np.array([[0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0],   # equilateral
                  [0, 0, 0], [1, 0, 0], [0, 1, 0],                    # right isosceles
                  [0, 0, 0], [2, 0, 0], [1, 1e-3, 0],                 # sliver
                  [0, 0, 0], [1, 0, 0], [2, 0, 0],                    # degenerate (collinear)
                  [0.1, 0.2, 0.3], [1.4, -0.2, 0.9], [-0.3, 0.8, 1.1]], float)
    F = np.arange(15).reshape(5, 3)
    q = dc.triangle_quality(V, F)
    assert q[0] == pytest.approx(np.sqrt(3) / 4, abs=1e-12)
    assert q[1] == pytest.approx(3 * 0.5 / 4, abs=1e-12)          # A = 1/2, Σl² = 1 + 1 + 2
    assert q[2] == pytest.approx(3 * 1e-3 / (4 + 2 * (1 + 1e-6)), abs=1e-12)
    assert q[3] == 0.0
    for t in range(5):
        assert q[t] == pytest.approx(_hand_q(*V[F[t]]), abs=1e-12)


def test_invariant_to_rigid_motion_and_scale_and_2d_input():
    rng = np.random.default_rng(0)
    V2 = rng.random((30, 2))
    F = np.array([[i, i + 1, i + 2] for i in range(28)])
    q2 = dc.triangle_quality(V2, F)
    R, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    V3 = np.column_stack([V2, np.zeros(30)]) @ R.T * 1e3 + rng.normal(size=3)
    np.testing.assert_allclose(dc.triangle_quality(V3, F), q2, rtol=1e-9, atol=1e-12)
    assert np.all(q2 <= np.sqrt(3) / 4 + 1e-15) and np.all(q2 >= 0)


def test_mesh_quality_summary():
    V = np.array([[0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0], [1.5, np.sqrt(3) / 2, 0]])
    F = np.array([[0, 1, 2], [1, 3, 2]])
    mq = dc.mesh_quality(V, F)
    assert mq.min == pytest.approx(np.sqrt(3) / 4, abs=1e-12)
    assert mq.mean == pytest.approx(np.sqrt(3) / 4, abs=1e-12)


def test_bad_inputs_raise_value_error_naming_argument():
    with pytest.raises(ValueError, match="faces"):
        dc.triangle_quality(np.zeros((3, 3)), [[0, 1, 5]])
    with pytest.raises(ValueError, match="vertices"):
        dc.triangle_quality([[0, 0, np.nan], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    with pytest.raises(ValueError, match="vertices"):
        dc.triangle_quality(np.zeros((3, 4)), [[0, 1, 2]])
