"""Symmetric Chamfer distances, nearest-point and point-to-surface queries."""
import threading
import time

import numpy as np
import pytest
import trimesh

import diffavatar_core as dc


def _grid(n=20, size=1.0):
    """A flat square mesh in the z = 0 plane, size×size, (n+1)² vertices."""
    x, y = np.meshgrid(np.linspace(0, size, n + 1), np.linspace(0, size, n + 1))
    V = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    F = np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    return V, F


def test_mesh_with_itself_is_zero_and_unit_translated_copy_is_one():
    V, F = _grid()
    assert dc.chamfer_meshes(V, F, V, F, samples=5000) == pytest.approx(0.0, abs=1e-12)
    # translation along the normal of a flat sheet: every point is exactly 1 from the other
    assert dc.chamfer_meshes(V, F, V + [0, 0, 1], F, samples=5000) == pytest.approx(1.0, abs=1e-12)


def test_closed_mesh_unit_translation_far_apart_is_about_one():
    s = trimesh.creation.icosphere(subdivisions=3, radius=0.01)
    d = dc.chamfer_meshes(s.vertices, s.faces, s.vertices + [1.0, 0, 0], s.faces, samples=4000)
    assert d == pytest.approx(1.0, abs=0.011)  # within the object's radius


def test_point_sets_self_and_translation():
    rng = np.random.default_rng(1)
    A = rng.random((2000, 3))
    assert dc.chamfer_points(A, A) == 0.0
    B = A * 1e-3 + [5.0, 0, 0]
    assert dc.chamfer_points(A * 1e-3, B) == pytest.approx(5.0, rel=1e-3)


def test_nearest_point_distances_match_brute_force():
    rng = np.random.default_rng(2)
    A, B = rng.normal(size=(300, 3)), rng.normal(size=(500, 3))
    brute = np.sqrt(((A[:, None, :] - B[None, :, :]) ** 2).sum(-1)).min(1)
    np.testing.assert_allclose(dc.nearest_point_distances(A, B), brute, rtol=1e-12, atol=1e-14)


def _brute_point_triangle_distance(P, V, F):
    """Independent reference: min over triangles of (plane distance if the projection falls
    inside the triangle, else the distance to the nearest of its three edge segments)."""
    A, B, C = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    n = np.cross(B - A, C - A)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    d = np.full((len(P), len(F)), np.inf)
    for a, b in ((A, B), (B, C), (C, A)):
        ab = b - a
        t = np.clip(np.einsum("ptk,tk->pt", P[:, None, :] - a[None], ab) / (ab ** 2).sum(1), 0, 1)
        d = np.minimum(d, np.linalg.norm(P[:, None, :] - (a[None] + t[..., None] * ab[None]), axis=2))
    h = np.einsum("ptk,tk->pt", P[:, None, :] - A[None], n)
    Q = P[:, None, :] - h[..., None] * n[None]
    inside = np.ones_like(h, bool)
    for a, b in ((A, B), (B, C), (C, A)):
        inside &= np.einsum("ptk,tk->pt", np.cross(b - a, Q - a[None]), n) >= 0
    return np.where(inside, np.minimum(np.abs(h), d), d).min(1)


def test_surface_distances_match_brute_force():
    s = trimesh.creation.icosphere(subdivisions=2, radius=0.3)
    rng = np.random.default_rng(3)
    P = rng.normal(scale=0.5, size=(300, 3))
    ref = _brute_point_triangle_distance(P, np.asarray(s.vertices), np.asarray(s.faces))
    np.testing.assert_allclose(dc.surface_distances(P, s.vertices, s.faces), ref, rtol=1e-9, atol=1e-12)


def test_surface_sampling_is_area_uniform_and_seeded():
    V, F = _grid(n=4, size=2.0)
    P, tri = dc.sample_surface(V, F, 40000, seed=7)
    P2, _ = dc.sample_surface(V, F, 40000, seed=7)
    np.testing.assert_array_equal(P, P2)
    assert np.all((P[:, :2] >= 0) & (P[:, :2] <= 2)) and np.allclose(P[:, 2], 0)
    # each quadrant holds a quarter of the samples (binomial σ ≈ 0.0022)
    frac = np.mean((P[:, 0] < 1) & (P[:, 1] < 1))
    assert frac == pytest.approx(0.25, abs=0.01)


def test_progress_and_cancel():
    rng = np.random.default_rng(4)
    A, B = rng.random((50000, 3)), rng.random((20000, 3))
    events = []
    dc.nearest_point_distances(A, B, progress=events.append)
    assert events and events[-1].done == events[-1].total == 50000
    assert all(e.done <= e.total for e in events)
    tok = dc.CancelToken()
    tok.cancel()
    with pytest.raises(dc.Cancelled):
        dc.chamfer_points(A, B, cancel=tok)


def test_long_call_releases_the_gil():
    """A Python thread keeps running while the core computes."""
    rng = np.random.default_rng(5)
    A, B = rng.random((400000, 3)), rng.random((400000, 3))
    ticks = []
    stop = threading.Event()

    def ticker():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    th = threading.Thread(target=ticker)
    th.start()
    t0 = time.perf_counter()
    dc.chamfer_points(A, B)
    t1 = time.perf_counter()
    stop.set()
    th.join()
    during = [t for t in ticks if t0 < t < t1]
    # with the GIL held the ticker could not run at all during the call
    assert len(during) >= 0.25 * (t1 - t0) / 0.002


def test_bad_inputs():
    with pytest.raises(ValueError, match="a"):
        dc.chamfer_points(np.zeros((0, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="samples"):
        V, F = _grid(2)
        dc.chamfer_meshes(V, F, V, F, samples=0)
    with pytest.raises(ValueError, match="fa"):
        V, F = _grid(2)
        dc.chamfer_meshes(V, F + 100, V, F)
    with pytest.raises(ValueError, match="zero surface area"):
        V = np.zeros((3, 3))
        dc.chamfer_meshes(V, [[0, 1, 2]], V, [[0, 1, 2]])
