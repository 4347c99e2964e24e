"""Malformed scans found by fuzzing the loaders and the preprocessing: each is refused with the
ScanError subclass (and the ROS code) naming the problem, or read as it is meant — never a crash,
a hang or a message that names another problem."""
import time

import numpy as np
import pytest

from diffavatar_core import scan as sv
from diffavatar_core.scan.cleaning import merge_duplicate_vertices


def _tube(n_phi=24, n_y=10, r=0.2, y0=0.5, y1=1.0):
    """An open cylinder (a skirt's shape), m: (V (n_y·n_phi, 3), F)."""
    phi = 2 * np.pi * np.arange(n_phi) / n_phi
    y = np.repeat(np.linspace(y0, y1, n_y), n_phi)
    V = np.column_stack([r * np.cos(np.tile(phi, n_y)), y, r * np.sin(np.tile(phi, n_y))])
    i, j = np.meshgrid(np.arange(n_y - 1), np.arange(n_phi), indexing="ij")
    a, b = (i * n_phi + j).ravel(), (i * n_phi + (j + 1) % n_phi).ravel()
    return V, np.concatenate([np.stack([a, a + n_phi, b], 1), np.stack([b, a + n_phi, b + n_phi], 1)])


def _refused(cls, code, *words, call):
    with pytest.raises(cls) as info:
        call()
    assert info.value.code == code, (type(info.value), info.value.code)
    for w in words:
        assert w in str(info.value), (w, str(info.value))
    return str(info.value)


def test_coincident_vertices_merge_in_n_log_n():
    """Many vertices at one point (a broken export writing zeros) listed every pair of them: 37 s
    for 20 000 vertices, a MemoryError at 30 000."""
    n = 30000
    V = np.zeros((n, 3))
    V[n // 2:] = [0.0, 1.0, 0.0]
    t = time.perf_counter()
    Vm, Fm, old_to_new = merge_duplicate_vertices(V, np.array([[0, n - 1, 1]]), 1e-6)
    assert time.perf_counter() - t < 5.0
    np.testing.assert_array_equal(Vm, [[0, 0, 0], [0, 1, 0]])
    np.testing.assert_array_equal(old_to_new, np.repeat([0, 1], n // 2))
    np.testing.assert_array_equal(Fm, [[0, 1, 0]])
    _refused(sv.DegenerateScanError, "IMPLAUSIBLE_SIZE", "degenerate",
             call=lambda: sv.load_scan((np.ones((n, 3)), np.arange(n).reshape(-1, 3)), garment_type="skirt"))
